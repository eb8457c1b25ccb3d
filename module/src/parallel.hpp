// Internal: the cloth's own small fixed thread pool (the Executor a cloth uses when
// ClothSettings::threads > 1 and the caller gave it none), and the helpers the core's loops
// call their executor through.
//
// Determinism: parallelFor splits [0, n) into contiguous pieces and runs `body(begin, end)` on
// each, on whichever thread takes it; the loops that use it write each output element from one
// piece only, never reduce across pieces in floating point, and compute nothing that depends
// on where a piece starts, so results are bit-identical for any thread count or split.
#pragma once

#include "drape/executor.hpp"

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace drape::detail {

/// The grain of the per-particle and per-slot passes (a few ns per element): waking a worker
/// costs tens of microseconds on a virtual machine, so below ~32k elements per thread a second
/// thread made the step slower (measured: a 100 x 100 sheet took 0.40 ms/step on 2 threads and
/// 0.32 ms on 1 with a grain of 4096).
inline constexpr std::size_t kParticleGrain = 32768;

class ThreadPool final : public Executor {
  public:
    /// `threads` >= 1 is the total number of threads including the caller's.
    explicit ThreadPool(int threads);
    ~ThreadPool();
    ThreadPool(const ThreadPool&) = delete;
    ThreadPool& operator=(const ThreadPool&) = delete;

    int threads() const { return static_cast<int>(workers_.size()) + 1; }
    int concurrency() const override { return threads(); }

    /// Runs body over [0, n) in contiguous pieces (kPiecesPerThread per thread used), taken
    /// by the calling thread and the workers until none is left. Loops shorter than `grain` per
    /// thread run inline.
    void parallelFor(std::size_t n, std::size_t grain, const Body& body) override;

    static constexpr std::size_t kPiecesPerThread = 4;
    /// How long a worker waits for the next loop before it sleeps.
    static constexpr std::chrono::microseconds kSpin{200};

  private:
    void workerLoop();
    void takePieces();

    std::vector<std::thread> workers_;
    std::mutex mutex_;
    std::condition_variable start_;
    std::condition_variable finished_;
    const Body* job_ = nullptr;
    std::size_t jobSize_ = 0;
    std::size_t pieces_ = 0;
    std::atomic<std::size_t> next_{0};         ///< the next piece to take
    std::atomic<std::size_t> done_{0};         ///< pieces finished
    std::size_t participants_ = 0;             ///< workers inside takePieces (under mutex_)
    std::atomic<std::uint64_t> generation_{0}; ///< changed under mutex_, read by spinning workers
    std::atomic<bool> stop_{false};
};

/// Runs body(begin, end) over [0, n): on the executor in pieces of at least `grain` elements
/// when there is one, else as one call on this thread.
template <class F>
void forChunks(Executor* executor, std::size_t n, F&& body, std::size_t grain = kParticleGrain) {
    if (executor) {
        executor->parallelFor(n, grain, body);
    } else {
        body(std::size_t{0}, n);
    }
}

/// Copies positions into coordinate arrays (x of every particle, then y, then z) in `out`,
/// split over the pool's threads.
template <class Points>
void toCoordinateArrays(Executor* executor, const Points& x, std::vector<double>& out) {
    const std::size_t n = x.size();
    out.resize(3 * n);
    forChunks(executor, n, [&](std::size_t b, std::size_t e) {
        double* px = out.data();
        double* py = px + n;
        double* pz = py + n;
        for (std::size_t i = b; i < e; ++i) {
            px[i] = x[i][0];
            py[i] = x[i][1];
            pz[i] = x[i][2];
        }
    });
}

} // namespace drape::detail
