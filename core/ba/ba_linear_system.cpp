// makeBaLinearSystem: the BA linear system of an ISA's kernels (landmark_system.cpp, compiled per
// ISA; core/estimator/linearization_kernels.h holds the tables).

#include "core/ba/landmark_system.h"
#include "core/common/scalar.h"
#include "core/estimator/linearization_kernels.h"

namespace marglab {

template <typename Scalar>
std::unique_ptr<BaLinearSystem<Scalar>> makeBaLinearSystem(const BalProblem& problem,
                                                           BaElimination elimination,
                                                           ThreadPool& pool, Isa isa) {
  const IsaKernels& k = kernelsOf(isa);
  if constexpr (std::is_same_v<Scalar, float>) {
    return k.ba_f32.make_system(problem, elimination, pool);
  } else {
    return k.ba_f64.make_system(problem, elimination, pool);
  }
}

template <typename Scalar>
std::unique_ptr<BaLinearSystem<Scalar>> makeBaLinearSystem(const BalProblem& problem,
                                                           BaElimination elimination,
                                                           ThreadPool& pool) {
  return makeBaLinearSystem<Scalar>(problem, elimination, pool, activeIsa());
}

#define MARGLAB_INST(S)                                                                \
  template std::unique_ptr<BaLinearSystem<S>> makeBaLinearSystem<S>(                   \
      const BalProblem&, BaElimination, ThreadPool&, Isa);                             \
  template std::unique_ptr<BaLinearSystem<S>> makeBaLinearSystem<S>(const BalProblem&, \
                                                                    BaElimination, ThreadPool&);
MARGLAB_INSTANTIATE(MARGLAB_INST)
#undef MARGLAB_INST

}  // namespace marglab
