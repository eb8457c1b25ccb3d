// Internal: a small fixed thread pool for data-parallel loops over index ranges.
//
// Determinism: parallelFor splits [0, n) into contiguous chunks and runs `body(begin, end)` on
// each; the loops that use it write each output element from one chunk only and never
// reduce across chunks in floating point, so results are bit-identical for any thread count.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace drape::detail {

class ThreadPool {
  public:
    /// `threads` >= 1 is the total number of threads including the caller's.
    explicit ThreadPool(int threads);
    ~ThreadPool();
    ThreadPool(const ThreadPool&) = delete;
    ThreadPool& operator=(const ThreadPool&) = delete;

    int threads() const { return static_cast<int>(workers_.size()) + 1; }

    /// Runs body over [0, n) in up to threads() contiguous chunks; the calling thread takes
    /// the first chunk. Loops shorter than `grain` per thread run inline. The default suits
    /// the per-particle and per-slot passes (a few ns per element): waking a worker costs
    /// tens of microseconds on a virtual machine, so below ~32k elements per thread a second
    /// thread makes the step slower (measured: a 100 x 100 sheet took 0.40 ms/step on 2
    /// threads and 0.32 ms on 1 with a grain of 4096).
    void parallelFor(std::size_t n, const std::function<void(std::size_t, std::size_t)>& body,
                     std::size_t grain = 32768);

  private:
    void workerLoop(std::size_t index);

    std::vector<std::thread> workers_;
    std::mutex mutex_;
    std::condition_variable start_;
    std::condition_variable done_;
    const std::function<void(std::size_t, std::size_t)>* job_ = nullptr;
    std::size_t jobSize_ = 0;
    std::size_t chunks_ = 0;
    std::size_t pending_ = 0;
    std::uint64_t generation_ = 0;
    bool stop_ = false;
};

/// Runs body(begin, end) over [0, n): on the pool in chunks when there is one, else as one
/// call on this thread.
template <class Body> void forChunks(ThreadPool* pool, std::size_t n, Body&& body) {
    if (pool) {
        pool->parallelFor(n, body);
    } else {
        body(std::size_t{0}, n);
    }
}

} // namespace drape::detail
