// core/common/statistics.h against values worked out by hand.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <vector>

#include "core/common/statistics.h"

namespace marglab {
namespace {

TEST(Statistics, MeanOfASampleAndNanForNone) {
  EXPECT_EQ(mean({1.0, 2.0, 6.0}), 3.0);
  EXPECT_TRUE(std::isnan(mean({})));
}

TEST(Statistics, MedianAveragesTheMiddlePairOfAnEvenCount) {
  EXPECT_EQ(median({3.0, 1.0, 2.0}), 2.0);
  EXPECT_EQ(median({4.0, 1.0, 3.0, 2.0}), 2.5);
  EXPECT_EQ(median({5.0}), 5.0);
  EXPECT_TRUE(std::isnan(median({})));
}

TEST(Statistics, UpperMedianIsAValueOfTheSample) {
  EXPECT_EQ(upperMedian({3.0, 1.0, 2.0}), 2.0);
  EXPECT_EQ(upperMedian({4.0, 1.0, 3.0, 2.0}), 3.0);
  EXPECT_EQ(upperMedian({-1.0, 7.0}), 7.0);
}

TEST(Statistics, MedianGapIgnoresADroppedSampleAndABurst) {
  // 200 Hz with one sample dropped (a 10 ms gap) and one duplicated early (a 1 ms gap).
  const std::vector<std::int64_t> t_ns{0,          5'000'000,  15'000'000, 20'000'000,
                                       21'000'000, 25'000'000, 30'000'000};
  EXPECT_EQ(medianGapNs(t_ns), 5'000'000);
  EXPECT_EQ(medianGapNs({10, 17}), 7);
}

}  // namespace
}  // namespace marglab
