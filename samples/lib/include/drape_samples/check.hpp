// drape_samples/check.hpp: "will this time step blow up?", asked before a run.
//
// The answer comes from the cloth's largest angular frequency omega_max (an upper bound from
// the mass-weighted spring Laplacian, see drape/stability.hpp) and each integrator's
// stability region on the imaginary axis (a spring mode without damping):
//   Velocity-Verlet, symplectic Euler: dt < 2 / omega_max
//   RK4:                               dt < 2.785 / omega_max
//   implicit Euler:                    any dt (A-stable); accuracy, not stability, limits it
//   explicit Euler:                    |1 + i omega dt| > 1 for every dt: an undamped spring
//     gains energy at any time step. With damping, a mode x'' = -omega^2 x - 2 gamma x' is
//     stable when |1 + lambda dt| < 1, i.e. dt < 2 gamma / omega^2. Particle damping C_d gives
//     2 gamma = C_d / m; spring damping c_s gives 2 gamma = c_s omega^2 / k on the stiffest
//     mode, so dt < C_d / (m omega_max^2) + c_s / k. Usually far below 2 / omega_max.
// The runner can call checkTimeStep(cloth, dt) before stepping and print .message; drape-check
// does the same from the command line.
#pragma once

#include <drape/cloth.hpp>

#include <cstddef>
#include <functional>
#include <limits>
#include <string>

namespace drape::samples {

/// The verdict on one (cloth, integrator, dt).
struct TimeStepCheck {
    IntegratorKind integrator = IntegratorKind::VelocityVerlet;
    double timeStep = 0.0; ///< the dt asked about [s]
    double omegaMax = 0.0; ///< upper bound on the largest angular frequency [rad/s]
    double limit = 0.0;    ///< largest stable dt of the integrator [s]; inf if none
    /// The explicit aerodynamics' limit at the cloth's wind (Cloth::aeroTimeStep) [s]; inf
    /// without aerodynamics. `limit` is the smaller of it and the springs'.
    double aeroLimit = 0.0;
    /// The relative speed of the air [m/s] up to which timeStep stays within the drag's
    /// limit (which falls as the cloth speeds up); inf without aerodynamics.
    double aeroSpeed = std::numeric_limits<double>::infinity();
    bool stable = false;            ///< timeStep <= limit
    double suggestedTimeStep = 0.0; ///< a stable dt with a 10 % margin [s] (0: none exists)
    int substeps = 1;               ///< sub-steps of timeStep that make it stable (0: none do)
    std::string message;            ///< the verdict in one or two sentences, for a user
};

/// Checks dt for the cloth's integrator (or `integrator` when given), stiffness, masses,
/// damping and pins, and for its aerodynamics at its wind of the moment.
TimeStepCheck checkTimeStep(const Cloth& cloth, double dt);
TimeStepCheck checkTimeStep(const Cloth& cloth, double dt, IntegratorKind integrator);

/// Explicit Euler's damped limit C_d / (m_max omega^2) + c_s / k_max [s] (0 without damping).
double explicitEulerLimit(double omegaMax, double particleDamping, double springDamping,
                          double maxMass, double maxStiffness);

/// The springs' stable time step for `integrator` [s]: Cloth's for Velocity-Verlet, symplectic
/// Euler and RK4 (stableTimeStep), for explicit Euler the least of explicitEulerLimit (0
/// without damping: unstable at every step), the damping's own limit 2 m_min / (C_d + 2 c_s)
/// and 2 / omega_max; +infinity for implicit Euler. With `omega`, for that omega_max.
double springsTimeStep(const Cloth& cloth, IntegratorKind integrator);
double springsTimeStep(const Cloth& cloth, IntegratorKind integrator, double omega);

/// A positive limit written with `digits` significant digits, rounded down, so that a value
/// copied from advice ("set the time step to at most ...") passes the check it came from.
std::string formatDown(double value, int digits = 6);

class Simulation;

/// What a scene costs on this machine, measured by stepping it: drape-check's trial.
struct TrialCost {
    std::size_t steps = 0;        ///< scene steps taken
    double simulated = 0.0;       ///< simulated time they cover [s]
    double medianCpu = 0.0;       ///< median process CPU time of one scene step [s]
    double meanCpu = 0.0;         ///< mean process CPU time of one scene step [s]
    double worstCpu = 0.0;        ///< the dearest scene step [s]
    double medianPerFrame = 0.0;  ///< medianCpu per 1/60 s of simulated time [s]
    bool stoppedByBudget = false; ///< the CPU budget ran out before `seconds` were simulated
    std::string message;          ///< the figures in a sentence or two, for a user
};

/// Steps `sim` (a scene as drape-run runs it: its world, bodies and contacts) for `seconds` of
/// simulated time (at least one step, at most the scene's duration left), or until the steps
/// have spent `cpuBudget` seconds of process CPU time, and reports what a step cost. The
/// simulation is left where the trial stopped. Throws what Simulation::step throws.
TrialCost trialCost(Simulation& sim, double seconds, double cpuBudget);

/// The cloth steps `cloth` has taken (its integrate phase's calls, PhaseTimers), the counter
/// trialCost's `clothSteps` takes for a cloth that splits its steps itself.
double clothStepsTaken(const Cloth& cloth);

/// The same for any step: calls `step` (one step of `dt` seconds, `substeps` cloth sub-steps)
/// `steps` times, or until the calls have spent `cpuBudget` seconds of process CPU time (a
/// step in progress runs to its end). `afterStep`, when given, runs after each step, untimed
/// (a check that throws to stop the trial); `clothSteps`, when given, counts the cloth steps
/// taken so far, and the message gives their number a step from it instead of `substeps`.
TrialCost trialCost(const std::function<void()>& step, double dt, int substeps, std::size_t steps,
                    double cpuBudget, const std::function<void()>& afterStep = nullptr,
                    const std::function<double()>& clothSteps = nullptr);

} // namespace drape::samples
