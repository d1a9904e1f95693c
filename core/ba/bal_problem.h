#pragma once
// A BAL bundle-adjustment problem ("Bundle Adjustment in the Large", Agarwal et al., ECCV 2010;
// datasets/bal/README.md) and its loader.
//
// File format (whitespace-separated numbers; the loader reads any layout of them, the files have
// one observation or one parameter per line):
//     num_cameras num_points num_observations
//     camera point x y                    × num_observations (pixels from the image centre, y up)
//     ω₁ ω₂ ω₃ t₁ t₂ t₃ f k1 k2           × num_cameras (one number per line in the files)
//     X₁ X₂ X₃                            × num_points
// The file may be bzip2-compressed (recognized by its "BZh" magic, whatever its name); it is
// decompressed in memory with libbz2. Every malformed input — a missing or non-numeric field, an
// index out of range, a non-positive count, a non-finite number, data after the last point —
// throws InputError naming the file and the 1-based line of the offending field.

#include <cstdint>
#include <string>
#include <vector>

#include "core/common/eigen_types.h"

namespace marglab {

struct BalObservation {
  int camera = 0;
  int point = 0;
  Vec<double, 2> z = Vec<double, 2>::Zero();  // pixels
};

struct BalProblem {
  std::string name;  // the file name without folders and .txt / .bz2
  std::vector<BalObservation> observations;
  std::vector<Vec<double, 9>> cameras;  // ω, t, f, k1, k2 (snavely_camera.h)
  std::vector<Vec3<double>> points;

  int numCameras() const { return static_cast<int>(cameras.size()); }
  int numPoints() const { return static_cast<int>(points.size()); }
  int numObservations() const { return static_cast<int>(observations.size()); }
};

BalProblem loadBalProblem(const std::string& path);

// The name of the problem of a file: its name without folders and .txt / .bz2
// ("ladybug-problem-49-7776-pre").
std::string balProblemName(const std::string& path);

// The file's bytes, bzip2-decompressed when they start with "BZh"; InputError(path, 0, …) when the
// file cannot be read or the bzip2 stream is corrupt.
std::string readPlainOrBzip2(const std::string& path);

// rootba's / Ceres' normalization (BALProblem::Normalize): with m the coordinate-wise median of
// the points and s = scale / median_i ‖X_i − m‖₁, every point X ← s (X − m) and every camera
// centre C = −Rᵀt ← s (C − m) (t ← −R C); rotations and intrinsics are unchanged. Reprojection
// residuals are invariant.
void normalizeBalProblem(BalProblem* problem, double scale);

// rootba's perturbation (BalProblem::perturb, translation and landmark σ, no rotation): every
// camera centre and every point moves by an independent N(0, σ²I₃) draw, from std::mt19937_64
// seeded with `seed` (libstdc++'s normal distribution: reproducible here, not rootba's draws).
void perturbBalProblem(BalProblem* problem, double sigma, std::uint64_t seed);

}  // namespace marglab
