// drape/executor.hpp: where a cloth's data-parallel loops run.
//
// A cloth splits its per-particle and per-spring passes (forces, integration, the limiter's scan)
// over threads through an Executor. Without one it uses its own small pool when
// ClothSettings::threads > 1, else the calling thread. A program that already owns threads (a
// game's job system, a oneTBB task arena) hands the cloth an Executor over them instead
// (Cloth::setExecutor), so the cloth's loops and the rest of the frame share one set of threads;
// drape::bullet does this with the world's task arena (BulletClothSettings::threads).
//
// Determinism: every loop a cloth gives an executor writes each output element from one piece
// only and reduces nothing across pieces, so a step's results are bit-identical for any executor,
// any thread count and any split of the range into pieces.
#pragma once

#include <cstddef>
#include <functional>

namespace drape {

class Executor {
  public:
    using Body = std::function<void(std::size_t begin, std::size_t end)>;

    virtual ~Executor() = default;

    /// The number of threads loops may run on at once (>= 1), the caller's included.
    virtual int concurrency() const = 0;

    /// Calls body(begin, end) on contiguous pieces that cover [0, n) exactly once, on any of the
    /// executor's threads, and returns when every piece has run. `grain` is the fewest elements
    /// the cloth wants in a piece when its threads must be woken for the loop (the cloth's own
    /// pool: 32768 for the per-particle passes, 1 for loops over blocks of springs); an
    /// executor whose threads stay ready between loops may cut pieces a few times smaller
    /// (drape::bullet's arena takes an eighth). A loop of fewer than two pieces is best run as
    /// one call on the calling thread. Called only from the thread that steps the cloth (or
    /// from a task the executor itself runs); must not throw unless body throws.
    virtual void parallelFor(std::size_t n, std::size_t grain, const Body& body) = 0;
};

} // namespace drape
