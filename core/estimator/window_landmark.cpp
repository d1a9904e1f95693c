// The reprojection rows of one landmark (Window::observationRows, Window::linearizeLandmark): the
// landmark linearization of every LM iteration. Apart from window.cpp because it is one of the
// hot kernels compiled per ISA (core/isa_kernels.cmake, docs/design.md §1 ISA dispatch): the
// reprojection Jacobians are small fixed-size products (2 × 3, 2 × 6, 3 × 6) that AVX2 + FMA
// evaluates with fewer instructions. Also compiled into the library itself (SSE2) for the
// marginalizers and the tests.

#include "core/common/scalar.h"
#include "core/estimator/window.h"

namespace marglab {

template <typename Scalar>
void Window<Scalar>::observationRows(const Landmark& lm, const std::set<int64_t>& system_frames,
                                     const RelativePoses& rel,
                                     std::vector<ReprojectionRows<Scalar>>* rows,
                                     Scalar* cost) const {
  const Vec3S p_w_jac = lm.world() ? lm.jacobianPoint() : Vec3S::Zero();
  for (const auto& [frame_id, obs] : lm.obs) {
    if (system_frames.count(frame_id) == 0) continue;
    const bool in_host = frame_id == lm.host;
    BodyPoint<Scalar> body;  // world points only
    if (lm.world())
      body = worldBodyPoint<Scalar>(jacobianPoseOf(frame_id), poseOf(frame_id), p_w_jac, lm.param);
    for (int cam = 0; cam < (obs.has_right ? 2 : 1); ++cam) {
      size_t k_rel = 0;
      TargetPoint<Scalar> point;
      if (lm.world()) {
        point = worldTargetPoint<Scalar>(T_c_i_[cam], body);
      } else {
        k_rel = rel.index(lm.host, frame_id, cam);
        point = hostedTargetPoint<Scalar>(rel.T_ct_h_jac[k_rel], rel.T_ct_h[k_rel], lm.param);
      }
      ReprojectionRows<Scalar> row;
      if (!linearizeReprojection<Scalar>(cam == 0 ? rig_.cam0 : rig_.cam1, point,
                                         cam == 0 ? obs.uv0 : obs.uv1, noise_, &row, cost)) {
        continue;
      }
      row.target = in_host ? -1 : frame_id;
      row.cam = cam;
      if (!lm.world() && !in_host) {
        // Through the relative pose onto the host and target increments.
        const Mat<Scalar, 2, 6> D_r_T = row.J_t;
        row.J_h = D_r_T * rel.D_rel_h[k_rel];
        row.J_t = D_r_T * rel.D_rel_t[k_rel];
      }
      rows->push_back(row);
    }
  }
}

template <typename Scalar>
bool Window<Scalar>::linearizeLandmark(int64_t track_id, const Landmark& lm,
                                       const std::set<int64_t>& system_frames,
                                       const RelativePoses& rel, LandmarkJacobians<Scalar>* out,
                                       NfrRows nfr, int min_rows) const {
  // Scratch reused across calls (no allocation per landmark once warm); one per thread.
  thread_local std::vector<ReprojectionRows<Scalar>> rows;
  thread_local std::vector<PoseLandmarkRows<Scalar>> extra;
  rows.clear();
  extra.clear();
  out->cost = 0;
  observationRows(lm, system_frames, rel, &rows, &out->cost);
  Eigen::Index m = 2 * static_cast<Eigen::Index>(rows.size());
  for (const NfrFactor& f : lm.nfr) {
    if (nfr == NfrRows::kExclude || system_frames.count(f.frame) == 0) continue;
    RowBlock<Scalar> block = linearizeNfr(f, track_id, &lm);
    out->cost += Scalar(0.5) * block.r.squaredNorm();
    m += block.r.size();
    extra.push_back({f.frame, std::move(block.J), std::move(block.r)});
  }
  if (m < min_rows) return false;
  stackLandmarkRows<Scalar>(track_id, lm.host, rows, extra, out, estimatesStereoOffset());
  return true;
}

#define MARGLAB_INST(S)                                                                            \
  template void Window<S>::observationRows(const Landmark&, const std::set<int64_t>&,              \
                                           const RelativePoses&,                                   \
                                           std::vector<ReprojectionRows<S>>*, S*) const;           \
  template bool Window<S>::linearizeLandmark(int64_t, const Landmark&, const std::set<int64_t>&,   \
                                             const RelativePoses&, LandmarkJacobians<S>*, NfrRows, \
                                             int) const;
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
