#include "core/common/thread_pool.h"

namespace marglab {

ThreadPool::ThreadPool(int threads) {
  for (int chunk = 1; chunk < threads; ++chunk) {
    workers_.emplace_back([this, chunk] { work(chunk); });
  }
}

ThreadPool::~ThreadPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  start_.notify_all();
  for (std::thread& worker : workers_) worker.join();
}

void ThreadPool::forChunks(size_t n, const std::function<void(size_t, size_t, int)>& fn) {
  const size_t k = static_cast<size_t>(threads());
  if (k == 1) {
    fn(0, n, 0);
    return;
  }
  // Chunk c covers [c·n/k, (c+1)·n/k): sizes differ by at most one.
  const std::function<void(int)> job = [&](int chunk) {
    const size_t c = static_cast<size_t>(chunk);
    fn(c * n / k, (c + 1) * n / k, chunk);
  };
  {
    std::lock_guard<std::mutex> lock(mutex_);
    job_ = &job;
    pending_ = static_cast<int>(workers_.size());
    ++generation_;
  }
  start_.notify_all();
  job(0);
  std::unique_lock<std::mutex> lock(mutex_);
  done_.wait(lock, [this] { return pending_ == 0; });
  job_ = nullptr;
}

void ThreadPool::work(int chunk) {
  std::uint64_t seen = 0;
  while (true) {
    const std::function<void(int)>* job = nullptr;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      start_.wait(lock, [&] { return stop_ || generation_ != seen; });
      if (stop_) return;
      seen = generation_;
      job = job_;
    }
    (*job)(chunk);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (--pending_ == 0) done_.notify_one();
    }
  }
}

}  // namespace marglab
