// makeBaLinearSystem: the BA linear system of an ISA's kernels (landmark_system.cpp, compiled per
// ISA; core/estimator/linearization_kernels.h holds the tables).

#include "core/ba/landmark_system.h"
#include "core/common/scalar.h"
#include "core/estimator/linearization_kernels.h"

namespace marglab {

template <typename Scalar>
std::unique_ptr<BaLinearSystem<Scalar>> makeBaLinearSystem(const BalProblem& problem,
                                                           BaElimination elimination, Isa isa) {
  const IsaKernels& k = kernelsOf(isa);
  if constexpr (std::is_same_v<Scalar, float>) {
    return k.ba_f32.make_system(problem, elimination);
  } else {
    return k.ba_f64.make_system(problem, elimination);
  }
}

template <typename Scalar>
std::unique_ptr<BaLinearSystem<Scalar>> makeBaLinearSystem(const BalProblem& problem,
                                                           BaElimination elimination) {
  return makeBaLinearSystem<Scalar>(problem, elimination, activeIsa());
}

#define MARGLAB_INST(S)                                                                  \
  template std::unique_ptr<BaLinearSystem<S>> makeBaLinearSystem<S>(const BalProblem&,   \
                                                                    BaElimination, Isa); \
  template std::unique_ptr<BaLinearSystem<S>> makeBaLinearSystem<S>(const BalProblem&,   \
                                                                    BaElimination);
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
