#pragma once
// A fixed set of worker threads for data-parallel loops over index ranges (the estimator's
// landmark blocks). forChunks splits [0, n) into threads() contiguous chunks, runs chunk 0 on the
// calling thread and the others on the workers, and returns when all are done. The split depends
// only on n and the thread count, so a reduction done per chunk and then in chunk order gives the
// same bits in every run with the same thread count; with one thread nothing is started and the
// loop runs inline, in index order.

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace marglab {

class ThreadPool {
 public:
  explicit ThreadPool(int threads);
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  int threads() const { return static_cast<int>(workers_.size()) + 1; }

  // Calls fn(begin, end, chunk) for every chunk of [0, n); chunks may be empty when n < threads().
  // fn must not throw.
  void forChunks(size_t n, const std::function<void(size_t, size_t, int)>& fn);

 private:
  void work(int chunk);

  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable start_, done_;
  const std::function<void(int)>* job_ = nullptr;
  std::atomic<std::uint64_t> generation_{0};
  std::atomic<int> pending_{0};
  std::atomic<bool> stop_{false};
};

}  // namespace marglab
