// drape/executor.hpp: where a cloth's data-parallel loops run.
//
// A cloth splits its per-particle and per-spring passes (forces, integration, the limiter's scan)
// over threads through an Executor. Without one it uses its own small pool when
// ClothSettings::threads > 1, else the calling thread. A program that already owns threads (a
// game's job system, a oneTBB task arena) hands the cloth an Executor over them instead
// (Cloth::setExecutor), so the cloth's loops and the rest of the frame share one set of threads;
// drape::bullet does this for a cloth with ClothSettings::threads > 1 with the world's arena.
//
// Determinism: every loop a cloth gives an executor writes each output element from one piece
// only and reduces nothing across pieces, so a step's results are bit-identical for any executor,
// any thread count and any split of the range into pieces, provided the executor's threads
// compute as the calling thread does (the same floating-point environment: rounding mode and
// flush-to-zero / denormals-are-zero flags, which some job systems set on their threads).
#pragma once

#include <cstddef>
#include <functional>

namespace drape {

class Executor {
  public:
    using Body = std::function<void(std::size_t begin, std::size_t end)>;

    virtual ~Executor() = default;

    /// The number of threads loops may run on at once (>= 1), the caller's included: for the
    /// program's information (drape::bullet compares it with the arena it wants).
    virtual int concurrency() const = 0;

    /// Calls body(begin, end) on contiguous pieces that cover [0, n) exactly once, on any of the
    /// executor's threads, and returns when every piece has run.
    ///
    /// `grain` says how fine a split pays: below about `grain` elements per thread, splitting
    /// the loop costs more than it saves when the threads have to be woken for it. The cloth
    /// passes 32768 for its per-particle and per-slot passes (a few ns per element) and 1 or 2
    /// for loops over blocks of springs or segments of slots (each a large piece of work). The
    /// cloth's own pool runs a loop on the calling thread below two grains and otherwise cuts
    /// it into 4 pieces per thread used; drape::bullet's oneTBB arena, whose workers stay ready,
    /// cuts pieces of at most grain / 8.
    ///
    /// The cloth calls it from the thread that steps the cloth (possibly a task of this
    /// executor); an executor shared by several cloths stepped at once gets concurrent calls.
    /// The cloth's loop bodies do not throw.
    virtual void parallelFor(std::size_t n, std::size_t grain, const Body& body) = 0;
};

} // namespace drape
