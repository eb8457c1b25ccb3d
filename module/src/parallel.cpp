// The thread pool behind ClothSettings::threads.
#include "parallel.hpp"

#include <algorithm>
#include <chrono>

namespace drape::detail {

ThreadPool::ThreadPool(int threads) {
    const int extra = std::max(threads, 1) - 1;
    for (int i = 0; i < extra; ++i)
        workers_.emplace_back([this] { workerLoop(); });
}

ThreadPool::~ThreadPool() {
    {
        std::lock_guard<std::mutex> lock(mutex_);
        stop_.store(true, std::memory_order_relaxed);
    }
    start_.notify_all();
    for (auto& w : workers_)
        w.join();
}

void ThreadPool::parallelFor(std::size_t n, std::size_t grain, const Body& body) {
    const std::size_t maxChunks = std::min<std::size_t>(
        threads(), std::max<std::size_t>(1, n / std::max<std::size_t>(grain, 1)));
    if (maxChunks <= 1) {
        if (n > 0) body(0, n);
        return;
    }
    // The range is cut into more pieces than threads, and every thread (the caller too) takes
    // pieces until none is left. A worker that the system wakes late (on a virtual machine a
    // sleeping thread can take milliseconds to run again) then costs nothing but its share:
    // with one chunk per thread the caller waited for it, and two threads were as slow as one.
    const std::size_t pieces = maxChunks * kPiecesPerThread;
    {
        std::lock_guard<std::mutex> lock(mutex_);
        job_ = &body;
        jobSize_ = n;
        pieces_ = pieces;
        next_.store(0, std::memory_order_relaxed);
        done_.store(0, std::memory_order_relaxed);
        generation_.fetch_add(1, std::memory_order_release);
    }
    start_.notify_all();
    takePieces();
    std::unique_lock<std::mutex> lock(mutex_);
    finished_.wait(lock, [&] {
        return done_.load(std::memory_order_acquire) == pieces && participants_ == 0;
    });
    job_ = nullptr; // a worker that wakes from now on finds no job
}

void ThreadPool::takePieces() {
    for (;;) {
        const std::size_t k = next_.fetch_add(1, std::memory_order_relaxed);
        if (k >= pieces_) return;
        (*job_)(jobSize_ * k / pieces_, jobSize_ * (k + 1) / pieces_);
        if (done_.fetch_add(1, std::memory_order_acq_rel) + 1 == pieces_) {
            std::lock_guard<std::mutex> lock(mutex_);
            finished_.notify_all();
        }
    }
}

namespace {
/// A hint to the processor that this thread is waiting in a loop.
inline void cpuRelax() {
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#endif
}
} // namespace

void ThreadPool::workerLoop() {
    std::uint64_t seen = 0;
    for (;;) {
        // A step runs several loops with short sequential parts between them: a worker that
        // waits for the next one a little before it sleeps is there when it starts (waking a
        // sleeping thread costs tens of microseconds on a virtual machine).
        const auto until = std::chrono::steady_clock::now() + kSpin;
        while (generation_.load(std::memory_order_acquire) == seen &&
               !stop_.load(std::memory_order_relaxed)) {
            for (int k = 0; k < 64; ++k)
                cpuRelax();
            if (std::chrono::steady_clock::now() >= until) break;
        }
        {
            std::unique_lock<std::mutex> lock(mutex_);
            start_.wait(lock, [&] {
                return stop_.load(std::memory_order_relaxed) ||
                       generation_.load(std::memory_order_relaxed) != seen;
            });
            if (stop_.load(std::memory_order_relaxed)) return;
            seen = generation_.load(std::memory_order_relaxed);
            if (job_ == nullptr) continue; // woke after the caller had finished the job
            ++participants_;
        }
        takePieces();
        std::lock_guard<std::mutex> lock(mutex_);
        --participants_;
        finished_.notify_all();
    }
}

} // namespace drape::detail
