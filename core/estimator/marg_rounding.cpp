#include "core/estimator/marg_rounding.h"

#include <fmt/core.h>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>

#include <cmath>
#include <limits>

#include "core/common/scalar.h"
#include "core/diagnostics/gauge.h"
#include "core/estimator/marginalizer.h"
#include "core/estimator/window_snapshot.h"

namespace marglab {
namespace {

template <typename Scalar>
MargPrior<double> promoted(const MargPrior<Scalar>& p) {
  MargPrior<double> out;
  out.storage = p.storage;
  for (const auto& block : p.blocks) {
    out.addBlock(block.var, block.T0.template cast<double>(), block.sb0.template cast<double>(),
                 block.p0.template cast<double>());
  }
  out.setHessian(p.hessian.H.template cast<double>(), p.hessian.b.template cast<double>(),
                 static_cast<double>(p.hessian.c));
  return out;
}

double minEigen(const MatXd& A) {
  if (A.size() == 0) return std::numeric_limits<double>::quiet_NaN();
  const MatXd sym = 0.5 * (A + A.transpose());
  return Eigen::SelfAdjointEigenSolver<MatXd>(sym, Eigen::EigenvaluesOnly).eigenvalues()(0);
}

// The orthonormalized rigid motions (6 columns) of a prior's layout at its linearization points.
template <typename Scalar>
MatXd gaugeBasis(const MargPrior<Scalar>& prior) {
  PriorLayout layout;
  GaugeState state;
  prior.gaugeLayout(&layout, &state);
  const GaugeDirections d = gaugeDirections(layout, prior.cols(), state, 0);
  const MatXd rigid = d.leftCols(6);
  Eigen::HouseholderQR<MatXd> qr(rigid);
  return qr.householderQ() * MatXd::Identity(rigid.rows(), 6);
}

MargRoundingStage stage(const MatXd& E, double ref_norm, const MatXd& G) {
  MargRoundingStage s;
  const double e = E.norm();
  const MatXd block = G.transpose() * E * G;
  s.rel_fro = ref_norm > 0 ? e / ref_norm : std::numeric_limits<double>::quiet_NaN();
  s.gauge_share = e > 0 ? block.norm() / e : 0.0;
  s.gauge_trace = block.trace();
  return s;
}

// Schur₆₄ of a system (the run's pseudo-inverse rule, in double).
Status schur64(const MatXd& H, const VecXd& b, int n_marg, HessianPrior<double>* out) {
  SchurMarginalization<double> sc = schurMarginalize<double>(H, b, n_marg);
  *out = std::move(sc.prior);
  return sc.status;
}

}  // namespace

template <typename Scalar>
Status measureMargRounding(const Window<Scalar>& window, const MargPlan& plan,
                           const MargPrior<Scalar>& before, const MargPrior<Scalar>& after,
                           const Variant& variant, MargRoundingRow* row) {
  const PriorStorage& storage = after.storage;
  if (!hessianStorage(storage) || storage.preconditioning != Preconditioning::kNone ||
      storage.psd != PsdProjection::kNone || window.isVio()) {
    return Status::Error(Status::Code::kInvalidArgument,
                         "marg_rounding needs a VO run with a plain Hessian prior (sq)");
  }
  // The run's stages in Scalar, with and without the old prior's term.
  SchurSystem<Scalar> a_s, n_s;
  if (Status s = schurSystem(window, plan, before, true, &a_s); !s.ok()) return s;
  if (Status s = schurSystem(window, plan, before, false, &n_s); !s.ok()) return s;
  SchurMarginalization<Scalar> d = schurMarginalize<Scalar>(a_s.H, a_s.b, a_s.n_marg);
  if (!d.status.ok()) return d.status;
  if (d.prior.H != after.hessian.H) {
    return Status::Error(Status::Code::kInvalidArgument,
                         "marg_rounding: the stages are not the run's");
  }
  // The same inputs in double.
  const Window<double> wd = restoredWindow<double>(snapshotOf(window), variant, window.config());
  const MargPrior<double> before64 = promoted(before);
  SchurSystem<double> a_64, n_64;
  if (Status s = schurSystem(wd, plan, before64, true, &a_64); !s.ok()) return s;
  if (Status s = schurSystem(wd, plan, before64, false, &n_64); !s.ok()) return s;

  const MatXd A_s = a_s.H.template cast<double>();
  const VecXd b_s = a_s.b.template cast<double>();
  HessianPrior<double> S_a, S_b, S_c;
  Status s = schur64(a_64.H, a_64.b, a_64.n_marg, &S_a);
  if (s.ok()) {
    s = schur64(a_64.H + (n_s.H.template cast<double>() - n_64.H),
                a_64.b + (n_s.b.template cast<double>() - n_64.b), a_64.n_marg, &S_b);
  }
  if (s.ok()) s = schur64(A_s, b_s, a_64.n_marg, &S_c);
  if (!s.ok()) return s;
  const MatXd S_d = d.prior.H.template cast<double>();

  const MatXd G = gaugeBasis(after);
  const double ref = S_a.H.norm();
  row->n = static_cast<int>(S_a.H.rows());
  row->n_marg = a_64.n_marg;
  row->n_landmarks = static_cast<int>(plan.landmarks.size());
  row->total = stage(S_d - S_a.H, ref, G);
  row->new_factors = stage(S_b.H - S_a.H, ref, G);
  row->add_prior = stage(S_c.H - S_b.H, ref, G);
  row->schur = stage(S_d - S_c.H, ref, G);
  row->floor_rel_fro = (S_a.H.template cast<Scalar>().template cast<double>() - S_a.H).norm() / ref;
  const VecXd b_ref = S_a.b - S_a.H * a_64.new_delta;
  const double b_norm = b_ref.norm();
  row->b_rel = b_norm > 0 ? (after.hessian.b.template cast<double>() - b_ref).norm() / b_norm
                          : std::numeric_limits<double>::quiet_NaN();
  const MatXd sym_ref = 0.5 * (S_a.H + S_a.H.transpose());
  row->sigma_max = Eigen::SelfAdjointEigenSolver<MatXd>(sym_ref, Eigen::EigenvaluesOnly)
                       .eigenvalues()
                       .maxCoeff();
  row->eig_min_run = minEigen(S_d);
  row->eig_min_ref = minEigen(S_a.H);
  row->gauge_min_run = minEigen(G.transpose() * S_d * G);
  row->gauge_min_ref = minEigen(G.transpose() * S_a.H * G);
  // G's first 3 columns span the translations (the QR keeps the span of leading columns).
  row->translation_min_ref = minEigen(G.leftCols(3).transpose() * S_a.H * G.leftCols(3));
  return Status::Ok();
}

std::string margRoundingCsv(const std::vector<MargRoundingRow>& rows) {
  std::string out =
      "frame_index,n,n_marg,n_landmarks,total_rel,total_gauge_share,total_gauge_trace,"
      "new_rel,new_gauge_share,new_gauge_trace,add_rel,add_gauge_share,add_gauge_trace,"
      "schur_rel,schur_gauge_share,schur_gauge_trace,floor_rel,b_rel,sigma_max,eig_min_run,"
      "eig_min_ref,gauge_min_run,gauge_min_ref,translation_min_ref\n";
  auto stageText = [](const MargRoundingStage& s) {
    return fmt::format("{:.9g},{:.9g},{:.9g}", s.rel_fro, s.gauge_share, s.gauge_trace);
  };
  for (const MargRoundingRow& r : rows) {
    out += fmt::format(
        "{},{},{},{},{},{},{},{},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g},{:.9g}\n",
        r.frame_index, r.n, r.n_marg, r.n_landmarks, stageText(r.total), stageText(r.new_factors),
        stageText(r.add_prior), stageText(r.schur), r.floor_rel_fro, r.b_rel, r.sigma_max,
        r.eig_min_run, r.eig_min_ref, r.gauge_min_run, r.gauge_min_ref, r.translation_min_ref);
  }
  return out;
}

#define MARGLAB_INST(S)                                                                          \
  template Status measureMargRounding<S>(const Window<S>&, const MargPlan&, const MargPrior<S>&, \
                                         const MargPrior<S>&, const Variant&, MargRoundingRow*);
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
