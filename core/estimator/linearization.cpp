// makeLinearization: the landmark linearization of the active ISA's kernels
// (linearization_kernels.h).

#include "core/estimator/linearization.h"

#include "core/common/scalar.h"
#include "core/estimator/linearization_kernels.h"

namespace marglab {

const IsaKernels& kernelsOf(Isa isa) {
#ifdef MARGLAB_ISA_SSE2_ONLY
  (void)isa;  // the only ISA built (core/isa_kernels.cmake)
#else
  switch (isa) {
    case Isa::kAvx512:
      return isa_avx512::kernels();
    case Isa::kAvx2:
      return isa_avx2::kernels();
    case Isa::kSse2:
      break;
  }
#endif
  return isa_sse2::kernels();
}

template <typename Scalar>
std::unique_ptr<Linearization<Scalar>> makeLinearization(
    OptElimination elimination, const typename Linearization<Scalar>::Options& options) {
  return linearizationKernels<Scalar>(activeKernels()).of_elimination(elimination, options);
}

template <typename Scalar>
std::unique_ptr<Linearization<Scalar>> makeLinearization(
    const Variant& variant, const typename Linearization<Scalar>::Options& options) {
  return linearizationKernels<Scalar>(activeKernels()).of_variant(variant, options);
}

#define MARGLAB_INST(S)                                            \
  template std::unique_ptr<Linearization<S>> makeLinearization<S>( \
      OptElimination, const typename Linearization<S>::Options&);  \
  template std::unique_ptr<Linearization<S>> makeLinearization<S>( \
      const Variant&, const typename Linearization<S>::Options&);
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
