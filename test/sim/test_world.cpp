// World generation (core/sim/world.h): determinism, geometry of the indoor box and the street,
// the chunk index, and the platform-independent random numbers.

#include <gtest/gtest.h>

#include <cmath>

#include "core/common/error.h"
#include "core/sim/world.h"
#include "sim_test_utils.h"

namespace marglab {
namespace {

TEST(SimRandom, UniformAndNormalMoments) {
  SimRandom rng(42);
  const int n = 200000;
  double sum_u = 0, sum_n = 0, sum_n2 = 0, min_u = 1, max_u = 0;
  for (int i = 0; i < n; ++i) {
    const double u = rng.uniform();
    min_u = std::min(min_u, u);
    max_u = std::max(max_u, u);
    sum_u += u;
    const double x = rng.normal();
    sum_n += x;
    sum_n2 += x * x;
  }
  EXPECT_GE(min_u, 0.0);
  EXPECT_LT(max_u, 1.0);
  // 5σ bounds of the sample means: σ(ū) = 1/√(12 n), σ(x̄) = 1/√n, σ(mean x²) = √(2/n).
  EXPECT_NEAR(sum_u / n, 0.5, 5 / std::sqrt(12.0 * n));
  EXPECT_NEAR(sum_n / n, 0.0, 5 / std::sqrt(1.0 * n));
  EXPECT_NEAR(sum_n2 / n, 1.0, 5 * std::sqrt(2.0 / n));
}

TEST(SimRandom, StreamFixedBySeed) {
  // mt19937_64 is specified by the standard: its 10000th output from the default seed 5489.
  std::mt19937_64 engine;
  engine.discard(9999);
  EXPECT_EQ(engine(), 9981545732273789042ULL);
  SimRandom a(7), b(7), c(8);
  for (int i = 0; i < 100; ++i) {
    const double x = a.normal();
    EXPECT_EQ(x, b.normal());
    EXPECT_NE(x, c.normal());
  }
  EXPECT_NE(SimRandom::subSeed(1, 2), SimRandom::subSeed(1, 3));
}

void expectSameWorld(const World& a, const World& b) {
  ASSERT_EQ(a.points_w.size(), b.points_w.size());
  for (std::size_t i = 0; i < a.points_w.size(); ++i) {
    ASSERT_EQ(a.points_w[i], b.points_w[i]) << i;
    ASSERT_EQ(a.normals_w[i], b.normals_w[i]) << i;
  }
  ASSERT_EQ(a.walls.size(), b.walls.size());
}

TEST(World, DeterministicForSeed) {
  const test::IndoorLoop loop(20.0);
  const WorldOptions options = defaultWorldOptions(DatasetKind::kEuroc);
  const World a = makeWorld(loop, options, 3);
  expectSameWorld(a, makeWorld(loop, options, 3));
  const World c = makeWorld(loop, options, 4);
  EXPECT_FALSE(a.points_w.size() == c.points_w.size() &&
               std::equal(a.points_w.begin(), a.points_w.end(), c.points_w.begin()));
}

TEST(World, IndoorBoxAroundThePath) {
  const test::IndoorLoop loop(40.0);  // x ∈ [−4, 4], y ∈ [−3, 3], z ∈ [1.2, 1.8]
  const WorldOptions o = defaultWorldOptions(DatasetKind::kEuroc);
  const World world = makeWorld(loop, o, 1);
  const Eigen::Vector3d lo(-4 - o.horizontal_margin, -3 - o.horizontal_margin,
                           1.2 - o.floor_margin);
  const Eigen::Vector3d hi(4 + o.horizontal_margin, 3 + o.horizontal_margin,
                           1.8 + o.ceiling_margin);
  const double tol = 0.01;  // the path is sampled, its bounding box is approximate
  std::size_t on_floor = 0, free_points = 0;
  for (std::size_t i = 0; i < world.points_w.size(); ++i) {
    const Eigen::Vector3d& p = world.points_w[i];
    ASSERT_TRUE((p.array() >= lo.array() - tol).all() && (p.array() <= hi.array() + tol).all())
        << p.transpose();
    if (std::abs(p.z() - lo.z()) < tol) ++on_floor;
    const double n = world.normals_w[i].norm();
    ASSERT_TRUE(n == 0 || std::abs(n - 1) < 1e-12);
    if (n == 0) {
      ++free_points;
      // Free clutter points keep the clearance to the path (checked at 0.1 s samples).
      for (int64_t t = 0; t <= loop.endTimeNs(); t += 100'000'000) {
        ASSERT_GE((loop.evaluate(t).p_w_b - p).norm(), o.path_clearance - 0.05);
      }
    }
  }
  // Floor area × density within 5 % (plus clutter-box tops do not lie on the floor).
  const double floor_area = (hi.x() - lo.x()) * (hi.y() - lo.y());
  EXPECT_NEAR(static_cast<double>(on_floor), floor_area * o.surface_density,
              0.05 * floor_area * o.surface_density);
  EXPECT_GT(free_points, 0u);
  EXPECT_TRUE(world.walls.empty());
}

TEST(World, StreetFacadesGroundAndFarPoints) {
  const test::StreetDrive drive(20.0);  // 200 m, x ≈ 8 sin(0.05 t), y down
  const WorldOptions o = defaultWorldOptions(DatasetKind::kKitti);
  const World world = makeWorld(drive, o, 1);
  std::size_t left = 0, right = 0, ground = 0, far = 0;
  for (std::size_t i = 0; i < world.points_w.size(); ++i) {
    const Eigen::Vector3d& p = world.points_w[i];
    const double height = o.camera_height - p.y();  // above the ground (world y down, flat road)
    ASSERT_GE(height, -1e-9);
    ASSERT_LE(height, std::max(o.facade_height, o.far_height) + 1e-9);
    const double lateral = p.x() - 8 * std::sin(0.05 * p.z() / 10);
    if (world.normals_w[i].isZero()) {
      ++far;
    } else if (std::abs(height) < 1e-9) {
      ++ground;
      ASSERT_LE(std::abs(lateral), o.ground_half_width + 0.5);
    } else {
      // Facade points face the road and lie 5–12 m to the side (up to the road's curvature).
      ASSERT_LE(world.normals_w[i].x() * lateral, 0.0);
      ASSERT_GE(std::abs(lateral), o.facade_offset_min - 0.5);
      ASSERT_LE(std::abs(lateral), o.facade_offset_max + 0.5);
      (lateral > 0 ? right : left) += 1;
    }
  }
  EXPECT_GT(left, 100u);
  EXPECT_GT(right, 100u);
  EXPECT_GT(ground, 100u);
  EXPECT_GT(far, 30u);
  EXPECT_FALSE(world.walls.empty());
}

// A straight walk that jumps `jump_m` along x at 0.5 s (an implausible pose the spline follows).
class JumpingWalk : public TrajectoryFunction {
 public:
  explicit JumpingWalk(double jump_m) : jump_m_(jump_m) {}
  int64_t startTimeNs() const override { return 0; }
  int64_t endTimeNs() const override { return 1'000'000'000; }
  TrajectorySample evaluate(int64_t t_ns) const override {
    TrajectorySample s;
    s.p_w_b = Eigen::Vector3d(t_ns >= 500'000'000 ? jump_m_ : 0.0, 1e-9 * t_ns, 1.5);
    return s;
  }

 private:
  double jump_m_;
};

TEST(World, RefusedBeyondItsSizeBoundBeforeItIsBuilt) {
  for (const DatasetKind kind : {DatasetKind::kEuroc, DatasetKind::kKitti}) {
    const WorldOptions o = defaultWorldOptions(kind);
    EXPECT_NO_THROW(makeWorld(JumpingWalk(0.0), o, 1));
    for (const double jump : {1e8, 1e300}) {
      try {
        makeWorld(JumpingWalk(jump), o, 1);
        ADD_FAILURE() << "expected InputError for a jump of " << jump;
      } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("more than the limit of 5e+06: is the trajectory "
                                             "plausible?"),
                  std::string::npos)
            << e.what();
      }
    }
  }
  // The bound is an option: the 200 m street (~3900 points) is refused under 1000.
  WorldOptions small = defaultWorldOptions(DatasetKind::kKitti);
  small.max_points = 1000;
  EXPECT_THROW(makeWorld(test::StreetDrive(20.0), small, 1), InputError);
}

TEST(World, ChunksCoverThePointsAndBoundThem) {
  SimRandom rng(5);
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < 5000; ++i) {
    points.emplace_back(rng.uniform(-30, 30), rng.uniform(-30, 30), rng.uniform(0, 10));
  }
  const World world = indexWorld(points, {}, 8.0);
  ASSERT_EQ(world.points_w.size(), points.size());
  uint32_t next = 0;
  for (const WorldChunk& chunk : world.chunks) {
    ASSERT_EQ(chunk.begin, next);
    ASSERT_GT(chunk.end, chunk.begin);
    next = chunk.end;
    for (uint32_t i = chunk.begin; i < chunk.end; ++i) {
      ASSERT_LE((world.points_w[i] - chunk.centre).norm(), chunk.radius * (1 + 1e-12));
      ASSERT_LE(chunk.radius, 0.5 * std::sqrt(3.0) * 8.0 + 1e-9);
    }
  }
  EXPECT_EQ(next, points.size());
  // A permutation of the input.
  auto key = [](const Eigen::Vector3d& p) { return std::make_tuple(p.x(), p.y(), p.z()); };
  std::vector<std::tuple<double, double, double>> a, b;
  for (const auto& p : points) a.push_back(key(p));
  for (const auto& p : world.points_w) b.push_back(key(p));
  std::sort(a.begin(), a.end());
  std::sort(b.begin(), b.end());
  EXPECT_EQ(a, b);
}

}  // namespace
}  // namespace marglab
