// The mass-spring experiment (primer §6): the two-stage method reproduces the single-stage
// Gauss–Newton state; the CLI prints the comparison. Timings are not asserted.

#include <gtest/gtest.h>

#include <cmath>

#include "core/massspring/mass_spring.h"
#include "test/common/cli_runner.h"

namespace marglab::massspring {
namespace {

TEST(MassSpringGrid, StructureOfThePrimersExample) {
  const MassSpringSystem s = MassSpringSystem::grid(GridSpec{});
  EXPECT_EQ(s.num_masses, 25);
  EXPECT_EQ(s.nonlinearMasses(), 12);
  EXPECT_EQ(s.springs.size(), 40u);
  int quartic = 0;
  for (const Spring& spring : s.springs) quartic += spring.p == 4 ? 1 : 0;
  EXPECT_EQ(quartic, 8);
  // At rest the springs carry no energy; only the anchors do.
  const std::vector<double> e = s.springEnergies(s.rest);
  for (std::size_t i = 0; i < s.springs.size(); ++i) EXPECT_EQ(e[i], 0.0);
}

class TwoStage : public ::testing::TestWithParam<std::tuple<int, ceres_marg::Method>> {};

TEST_P(TwoStage, AgreesWithSingleStage) {
  const auto [n, method] = GetParam();
  GridSpec spec;
  spec.n = n;
  const MassSpringSystem system = MassSpringSystem::grid(spec);
  const SingleStageResult single = solveSingleStage(system, 10);
  const TwoStageResult two = solveTwoStage(system, 10, method);
  ASSERT_TRUE(two.status.ok()) << two.status.toString();
  EXPECT_EQ(single.rejected_steps, 0);
  EXPECT_EQ(two.stage1_rejected_steps, 0);
  EXPECT_EQ(two.marginalization.marginalized_blocks, system.num_masses - 12);
  // Translation of the blanket is a gauge of the (anchor-free) eliminated springs.
  EXPECT_EQ(two.marginalization.prior_rank, two.marginalization.blanket_dim - 2);
  double diff = 0;
  for (std::size_t i = 0; i < single.x.size(); ++i) {
    diff = std::max(diff, std::abs(single.x[i] - two.x[i]));
  }
  EXPECT_LT(diff, 1e-8);
  EXPECT_NEAR(two.final_cost, system.energy(single.x), 1e-10 * system.energy(single.x));
}

INSTANTIATE_TEST_SUITE_P(
    Grids, TwoStage,
    ::testing::Values(std::make_tuple(5, ceres_marg::Method::kQr),
                      std::make_tuple(5, ceres_marg::Method::kSchur),
                      std::make_tuple(5, ceres_marg::Method::kSparseSchur),
                      std::make_tuple(12, ceres_marg::Method::kSparseSchur)),
    [](const ::testing::TestParamInfo<std::tuple<int, ceres_marg::Method>>& info) {
      std::string name = std::to_string(std::get<0>(info.param)) + "x" +
                         std::to_string(std::get<0>(info.param)) + "_" +
                         ceres_marg::toString(std::get<1>(info.param));
      for (char& c : name) c = c == '-' ? '_' : c;
      return name;
    });

TEST(MassSpringCli, JsonHasTheComparison) {
  const test::CliResult r = test::runCli("massspring --grid 5 --reps 1 --json --no-plot");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  for (const char* key : {"\"single_stage_ms\"", "\"two_stage_ms\"", "\"speedup\"",
                          "\"max_abs_diff\"", "\"scaling\":[]",
                          "\"primer_table1\":{\"single_stage_ms_per_iteration\":14.2,"
                          "\"two_stage_ms_per_iteration\":1.4}"}) {
    EXPECT_NE(r.output.find(key), std::string::npos) << key << " in " << r.output;
  }
}

TEST(MassSpringCli, TablesWithScaling) {
  const test::CliResult r = test::runCli("massspring --reps 1 --sizes 5,6 --no-plot");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("two-stage, qr"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("6x6"), std::string::npos) << r.output;
  // The primer's Table 1 (experiments/paper_values.toml) beside ours.
  EXPECT_NE(r.output.find("primer Table 1 beside ours"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("| single stage |      14.2 |"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("| two-stage    |       1.4 |"), std::string::npos) << r.output;
}

TEST(MassSpringCli, UsageErrors) {
  EXPECT_EQ(test::runCli("massspring --method lu --no-plot").exit_code, 2);
  EXPECT_EQ(test::runCli("massspring --grid 3 --no-plot").exit_code, 2);
  EXPECT_EQ(test::runCli("massspring --sizes 5,x --no-plot").exit_code, 2);
}

}  // namespace
}  // namespace marglab::massspring
