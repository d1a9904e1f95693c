#include "core/common/thread_pool.h"

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#endif

namespace marglab {
namespace {

// An LM iteration starts a few jobs of tens to hundreds of microseconds each, back to back: a
// futex sleep and wake per job costs as much as the job. Waiters therefore spin this many times
// before they block.
constexpr int kSpins = 20000;

inline void cpuRelax() {
#if defined(__x86_64__) || defined(__i386__)
  _mm_pause();
#endif
}

}  // namespace

ThreadPool::ThreadPool(int threads) {
  for (int chunk = 1; chunk < threads; ++chunk) {
    workers_.emplace_back([this, chunk] { work(chunk); });
  }
}

ThreadPool::~ThreadPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_.store(true);
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
    pending_.store(static_cast<int>(workers_.size()));
    generation_.fetch_add(1);
  }
  start_.notify_all();
  job(0);
  for (int spin = 0; spin < kSpins && pending_.load() != 0; ++spin) cpuRelax();
  std::unique_lock<std::mutex> lock(mutex_);
  done_.wait(lock, [this] { return pending_.load() == 0; });
  job_ = nullptr;
}

void ThreadPool::work(int chunk) {
  std::uint64_t seen = 0;
  while (true) {
    for (int spin = 0; spin < kSpins && generation_.load() == seen && !stop_.load(); ++spin) {
      cpuRelax();
    }
    const std::function<void(int)>* job = nullptr;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      start_.wait(lock, [&] { return stop_.load() || generation_.load() != seen; });
      if (stop_.load()) return;
      seen = generation_.load();
      job = job_;
    }
    (*job)(chunk);
    if (pending_.fetch_sub(1) == 1) {
      std::lock_guard<std::mutex> lock(mutex_);
      done_.notify_one();
    }
  }
}

}  // namespace marglab
