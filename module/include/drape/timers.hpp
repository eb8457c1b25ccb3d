// drape/timers.hpp: per-phase counters of wall time and, on request, of the stepping thread's
// CPU time, readable by callers after any step (Cloth::timers()).
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
    /// Total CPU time of the thread that ran it [s]: counted only while
    /// PhaseTimers::measureThreadCpuTime(true) (else 0). Unlike wall time it leaves out the
    /// time the thread waited for a core, so it measures the phase on a loaded machine.
    double cpuSeconds = 0.0;
};

/// CPU time the calling thread has used [s] (POSIX CLOCK_THREAD_CPUTIME_ID; elsewhere the
/// process's CPU time, std::clock). A system call: about a microsecond or less.
double threadCpuSeconds();

/// A set of named counters; phases register once and are then addressed by slot number.
class PhaseTimers {
  public:
    /// Returns the slot of `name`, registering it on first use.
    std::size_t slot(const std::string& name);
    void add(std::size_t slot, double seconds, double cpuSeconds = 0.0) {
        timers_[slot].calls += 1;
        timers_[slot].seconds += seconds;
        timers_[slot].cpuSeconds += cpuSeconds;
    }
    /// Also count each phase's thread CPU time (PhaseTimer::cpuSeconds). Off by default: it
    /// costs two system calls per timed phase, a few per cent of a small cloth's step.
    void measureThreadCpuTime(bool on) { cpu_ = on; }
    bool measuresThreadCpuTime() const { return cpu_; }
    const std::vector<PhaseTimer>& all() const { return timers_; }
    /// The counter called `name`, or nullptr if no phase of that name has run.
    const PhaseTimer* find(const std::string& name) const;
    void reset();

  private:
    std::vector<PhaseTimer> timers_;
    bool cpu_ = false;
};

/// Times a scope into one slot of a PhaseTimers.
class ScopedPhase {
  public:
    ScopedPhase(PhaseTimers& timers, std::size_t slot)
        : timers_(timers), slot_(slot),
          cpuStart_(timers.measuresThreadCpuTime() ? threadCpuSeconds() : 0.0),
          start_(std::chrono::steady_clock::now()) {}
    ~ScopedPhase() {
        const auto end = std::chrono::steady_clock::now();
        const double cpu = timers_.measuresThreadCpuTime() ? threadCpuSeconds() - cpuStart_ : 0.0;
        timers_.add(slot_, std::chrono::duration<double>(end - start_).count(), cpu);
    }
    ScopedPhase(const ScopedPhase&) = delete;
    ScopedPhase& operator=(const ScopedPhase&) = delete;

  private:
    PhaseTimers& timers_;
    std::size_t slot_;
    double cpuStart_;
    std::chrono::steady_clock::time_point start_;
};

} // namespace drape
