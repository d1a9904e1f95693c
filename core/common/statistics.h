#pragma once
// Sample statistics shared across the library: one definition each, so that a median means the
// same in a table, a report and a check.

#include <cstdint>
#include <vector>

namespace marglab {

// The arithmetic mean, summed in order; NaN for an empty sample.
double mean(const std::vector<double>& values);

// The median: for an even count the mean of the two middle values (as numpy's median); NaN for an
// empty sample.
double median(std::vector<double> values);

// The upper median: element n/2 of the sorted sample, for an even count the larger middle value.
// A value of the sample itself; rootba's and Ceres' BAL normalization take it. Requires a
// non-empty sample.
double upperMedian(std::vector<double> values);

// The upper median of the gaps between consecutive timestamps [ns]: a sampling period that
// dropped samples or a burst do not move. Requires at least two timestamps.
std::int64_t medianGapNs(const std::vector<std::int64_t>& t_ns);

}  // namespace marglab
