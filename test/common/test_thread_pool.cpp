// ThreadPool: every index is visited exactly once, in contiguous chunks whose split depends only
// on n and the thread count, and the pool survives many jobs (the estimator runs a few per LM
// iteration).

#include <gtest/gtest.h>

#include <atomic>
#include <numeric>
#include <vector>

#include "core/common/thread_pool.h"

namespace marglab {
namespace {

TEST(ThreadPool, VisitsEveryIndexOnceInContiguousChunks) {
  for (int threads : {1, 2, 3, 8}) {
    ThreadPool pool(threads);
    EXPECT_EQ(pool.threads(), threads);
    for (size_t n : {size_t{0}, size_t{1}, size_t{5}, size_t{1000}}) {
      std::vector<int> visits(n, 0);
      std::vector<std::pair<size_t, size_t>> ranges(static_cast<size_t>(threads), {0, 0});
      pool.forChunks(n, [&](size_t begin, size_t end, int chunk) {
        ranges[static_cast<size_t>(chunk)] = {begin, end};
        for (size_t i = begin; i < end; ++i) ++visits[i];
      });
      for (size_t i = 0; i < n; ++i) EXPECT_EQ(visits[i], 1) << threads << " threads, n " << n;
      // Chunks tile [0, n) in order, sizes differing by at most one.
      size_t next = 0;
      for (const auto& [begin, end] : ranges) {
        EXPECT_EQ(begin, next);
        EXPECT_LE(end - begin, n / static_cast<size_t>(threads) + 1);
        next = end;
      }
      EXPECT_EQ(next, n);
    }
  }
}

TEST(ThreadPool, ChunkOrderedReductionIsReproducible) {
  std::vector<float> values(10007);
  for (size_t i = 0; i < values.size(); ++i) values[i] = 1.0f / static_cast<float>(i + 1);
  auto reduce = [&](ThreadPool& pool) {
    std::vector<float> partial(static_cast<size_t>(pool.threads()), 0.0f);
    pool.forChunks(values.size(), [&](size_t begin, size_t end, int chunk) {
      float sum = 0;
      for (size_t i = begin; i < end; ++i) sum += values[i];
      partial[static_cast<size_t>(chunk)] = sum;
    });
    return std::accumulate(partial.begin(), partial.end(), 0.0f);
  };
  ThreadPool one(1), three(3);
  EXPECT_EQ(reduce(one), std::accumulate(values.begin(), values.end(), 0.0f));
  const float first = reduce(three);
  for (int repeat = 0; repeat < 200; ++repeat) ASSERT_EQ(reduce(three), first);
}

TEST(ThreadPool, RunsManyJobsAndUsesSeveralThreads) {
  ThreadPool pool(4);
  std::atomic<int> total{0};
  for (int job = 0; job < 2000; ++job) {
    pool.forChunks(4,
                   [&](size_t begin, size_t end, int) { total += static_cast<int>(end - begin); });
  }
  EXPECT_EQ(total.load(), 8000);
}

}  // namespace
}  // namespace marglab
