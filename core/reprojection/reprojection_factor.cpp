#include "core/reprojection/reprojection_factor.h"

#include <algorithm>

#include "core/common/scalar.h"

namespace marglab {

namespace {

constexpr int kPoseCols = 6;  // a pose increment [δt; δφ]

}  // namespace

template <typename Scalar>
void stackLandmarkRows(int64_t track_id, int64_t host,
                       const std::vector<ReprojectionRows<Scalar>>& rows,
                       const std::vector<PoseLandmarkRows<Scalar>>& extra,
                       LandmarkJacobians<Scalar>* out, bool stereo_offset) {
  const bool hosted = host >= 0;
  std::vector<int64_t>& frames = out->frames;
  frames.clear();
  // A small sorted vector (a lambda: inlined in the loops, measured).
  auto insert = [&frames](int64_t f) {
    const auto it = std::lower_bound(frames.begin(), frames.end(), f);
    if (it == frames.end() || *it != f) frames.insert(it, f);
  };
  for (const ReprojectionRows<Scalar>& row : rows) {
    if (row.target < 0) continue;
    if (hosted) insert(host);
    insert(row.target);
  }
  for (const PoseLandmarkRows<Scalar>& e : extra) insert(e.frame);
  auto local = [&frames](int64_t f) {
    return kPoseCols *
           static_cast<int>(std::lower_bound(frames.begin(), frames.end(), f) - frames.begin());
  };
  Eigen::Index m = 2 * static_cast<Eigen::Index>(rows.size());
  for (const PoseLandmarkRows<Scalar>& e : extra) m += e.r.size();
  out->track_id = track_id;
  out->stereo_offset = stereo_offset && std::any_of(rows.begin(), rows.end(),
                                                    [](const ReprojectionRows<Scalar>& row) {
                                                      return row.cam == 1;
                                                    });
  const Eigen::Index offset_col = kPoseCols * static_cast<Eigen::Index>(frames.size());
  out->J_p.setZero(m, offset_col + (out->stereo_offset ? 1 : 0));
  out->J_l.resize(m, 3);
  out->r.resize(m);
  const int host_col = frames.empty() || !hosted ? 0 : local(host);
  for (size_t i = 0; i < rows.size(); ++i) {
    out->J_l.template middleRows<2>(2 * i) = rows[i].J_l;
    out->r.template segment<2>(2 * i) = rows[i].r;
    if (out->stereo_offset && rows[i].cam == 1) out->J_p(2 * i, offset_col) = rows[i].scale;
    if (rows[i].target < 0) continue;
    if (hosted) out->J_p.template block<2, kPoseCols>(2 * i, host_col) += rows[i].J_h;
    out->J_p.template block<2, kPoseCols>(2 * i, local(rows[i].target)) += rows[i].J_t;
  }
  Eigen::Index row = 2 * static_cast<Eigen::Index>(rows.size());
  for (const PoseLandmarkRows<Scalar>& e : extra) {
    const Eigen::Index n_r = e.r.size();
    out->J_p.block(row, local(e.frame), n_r, kPoseCols) = e.J.leftCols(kPoseCols);
    out->J_l.middleRows(row, n_r) = e.J.rightCols(3);
    out->r.segment(row, n_r) = e.r;
    row += n_r;
  }
}

#define MARGLAB_INST(S)                                                                         \
  template void stackLandmarkRows<S>(int64_t, int64_t, const std::vector<ReprojectionRows<S>>&, \
                                     const std::vector<PoseLandmarkRows<S>>&,                   \
                                     LandmarkJacobians<S>*, bool);
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
