// drape/settings.hpp: per-cloth creation settings (integrator, limiter, mass, stiffness,
// forces). Defaults are inline; Cloth validates everything when it is constructed.
#pragma once

#include "drape/material.hpp"
#include "drape/mesh.hpp"

#include <optional>
#include <string>

namespace drape {

/// Time integrators (all share one interface, see integrators.hpp).
enum class IntegratorKind {
    VelocityVerlet,  ///< the paper's eq. (14) with the missing dt restored; the default
    ExplicitEuler,   ///< x += v dt, v += a dt (first order, for comparison)
    SymplecticEuler, ///< v += a dt, x += v dt (first order, symplectic)
    RungeKutta4,     ///< classic fourth-order Runge-Kutta
    ImplicitEuler,   ///< linearised backward Euler (Baraff & Witkin 1998) with Eigen solvers
};

/// Strain limiters against the paper's "hyper elasticity".
enum class LimiterKind {
    None,          ///< springs alone
    StressOrdered, ///< the paper's section 3.2: Provot's rule applied in decreasing stress order
    Provot,        ///< Provot 1995: iterate over springs, shorten overstretched ones
    StressOrderedOneSided, ///< literal one-sided pulls in stress order; unstable, for comparison
};

/// Linear solver of the implicit integrator.
enum class LinearSolverKind {
    ConjugateGradient, ///< Eigen::ConjugateGradient (Jacobi preconditioner), matrix-free size
    LDLT,              ///< Eigen::SimplicialLDLT, direct
};

/// How particle masses are set when particleMass is not given.
enum class MassLumping {
    Uniform,    ///< M / n on every particle (eq. (6)); for regular sheets
    AreaLumped, ///< a third of each adjacent triangle's mass; for irregular meshes
};

const char* toString(IntegratorKind kind) noexcept;
const char* toString(LimiterKind kind) noexcept;
/// Parses "velocity_verlet", "explicit_euler", "symplectic_euler", "rk4", "implicit_euler".
IntegratorKind integratorFromString(const std::string& name);
/// Parses "none", "stress_ordered", "provot", "stress_ordered_one_sided".
LimiterKind limiterFromString(const std::string& name);

/// Aerodynamic drag and lift per triangle, against the wind. Off unless airDensity > 0.
struct AeroSettings {
    double airDensity = 0.0;      ///< rho_air [kg/m^3]; 1.2 for air at sea level; 0 = off
    double dragCoefficient = 1.0; ///< C_d, drag along the triangle normal [-]
    double liftCoefficient = 0.0; ///< C_l, lift across the relative flow [-]
    Vec3 wind = Vec3::Zero();     ///< wind velocity [m/s]
};

/// Strain limiter settings.
struct LimiterSettings {
    LimiterKind kind = LimiterKind::StressOrdered;
    double maxStrain = 0.10; ///< largest allowed (l - L0) / L0 [-]; the paper's 10 %
    /// The promise: after every step each spring is within (1 + maxStrain + tolerance) L0.
    /// Springs beyond it are set to exactly (1 + maxStrain) L0; the band between is left
    /// alone (that is what lets the worklist stop) [-].
    double tolerance = 1e-3;
    /// Safety cap: the stress-ordered walk stops after maxRounds sweep-equivalents of spring
    /// evaluations, Provot after maxRounds sweeps. A step that hits it is counted
    /// (Cloth::limiterCapHits()) and the bound is then not promised. Experiment I needs at most
    /// ~11; a cloth whose sag per step is far beyond the tolerance band (a 20 x 20 sheet of
    /// k = 2 N/m at 60 Hz: 2.7 mm per step against a 0.05 mm band) needs ~200-300, hence the
    /// generous default: the bound is the promise, the work is the price.
    int maxRounds = 1000;
    /// Fraction of last step's limiter corrections re-applied at the start of a step, in
    /// [0, 1) (stress-ordered only). A hanging cloth's weight is carried by the limiter
    /// step after step; re-applying most of it saves the walk the sweeps it takes to carry it
    /// again. 0 turns it off. Larger values save work and overshoot more (energy); 0.6 was
    /// measured best on Experiment I (samples/benchmarks/LIMITER.md) [-].
    double warmStart = 0.6;
    /// Long-range attachments (Kim, Chentanez and Mueller 2012), stress-ordered only: each
    /// free particle stays within (1 + maxStrain) r of its nearest pinned particle, r its
    /// geodesic rest distance (geodesicAnchors in strain_limit.hpp). Carries a hanging load
    /// from the pins in one pass. No effect on a cloth without pinned particles.
    bool longRangeAttachments = true;
    /// r = min(spring path, longRangeSlack * geodesic) (see geodesicAnchors): the room left
    /// for shear. 1.02 keeps Experiment I's hanging shape within 1 % of the converged
    /// reference; must be >= 1 [-].
    double longRangeSlack = 1.02;
};

/// Implicit Euler settings.
struct ImplicitSettings {
    LinearSolverKind solver = LinearSolverKind::ConjugateGradient;
    double cgTolerance = 1e-10; ///< relative residual at which CG stops [-]
    int cgMaxIterations = 500;  ///< CG iteration cap per step
};

/// Blow-up detection beyond the always-on check for non-finite positions and velocities.
struct FailureSettings {
    /// Hard cap on the largest strain (l - L0) / L0 after a step (> 0); not given: no cap [-].
    std::optional<double> maxStrain;
    /// A step fails when the mechanical energy (kinetic + springs + gravity) grows by more
    /// than this times the energy scale (kinetic + elastic + total weight times the mean
    /// spring length). Only checked when nothing can add energy (no wind or user forces, no
    /// kinematic particles, no stages) (> 0); not given: not checked [-]. Costs two energy
    /// passes a step.
    std::optional<double> maxEnergyGrowth;
    /// Retry a failed step as this many sub-steps before giving up (0 or 1: no retry).
    int retrySubsteps = 0;
};

/// Sleeping: a cloth at rest stops computing until something wakes it (Cloth::isAsleep()).
/// The cloth is at rest when, for `time` seconds of consecutive steps, no particle strays
/// farther than `distance` from where it was when that time began (the limiter, kinematic
/// particles and the caller's stages included), and the limiter never stopped at its cap.
/// Positions, not velocities, are watched: a cloth whose weight the limiter carries keeps
/// a stored Velocity-Verlet velocity (the half kick the limiter cancels every step, ~0.2 m/s
/// for a small sheet at rest) and jitters inside the limiter's tolerance band (~0.1 mm)
/// without going anywhere. Asleep, the state is frozen exactly as it is: positions,
/// velocities, cached forces and the limiter's warm start are kept, and a step only
/// advances the time and the step count (O(number of kinematic particles)). Waking resumes
/// from that frozen state.
/// Off by default in the core (its experiments measure decay and convergence, which sleeping
/// would cut short); drape::bullet turns it on when a cloth is added (BulletClothSettings).
struct SleepSettings {
    bool enabled = false;
    /// Largest excursion of a particle during the quiet time [m]. 1 mm: below what a viewer
    /// sees at cloth scale, ten times the limiter's jitter at rest (its default tolerance
    /// 1e-3 times a 0.1 m spring) and, over the default time, a mean speed of 1 mm/s.
    double distance = 1e-3;
    /// Quiet simulated time before the cloth falls asleep [s]. Like Bullet's rigid bodies
    /// (2 s before deactivation): long enough that the turning point of a slow swing is not
    /// mistaken for rest (a swing of period below ~2 s leaves the 1 mm ball within it).
    double time = 1.0;
};

/// Angular frequency the automatic stiffness aims at [rad/s] (ClothSettings::springStiffness):
/// Velocity-Verlet's stability limit 2 / omega is then 1/30 s, twice a 60 Hz game step.
inline constexpr double kAutomaticStiffnessOmega = 60.0;

/// Everything a Cloth needs besides its topology. A default-constructed ClothSettings is
/// valid: a 200 g/m^2 cotton, stiffness chosen for a 60 Hz step, Velocity-Verlet, the
/// paper's stress-ordered limiting at 10 %, gravity -9.81 m/s^2 along y.
struct ClothSettings {
    IntegratorKind integrator = IntegratorKind::VelocityVerlet;

    // Mass: particleMass if given, else totalMass if given, else the material's density
    // times its thickness over the cloth's rest area. Given values must be positive.
    std::optional<double> particleMass;         ///< mass of every particle [kg]
    std::optional<double> totalMass;            ///< mass of the whole cloth [kg]
    MassLumping lumping = MassLumping::Uniform; ///< how totalMass or material mass is spread
    /// k of every spring [N/m] (the paper's C_e); must be positive. Not given: (M1) from
    /// material.youngsModulus if that is given; otherwise automatic: the uniform k for which
    /// the cloth's omega_max (stability.hpp, with its masses and no pins) is
    /// kAutomaticStiffnessOmega, so a 60 Hz Velocity-Verlet step is half its stability limit.
    /// That k depends on the mesh: finer meshes get softer springs (the strain limiter holds
    /// the cloth's stretch whatever k is).
    std::optional<double> springStiffness;
    FabricMaterial material; ///< used for whatever is not given directly

    Vec3 gravity = Vec3(0.0, -9.81, 0.0); ///< g [m/s^2]; eq. (6)
    double damping = 0.0;       ///< C_d of eq. (8): force -C_d v on every particle [N s/m]
    double springDamping = 0.0; ///< damping along springs: -c (dv . n) n [N s/m]
    AeroSettings aero;          ///< air drag and lift; off by default
    LimiterSettings limiter;    ///< strain limiting; stress-ordered 10 % by default
    ImplicitSettings implicit;  ///< used by ImplicitEuler only
    FailureSettings failure;    ///< blow-up detection and retry
    SleepSettings sleep;        ///< sleeping at rest; off by default

    /// Threads a step may use (>= 1, the caller's included). Springs, gravity, damping and
    /// the explicit integrators' particle loops are split over them; results are
    /// bit-identical for any thread count. Worth it from about 1e4 particles; smaller loops
    /// run on the calling thread only. The limiters and aerodynamics run on one thread.
    int threads = 1;

    /// Refuse (drape::Error UnstableTimeStep) a step whose dt exceeds the explicit
    /// integrator's stability limit 2/omega_max (see stability.hpp).
    bool rejectUnstableTimeStep = true;
};

} // namespace drape
