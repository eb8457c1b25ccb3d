// Small shared pieces: error and enum names, phase timers.
#include "drape/error.hpp"
#include "drape/settings.hpp"
#include "drape/timers.hpp"

#include <ctime>

namespace drape {

const char* toString(ErrorCode code) noexcept {
    switch (code) {
    case ErrorCode::InvalidArgument:
        return "invalid argument";
    case ErrorCode::NonFinite:
        return "non-finite value";
    case ErrorCode::IndexOutOfRange:
        return "index out of range";
    case ErrorCode::DegenerateTriangle:
        return "degenerate triangle";
    case ErrorCode::InvalidMesh:
        return "invalid mesh";
    case ErrorCode::UnstableTimeStep:
        return "unstable time step";
    case ErrorCode::SimulationFailure:
        return "simulation failure";
    case ErrorCode::FileError:
        return "file error";
    }
    return "unknown error";
}

const char* toString(IntegratorKind kind) noexcept {
    switch (kind) {
    case IntegratorKind::VelocityVerlet:
        return "velocity_verlet";
    case IntegratorKind::ExplicitEuler:
        return "explicit_euler";
    case IntegratorKind::SymplecticEuler:
        return "symplectic_euler";
    case IntegratorKind::RungeKutta4:
        return "rk4";
    case IntegratorKind::ImplicitEuler:
        return "implicit_euler";
    }
    return "unknown";
}

const char* toString(LimiterKind kind) noexcept {
    switch (kind) {
    case LimiterKind::None:
        return "none";
    case LimiterKind::StressOrdered:
        return "stress_ordered";
    case LimiterKind::Provot:
        return "provot";
    case LimiterKind::StressOrderedOneSided:
        return "stress_ordered_one_sided";
    }
    return "unknown";
}

IntegratorKind integratorFromString(const std::string& name) {
    for (auto k : {IntegratorKind::VelocityVerlet, IntegratorKind::ExplicitEuler,
                   IntegratorKind::SymplecticEuler, IntegratorKind::RungeKutta4,
                   IntegratorKind::ImplicitEuler}) {
        if (name == toString(k)) return k;
    }
    throw Error(ErrorCode::InvalidArgument,
                "unknown integrator '" + name +
                    "' (expected velocity_verlet, explicit_euler, symplectic_euler, rk4 or "
                    "implicit_euler)");
}

LimiterKind limiterFromString(const std::string& name) {
    for (auto k : {LimiterKind::None, LimiterKind::StressOrdered, LimiterKind::Provot,
                   LimiterKind::StressOrderedOneSided}) {
        if (name == toString(k)) return k;
    }
    throw Error(ErrorCode::InvalidArgument,
                "unknown strain limiter '" + name +
                    "' (expected none, stress_ordered, provot or stress_ordered_one_sided)");
}

double threadCpuSeconds() {
#if defined(CLOCK_THREAD_CPUTIME_ID)
    timespec t{};
    if (clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t) == 0)
        return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
#endif
    return static_cast<double>(std::clock()) / CLOCKS_PER_SEC;
}

std::size_t PhaseTimers::slot(const std::string& name) {
    for (std::size_t i = 0; i < timers_.size(); ++i) {
        if (timers_[i].name == name) return i;
    }
    timers_.push_back(PhaseTimer{name, 0, 0.0, 0.0});
    return timers_.size() - 1;
}

const PhaseTimer* PhaseTimers::find(const std::string& name) const {
    for (const auto& t : timers_) {
        if (t.name == name) return &t;
    }
    return nullptr;
}

void PhaseTimers::reset() {
    for (auto& t : timers_) {
        t.calls = 0;
        t.seconds = 0.0;
        t.cpuSeconds = 0.0;
    }
}

} // namespace drape
