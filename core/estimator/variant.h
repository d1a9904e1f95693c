#pragma once
// The ablation of docs/design.md §2: a variant is `opt-marg-storage-precision`.
//   opt      ns | sc    landmark elimination inside each LM iteration: nullspace projection
//                       (in-place Householder QR of [J_p J_l r], keep the Q2ᵀ rows) or Schur
//                       complement on 3×3 landmark blocks;
//   marg     qr | sc    marginalization: landmarks by nullspace projection then frame variables
//                       by the flat QR (paper §4.2), or everything by Schur complement on the
//                       Hessian with a pseudo-inverse of H_μμ (eqs. 22–23);
//   storage             three axes, spelled representation + preconditioning + psd projection
//                       (e.g. sq + p + g = sqpg), from the one table in variant.cpp:
//     representation  sqrt | sq   prior stored as (J_m, r_m) (eq. 4) or (H_m, b_m) (eq. 3); `sc` +
//                                 `sqrt` factorizes the new prior by LDLT (√D Lᵀ P);
//     preconditioning – | p | j   none, 3×3 block Jacobi per physical quantity (our reading of
//                                 PC-SRIF, Ke et al. 2024) or power-of-two point Jacobi
//                                 (docs/preconditioned_storage.md): every factorization of the
//                                 marginalization and of the LM step runs on the scaled matrix, a
//                                 Hessian prior is kept as (Q, Ĥ_m, b̂_m) with H_m = Qᵀ Ĥ_m Q;
//     psd projection  – | c | g   the new prior as computed; replaced by its LDLT with negative
//                                 pivots set to zero (c, a Hessian prior: JᵀJ of that square root);
//                                 or with pivots below a threshold relative to the largest set to
//                                 zero (g), which keeps the gauge nullspace exact;
//                       the rules (qr: plain sqrt only, …) are variantProblem() beside the tables;
//   precision f32 | f64 the scalar type of the whole estimator;
//             mixed     (ns only) landmark linearization storage and elimination in f32, reduced
//                       system, prior and marginalization in f64 (core/estimator/linearization.h).
// The paper's columns: √VIO/√VO = ns-qr-sqrt, baseline = sc-sc-sq; ablation adds sc-qr-sqrt,
// ns-sc-sqrt, sc-sc-sqrt — ten variants with both precisions.

#include <string>
#include <vector>

#include "core/linalg/preconditioner.h"

namespace marglab {

enum class OptElimination { kNullspace, kSchur };
enum class MargMethod { kQr, kSchur };
enum class Representation { kSqrt, kHessian };
enum class PsdProjection { kNone, kClampNegative, kGaugeExact };
enum class Precision { kF32, kF64, kMixed };

// One value of each storage axis.
struct PriorStorage {
  Representation representation = Representation::kSqrt;
  Preconditioning preconditioning = Preconditioning::kNone;
  PsdProjection psd = PsdProjection::kNone;

  constexpr bool operator==(const PriorStorage& o) const {
    return representation == o.representation && preconditioning == o.preconditioning &&
           psd == o.psd;
  }
  constexpr bool operator!=(const PriorStorage& o) const { return !(*this == o); }
};

// The Hessian storages keep (H_m, b_m, c), the preconditioned ones in scaled coordinates; the
// square-root ones (J_m, r_m).
constexpr bool hessianStorage(const PriorStorage& s) {
  return s.representation == Representation::kHessian;
}
constexpr bool sqrtStorage(const PriorStorage& s) { return !hessianStorage(s); }

// "sqrt", "sqp", "sqpg", …
std::string storageName(const PriorStorage& storage);
// Every combination of the storage axes' values, valid or not (variantProblem says which).
std::vector<PriorStorage> storageCombinations();

struct Variant {
  OptElimination opt = OptElimination::kNullspace;
  MargMethod marg = MargMethod::kQr;
  PriorStorage storage;
  Precision precision = Precision::kF32;

  // "ns-qr-sqrt-f32"
  std::string name() const;
  // Name without the precision, e.g. "ns-qr-sqrt".
  std::string method() const;
  // "f32", "f64" or "mixed".
  std::string precisionName() const;
  // The scalar type of the estimator's state: float for f32, double for f64 and mixed.
  bool floatState() const { return precision == Precision::kF32; }
  // Throws UsageError naming the part that is wrong and the accepted values, or the rule a
  // combination breaks.
  static Variant parse(const std::string& text);
  bool operator==(const Variant& other) const;
};

// Why the axes of v do not combine ("" when they do): the one place of the variant rules.
std::string variantProblem(const Variant& v);

// [marginalization] psd_hessian_prior = true, kept for existing configs: the psd axis `c` on a
// variant named without one (sq → sqc, sqp → sqpc; the name stays as given, so results files and
// sweep indexes of those configs are unchanged). Returns "" or why it does not apply.
std::string psdHessianPriorProblem(const Variant& v);
PriorStorage withPsdHessianPrior(PriorStorage storage, bool psd_hessian_prior);

// "opt-marg-storage-precision with opt ns or sc, …": the names the tables accept (help, errors).
std::string variantSyntax();

// The 10 variants of the paper's tables (docs/design.md §2), in table order.
std::vector<Variant> paperVariants();

}  // namespace marglab
