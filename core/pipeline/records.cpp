#include "core/pipeline/records.h"

namespace marglab {

FrameRecord toFrameRecord(const FrameResult& result) {
  FrameRecord record;
  record.t_ns = result.t_ns;
  record.is_keyframe = result.is_keyframe;
  record.n_landmarks = result.n_landmarks;
  record.n_observations = result.n_observations;
  record.lm_iterations = result.lm_iterations;
  record.n_connected = result.n_connected;
  record.n_checked = result.n_checked;
  record.n_inconsistent = result.n_inconsistent;
  record.cost_initial = result.cost_initial;
  record.cost_final = result.cost_final;
  record.t_opt_s = result.t_opt_s;
  record.t_marg_s = result.t_marg_s;
  record.p_est = result.T_w_i.translation();
  record.q_est = result.T_w_i.unitQuaternion();
  return record;
}

SparsifyRecord toSparsifyRecord(const SparsifyEvent& event, std::int64_t frame_index,
                                std::int64_t t_ns) {
  SparsifyRecord record;
  record.frame_index = frame_index;
  record.t_ns = t_ns;
  record.blanket_cols = event.blanket_cols;
  record.n_blanket_poses = event.n_blanket_poses;
  record.n_blanket_landmarks = event.n_blanket_landmarks;
  record.nnz_dense = event.nnz_dense;
  record.nnz_sparse = event.nnz_sparse;
  record.info_dense = event.info_dense;
  record.info_sparse = event.info_sparse;
  record.kld = event.kld;
  record.recovered = event.recovered;
  record.t_schur_s = event.t_schur_s;
  record.t_recovery_s = event.t_recovery_s;
  record.t_insert_s = event.t_insert_s;
  return record;
}

}  // namespace marglab
