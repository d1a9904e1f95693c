#include "core/geometry/camera.h"

namespace marglab {

template <typename Scalar>
bool StereoRig<Scalar>::triangulate(const Vec<Scalar, 2>& uv0, const Vec<Scalar, 2>& uv1,
                                    Vec3<Scalar>* p_c0,
                                    const TriangulationOptions<Scalar>& options) const {
  const SE3<Scalar> T_c0_c1 = this->T_c0_c1();
  const Vec3<Scalar>& t = T_c0_c1.translation();
  if (!(t.norm() >= options.min_baseline)) return false;

  const Vec3<Scalar> d0 = cam0.unproject(uv0);
  const Vec3<Scalar> d1 = T_c0_c1.unitQuaternion() * cam1.unproject(uv1);
  const Scalar sin_sq = d0.cross(d1).squaredNorm();
  const Scalar sin_min = std::sin(options.min_parallax);
  if (!(sin_sq >= sin_min * sin_min)) return false;

  const Scalar c = d0.dot(d1);
  const Scalar d0_t = d0.dot(t);
  const Scalar e = d1.dot(t);
  const Scalar s0 = (d0_t - c * e) / sin_sq;
  const Scalar s1 = (c * d0_t - e) / sin_sq;
  const Vec3<Scalar> p = Scalar(0.5) * (s0 * d0 + t + s1 * d1);
  const Vec3<Scalar> p_c1 = T_c0_c1.inverse() * p;
  if (!(p.z() >= cam0.min_depth && p_c1.z() >= cam1.min_depth) || !p.allFinite()) return false;
  *p_c0 = p;
  return true;
}

#define MARGLAB_INST(S) template struct StereoRig<S>;
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
