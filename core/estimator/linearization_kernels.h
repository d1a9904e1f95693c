#pragma once
// The per-ISA entry points of the hot kernels (docs/design.md §ISA dispatch).
//
// linearization_kernels.cpp (the landmark linearization), window_landmark.cpp (a landmark's
// reprojection rows), core/linalg/landmark_block.cpp and core/linalg/rcs_solve.cpp are compiled
// once per instruction set (core/isa_kernels.cmake: SSE2, AVX2 + FMA, AVX-512) with hidden
// visibility; each ISA's objects are partially linked and their
// hidden symbols made local, so every Eigen instantiation and every marglab function inside stays
// private to that ISA's copy (no weak symbol shared between copies for the linker to pick one of).
// The only symbol each copy exports is its kernels() table below; makeLinearization
// (linearization.h) takes the table of the active ISA (core/linalg/isa.h). The table also holds
// the bundle adjustment's linear system (core/ba/landmark_system.cpp, on the same landmark blocks;
// makeBaLinearSystem).

#include <memory>
#include <vector>

#include "core/ba/landmark_system.h"
#include "core/estimator/linearization.h"
#include "core/linalg/isa.h"
#include "core/linalg/landmark_block.h"

// The same Eigen ABI in every ISA copy and in the rest of the library (core/isa_kernels.cmake).
static_assert(EIGEN_MAX_ALIGN_BYTES == 16, "Eigen's alignment must be the SSE2 one everywhere");

#define MARGLAB_ISA_EXPORT __attribute__((visibility("default")))

namespace marglab {

template <typename Scalar>
struct LinearizationKernels {
  using Options = typename Linearization<Scalar>::Options;
  std::unique_ptr<Linearization<Scalar>> (*of_variant)(const Variant&, const Options&) = nullptr;
  std::unique_ptr<Linearization<Scalar>> (*of_elimination)(OptElimination,
                                                           const Options&) = nullptr;
  // The landmark QR kernel alone (LandmarkBlockNs::setFromJacobians on every landmark, for the
  // bench); false if one fails.
  bool (*landmark_qr)(const std::vector<LandmarkJacobians<Scalar>>&,
                      const std::vector<PoseBlockMap>&) = nullptr;
};

struct IsaKernels {
  Isa isa = Isa::kSse2;
  LinearizationKernels<float> f32;  // null entries without MARGLAB_WITH_FLOAT
  LinearizationKernels<double> f64;
  BaKernels<float> ba_f32;  // null without MARGLAB_WITH_FLOAT
  BaKernels<double> ba_f64;
};

namespace isa_sse2 {
MARGLAB_ISA_EXPORT const IsaKernels& kernels();
}
namespace isa_avx2 {
MARGLAB_ISA_EXPORT const IsaKernels& kernels();
}
namespace isa_avx512 {
MARGLAB_ISA_EXPORT const IsaKernels& kernels();
}

// The table of an ISA, and of the active one.
const IsaKernels& kernelsOf(Isa isa);
inline const IsaKernels& activeKernels() { return kernelsOf(activeIsa()); }

template <typename Scalar>
const LinearizationKernels<Scalar>& linearizationKernels(const IsaKernels& k) {
  if constexpr (std::is_same_v<Scalar, float>) {
    return k.f32;
  } else {
    return k.f64;
  }
}

}  // namespace marglab
