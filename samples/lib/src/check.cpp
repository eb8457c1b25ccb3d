// Time-step check before a run (the derivation is in check.hpp).
#include "drape_samples/check.hpp"

#include "drape_samples/simulation.hpp"

#include <drape/stability.hpp>

#include <time.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <iomanip>
#include <limits>
#include <sstream>
#include <vector>

namespace drape::samples {

namespace {

/// `value` with `digits` significant digits ("nan", "inf" as such).
std::string fmt(double value, int digits = 4) {
    std::ostringstream o;
    o << std::setprecision(digits) << value;
    return o.str();
}

/// Why omega_max is 0: nothing to oscillate, or frequencies below double precision.
std::string noOscillation(const Cloth& cloth) {
    bool freeSpring = false;
    const auto& w = cloth.inverseMasses();
    for (const Spring& sp : cloth.topology().springs())
        freeSpring = freeSpring || w[sp.a] != 0.0 || w[sp.b] != 0.0;
    if (!freeSpring)
        return "nothing can oscillate: every particle is pinned or there are no springs";
    return "the springs' frequencies sqrt(k / m) are zero to double precision (stiffness and "
           "mass far apart)";
}

/// The process's CPU time [s]: every thread's, the cloth's helpers included.
double processCpuSeconds() {
    timespec ts{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

} // namespace

double explicitEulerLimit(double omegaMax, double particleDamping, double springDamping,
                          double maxMass, double maxStiffness) {
    if (omegaMax <= 0.0) return std::numeric_limits<double>::infinity();
    double limit = 0.0;
    if (particleDamping > 0.0 && maxMass > 0.0)
        limit += particleDamping / (maxMass * omegaMax * omegaMax);
    if (springDamping > 0.0 && maxStiffness > 0.0) limit += springDamping / maxStiffness;
    return limit;
}

double springsTimeStep(const Cloth& cloth, IntegratorKind integrator) {
    return springsTimeStep(cloth, integrator, cloth.maxAngularFrequency());
}

double springsTimeStep(const Cloth& cloth, IntegratorKind integrator, double omega) {
    if (integrator != IntegratorKind::ExplicitEuler) return stableTimeStep(integrator, omega);
    double minMass = std::numeric_limits<double>::infinity(), maxMass = 0.0;
    for (std::size_t i = 0; i < cloth.particleCount(); ++i) {
        if (!(cloth.inverseMasses()[i] > 0.0)) continue;
        minMass = std::min(minMass, cloth.masses()[i]);
        maxMass = std::max(maxMass, cloth.masses()[i]);
    }
    double maxK = 0.0;
    for (double k : cloth.stiffness())
        maxK = std::max(maxK, k);
    const double cd = cloth.settings().damping, cs = cloth.settings().springDamping;
    // The underdamped modes' limit (explicitEulerLimit), and the overdamped ones': the damping
    // alone, v (1 - h rate) with rate up to C_d / m + 2 c_s / m for the lightest particle, flips
    // the velocity's sign beyond h = 2 / rate and grows it (review 19: C_d 50 on 10 g particles
    // was called stable at 0.005 s; it overflowed). And never beyond 2 / omega_max, the limit
    // the cloth itself checks (Cloth::stableTimeStep).
    const double rate =
        minMass < std::numeric_limits<double>::infinity() ? (cd + 2.0 * cs) / minMass : 0.0;
    const double overdamped = rate > 0.0 ? 2.0 / rate : std::numeric_limits<double>::infinity();
    return std::min({explicitEulerLimit(omega, cd, cs, maxMass, maxK), overdamped,
                     stableTimeStep(integrator, omega)});
}

std::string formatDown(double value, int digits) {
    const std::string near = fmt(value, digits);
    const double shown = std::strtod(near.c_str(), nullptr);
    if (!(value > 0.0) || !std::isfinite(value) || shown <= value) return near;
    return fmt(shown - std::pow(10.0, std::floor(std::log10(value)) - (digits - 1)), digits);
}

TimeStepCheck checkTimeStep(const Cloth& cloth, double dt) {
    return checkTimeStep(cloth, dt, cloth.settings().integrator);
}

TimeStepCheck checkTimeStep(const Cloth& cloth, double dt, IntegratorKind integrator) {
    TimeStepCheck c;
    c.integrator = integrator;
    c.timeStep = dt;
    c.omegaMax = cloth.maxAngularFrequency();
    const std::string name = toString(integrator);
    if (!(dt > 0.0) || !std::isfinite(dt)) {
        c.stable = false;
        c.substeps = 0;
        c.message = "the time step must be positive and finite, got " + fmt(dt);
        return c;
    }
    c.limit = springsTimeStep(cloth, integrator);
    // The explicit aerodynamics' own limit (every integrator takes drag and lift explicitly):
    // at the cloth's wind now, so a caller judging a gusty scene sets its strongest wind first.
    const double springsLimit = c.limit;
    c.aeroLimit = cloth.aeroTimeStep(dt);
    const bool aeroBinds = c.aeroLimit < c.limit;
    if (aeroBinds) c.limit = c.aeroLimit;
    c.stable = dt <= c.limit;
    if (!std::isfinite(c.limit)) {
        c.suggestedTimeStep = dt;
        c.substeps = 1;
        c.message = name + " at dt = " + fmt(dt) + " s: stable (" +
                    (c.omegaMax > 0.0 ? std::string("implicit Euler has no stability limit")
                                      : noOscillation(cloth)) +
                    "; accuracy, not stability, bounds the time step).";
        return c;
    }
    if (c.limit <= 0.0) {
        c.stable = false;
        c.suggestedTimeStep = 0.0;
        c.substeps = 0;
        c.message = name + " at dt = " + fmt(dt) +
                    " s: unstable at every time step: without "
                    "damping explicit Euler adds energy to each spring mode (amplification "
                    "sqrt(1 + (omega dt)^2) > 1 per step, omega_max = " +
                    fmt(c.omegaMax) +
                    " rad/s). Use symplectic_euler or velocity_verlet with dt <= " +
                    fmt(0.9 * 2.0 / c.omegaMax) + " s, or implicit_euler.";
        return c;
    }
    c.suggestedTimeStep = 0.9 * c.limit;
    // The count as a double first: dt / suggestedTimeStep can exceed any int (--dt 1e9).
    const double needed = std::max(1.0, std::ceil(dt / c.suggestedTimeStep - 1e-12));
    c.substeps =
        c.stable ? 1 : static_cast<int>(std::min(needed, double(std::numeric_limits<int>::max())));
    const std::string substepText =
        needed < 1e9 ? std::to_string(static_cast<long long>(needed)) : fmt(needed);
    const std::string why =
        aeroBinds
            ? "the explicit drag and lift bind at wind " + fmt(cloth.settings().aero.wind.norm()) +
                  " m/s: limit " + fmt(c.limit) + " s, the springs' " + fmt(springsLimit) + " s"
            : "omega_max = " + fmt(c.omegaMax) + " rad/s, limit " + fmt(c.limit) + " s";
    if (!c.stable && integrator == IntegratorKind::ExplicitEuler && !aeroBinds) {
        // |1 + lambda dt|^2 = 1 - 2 gamma dt + (omega dt)^2 = 1 + omega^2 dt (dt - limit): the
        // stiffest mode's growth per step. Say how fast, since it can pass unnoticed.
        const double w2 = c.omegaMax * c.omegaMax;
        const double rate = 0.5 * std::log1p(w2 * dt * (dt - c.limit)) / dt;
        c.message =
            name + " at dt = " + fmt(dt) + " s: UNSTABLE (" + why + ", dt is " +
            fmt(dt / c.limit, 3) + "x the limit; the stiffest mode grows by a factor e every " +
            fmt(1.0 / rate, 3) + " s). Use dt <= " + fmt(c.suggestedTimeStep) + " s, i.e. " +
            substepText + " sub-steps per step, or better velocity_verlet or implicit_euler.";
        return c;
    }
    if (std::isfinite(c.aeroLimit)) c.aeroSpeed = cloth.aeroSpeedBound(dt) * c.aeroLimit / dt;
    if (c.stable) {
        c.message = name + " at dt = " + fmt(dt) + " s: stable (" + why + ", margin " +
                    fmt(c.limit / dt, 3) + "x).";
        // The drag's limit is the state's of the moment: it falls as the cloth speeds up
        // against the air (a sheet in a dense fluid called stable with a margin of 20 blew up
        // as it sank: review 17). Say how fast the step holds.
        if (std::isfinite(c.aeroSpeed))
            c.message += " The drag's limit falls as the cloth speeds up against the air: dt "
                         "stays within it up to a relative speed of " +
                         fmt(c.aeroSpeed, 3) + " m/s (the cloth's against the wind).";
    } else {
        c.message = name + " at dt = " + fmt(dt) + " s: UNSTABLE (" + why + ", dt is " +
                    fmt(dt / c.limit, 3) + "x the limit). Use dt <= " + fmt(c.suggestedTimeStep) +
                    " s, i.e. " + substepText + " sub-steps per step" +
                    (aeroBinds ? " (every integrator takes drag and lift explicitly)."
                               : ", or implicit_euler.");
    }
    return c;
}

TrialCost trialCost(const std::function<void()>& step, double dt, int substeps, std::size_t steps,
                    double cpuBudget, const std::function<void()>& afterStep,
                    const std::function<double()>& clothSteps) {
    TrialCost t;
    std::vector<double> cpu;
    cpu.reserve(std::min<std::size_t>(steps, std::size_t(1) << 16)); // a budget stops it first
    double spent = 0.0;
    const double clothStepsBefore = clothSteps ? clothSteps() : 0.0;
    while (cpu.size() < steps) {
        if (spent >= cpuBudget) {
            t.stoppedByBudget = true;
            break;
        }
        const double start = processCpuSeconds();
        step();
        cpu.push_back(processCpuSeconds() - start);
        spent += cpu.back();
        if (afterStep) afterStep(); // untimed: a check of the state
    }
    t.steps = cpu.size();
    t.simulated = static_cast<double>(t.steps) * dt;
    if (cpu.empty()) {
        t.message = "trial: no step taken";
        return t;
    }
    t.worstCpu = *std::max_element(cpu.begin(), cpu.end());
    t.meanCpu = spent / static_cast<double>(cpu.size());
    auto middle = cpu.begin() + static_cast<std::ptrdiff_t>(cpu.size() / 2);
    std::nth_element(cpu.begin(), middle, cpu.end());
    t.medianCpu = *middle;
    t.medianPerFrame = t.medianCpu * (1.0 / 60.0) / dt;
    const double frameBudget = 1.0 / 60.0;
    std::ostringstream m;
    // The cloth steps a scene step took, counted where the cloth splits them further.
    const double perStep =
        clothSteps ? (clothSteps() - clothStepsBefore) / double(t.steps) : double(substeps);
    m << "trial: " << t.steps << " step" << (t.steps == 1 ? "" : "s") << " of " << fmt(dt) << " s ("
      << fmt(perStep, 4) << " cloth sub-step" << (perStep == 1.0 ? "" : "s")
      << (clothSteps && perStep != std::floor(perStep) ? " each on average" : " each")
      << ") took a median " << fmt(1e3 * t.medianCpu, 3) << " ms of CPU, worst "
      << fmt(1e3 * t.worstCpu, 3) << " ms: " << fmt(1e3 * t.medianPerFrame, 3)
      << " ms per 1/60 s simulated, " << fmt(100.0 * t.medianPerFrame / frameBudget, 3)
      << " % of a 60 Hz frame";
    if (t.stoppedByBudget)
        m << " (stopped after " << fmt(spent, 3) << " s of CPU, at t = " << fmt(t.simulated, 3)
          << " s)";
    m << ". Measured on this machine over the first " << fmt(t.simulated, 3)
      << " s; contacts and load that come later can cost more";
    t.message = m.str();
    return t;
}

double clothStepsTaken(const Cloth& cloth) {
    const PhaseTimer* p = cloth.timers().find("integrate");
    return p ? static_cast<double>(p->calls) : 0.0;
}

TrialCost trialCost(Simulation& sim, double seconds, double cpuBudget) {
    const double dt = sim.scene().timeStep;
    const std::size_t left =
        sim.scene().stepCount() > sim.steps() ? sim.scene().stepCount() - sim.steps() : 0;
    // In double first: seconds / dt can exceed any integer (--trial 1e6 at 1e-300 s).
    const double want = std::max(1.0, std::ceil(seconds / dt));
    const std::size_t wanted =
        want >= static_cast<double>(left) ? left : static_cast<std::size_t>(want);
    if (wanted == 0) {
        TrialCost t;
        t.message = "trial: no step left to take (the scene's duration has run out)";
        return t;
    }
    // After each step the state is checked as drape-run checks it (Simulation::stats: a
    // position beyond single precision or a non-finite value throws StepError): a cloth that
    // blew up without going non-finite was timed as if it ran (review 17).
    const Cloth& cloth = sim.cloth();
    TrialCost t =
        trialCost([&sim] { sim.step(); }, dt, sim.substeps(), wanted, cpuBudget,
                  [&sim] { (void)sim.stats(); }, [&cloth] { return clothStepsTaken(cloth); });
    t.message += " (drape-run's summary has the whole run)";
    return t;
}

} // namespace drape::samples
