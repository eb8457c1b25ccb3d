// drape/timers.hpp: per-phase wall-clock counters, readable by callers after any step.
#pragma once

#include <chrono>
#include <cstdint>
#include <string>
#include <vector>

namespace drape {

/// Accumulated cost of one named phase of the step pipeline.
struct PhaseTimer {
    std::string name;        ///< "integrate", "springs", "strain_limit", ...
    std::uint64_t calls = 0; ///< times the phase ran
    double seconds = 0.0;    ///< total wall time spent in it [s]
};

/// A set of named counters; phases register once and are then addressed by slot number.
class PhaseTimers {
  public:
    /// Returns the slot of `name`, registering it on first use.
    std::size_t slot(const std::string& name);
    void add(std::size_t slot, double seconds) {
        timers_[slot].calls += 1;
        timers_[slot].seconds += seconds;
    }
    const std::vector<PhaseTimer>& all() const { return timers_; }
    /// The counter called `name`, or nullptr if no phase of that name has run.
    const PhaseTimer* find(const std::string& name) const;
    void reset();

  private:
    std::vector<PhaseTimer> timers_;
};

/// Times a scope into one slot of a PhaseTimers.
class ScopedPhase {
  public:
    ScopedPhase(PhaseTimers& timers, std::size_t slot)
        : timers_(timers), slot_(slot), start_(std::chrono::steady_clock::now()) {}
    ~ScopedPhase() {
        const auto end = std::chrono::steady_clock::now();
        timers_.add(slot_, std::chrono::duration<double>(end - start_).count());
    }
    ScopedPhase(const ScopedPhase&) = delete;
    ScopedPhase& operator=(const ScopedPhase&) = delete;

  private:
    PhaseTimers& timers_;
    std::size_t slot_;
    std::chrono::steady_clock::time_point start_;
};

} // namespace drape
