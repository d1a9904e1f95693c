#pragma once
// The ablation of docs/design.md §2: a variant is `opt-marg-storage-precision`.
//   opt      ns | sc    landmark elimination inside each LM iteration: nullspace projection
//                       (in-place Householder QR of [J_p J_l r], keep the Q2ᵀ rows) or Schur
//                       complement on 3×3 landmark blocks;
//   marg     qr | sc    marginalization: landmarks by nullspace projection then frame variables
//                       by the flat QR (paper §4.2), or everything by Schur complement on the
//                       Hessian with a pseudo-inverse of H_μμ (eqs. 22–23);
//   storage  sqrt | sq  prior stored as (J_m, r_m) (eq. 4) or (H_m, b_m) (eq. 3); `sc` + `sqrt`
//                       factorizes the new prior by LDLT (√D Lᵀ P); `qr` requires `sqrt`;
//            sqp | sqj  Hessian storage preconditioned (docs/preconditioned_storage.md): the prior
//                       kept as (Q, Ĥ_m, b̂_m) with H_m = Qᵀ Ĥ_m Q, and every factorization of the
//                       marginalization and of the LM step run on the preconditioned matrix;
//                       sqp = 3×3 block Jacobi per physical quantity (our reading of PC-SRIF,
//                       Ke et al. 2024), sqj = point Jacobi with power-of-two scales; `sc` only;
//            sqrtp      square-root storage whose LDLT (and the LM step's) runs on the block-Jacobi
//                       preconditioned Hessian: PC-SRIF's own pipeline (preconditioned Cholesky,
//                       square root stored); `sc` only;
//   precision f32 | f64 the scalar type of the whole estimator;
//             mixed     (ns only) landmark linearization storage and elimination in f32, reduced
//                       system, prior and marginalization in f64 (core/estimator/linearization.h).
// The paper's columns: √VIO/√VO = ns-qr-sqrt, baseline = sc-sc-sq; ablation adds sc-qr-sqrt,
// ns-sc-sqrt, sc-sc-sqrt — ten variants with both precisions.

#include <string>
#include <vector>

namespace marglab {

enum class OptElimination { kNullspace, kSchur };
enum class MargMethod { kQr, kSchur };
enum class PriorStorage { kSqrt, kHessian, kHessianBlockJacobi, kHessianJacobi, kSqrtBlockJacobi };

// The Hessian storages keep (H_m, b_m, c), the preconditioned ones in scaled coordinates; the
// square-root ones (J_m, r_m).
constexpr bool hessianStorage(PriorStorage s) {
  return s == PriorStorage::kHessian || s == PriorStorage::kHessianBlockJacobi ||
         s == PriorStorage::kHessianJacobi;
}
constexpr bool sqrtStorage(PriorStorage s) { return !hessianStorage(s); }
enum class Precision { kF32, kF64, kMixed };

struct Variant {
  OptElimination opt = OptElimination::kNullspace;
  MargMethod marg = MargMethod::kQr;
  PriorStorage storage = PriorStorage::kSqrt;
  Precision precision = Precision::kF32;

  // "ns-qr-sqrt-f32"
  std::string name() const;
  // Name without the precision, e.g. "ns-qr-sqrt".
  std::string method() const;
  // "f32", "f64" or "mixed".
  std::string precisionName() const;
  // The scalar type of the estimator's state: float for f32, double for f64 and mixed.
  bool floatState() const { return precision == Precision::kF32; }
  // Throws UsageError naming the part that is wrong and the accepted values.
  static Variant parse(const std::string& text);
  bool operator==(const Variant& other) const;
};

// The 10 variants of the paper's tables (docs/design.md §2), in table order.
std::vector<Variant> paperVariants();

}  // namespace marglab
