// The thread pool behind ClothSettings::threads.
#include "parallel.hpp"

#include <algorithm>

namespace drape::detail {

ThreadPool::ThreadPool(int threads) {
    const int extra = std::max(threads, 1) - 1;
    for (int i = 0; i < extra; ++i) {
        workers_.emplace_back([this, i] { workerLoop(static_cast<std::size_t>(i) + 1); });
    }
}

ThreadPool::~ThreadPool() {
    {
        std::lock_guard<std::mutex> lock(mutex_);
        stop_ = true;
    }
    start_.notify_all();
    for (auto& w : workers_)
        w.join();
}

void ThreadPool::parallelFor(std::size_t n,
                             const std::function<void(std::size_t, std::size_t)>& body,
                             std::size_t grain) {
    const std::size_t maxChunks = std::min<std::size_t>(
        threads(), std::max<std::size_t>(1, n / std::max<std::size_t>(grain, 1)));
    if (maxChunks <= 1) {
        if (n > 0) body(0, n);
        return;
    }
    {
        std::lock_guard<std::mutex> lock(mutex_);
        job_ = &body;
        jobSize_ = n;
        chunks_ = maxChunks;
        pending_ = maxChunks - 1;
        ++generation_;
    }
    start_.notify_all();
    body(0, n / maxChunks);
    std::unique_lock<std::mutex> lock(mutex_);
    done_.wait(lock, [&] { return pending_ == 0; });
    job_ = nullptr;
}

void ThreadPool::workerLoop(std::size_t index) {
    std::uint64_t seen = 0;
    for (;;) {
        const std::function<void(std::size_t, std::size_t)>* job;
        std::size_t n, chunks;
        {
            std::unique_lock<std::mutex> lock(mutex_);
            start_.wait(lock, [&] { return stop_ || generation_ != seen; });
            if (stop_) return;
            seen = generation_;
            job = job_;
            n = jobSize_;
            chunks = chunks_;
        }
        if (index < chunks) {
            (*job)(n * index / chunks, n * (index + 1) / chunks);
            std::lock_guard<std::mutex> lock(mutex_);
            if (--pending_ == 0) done_.notify_one();
        }
    }
}

} // namespace drape::detail
