// drape/settings.hpp: per-cloth creation settings (integrator, limiter, mass, stiffness,
// forces). Defaults are inline; Cloth validates everything when it is constructed.
#pragma once

#include "drape/material.hpp"
#include "drape/mesh.hpp"

#include <algorithm>
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
    /// The band at steps of toleranceStep and longer: after such a step each spring is within
    /// (1 + maxStrain + tolerance) L0. Springs beyond the band are set to exactly
    /// (1 + maxStrain) L0; the band between is left alone (that is what lets the worklist
    /// stop) [-]; >= 0, 0 meaning the narrowest band (kMinimumLimiterBand). Shorter steps get
    /// a narrower band (bandAt). A band far below about 1e-6 is out of the walk's reach where
    /// the limiter carries load (soft springs, strong wind): it then stops at its cap
    /// (maxRounds, counted) in most steps (a new user's review, a 21 x 21 sheet of 1 N/m
    /// springs at 60 Hz: tolerance 0 capped 173 of 180 steps, 10 s of CPU against 9 ms;
    /// 1e-6: no cap, 0.33 s).
    double tolerance = 1e-3;
    /// The band shrinks with the step: a step dt uses tolerance * min(1, (dt/toleranceStep)^2)
    /// (bandAt). A correction jumps a spring from the band's top to the limit, a velocity of
    /// about band L0 / dt; with a fixed band that grows as dt shrinks and the limited
    /// trajectory does not converge. With the band ~ dt^2 it converges at first order
    /// (samples/reports/results/error). The price is work: where the limiter carries load a
    /// fine step costs far more per simulated second (a 21 x 21 sheet of 1 N/m springs: 3 ms
    /// of CPU a simulated second at 1/60 s, 26 s at 1e-4 s) [s]; must be > 0.
    double toleranceStep = 0.01;
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
    /// measured best on Experiment I (samples/benchmarks/LIMITER.md). Steps shorter than
    /// toleranceStep re-apply warmStart * dt / toleranceStep (warmStartAt): last step's
    /// correction is history the trajectory must forget as dt shrinks, or it does not
    /// converge [-].
    double warmStart = 0.6;
    /// Long-range attachments (Kim, Chentanez and Mueller 2012), stress-ordered only: each
    /// free particle stays within (1 + maxStrain) r of its nearest pinned particle, r its
    /// geodesic rest distance (geodesicAnchors in strain_limit.hpp). Carries a hanging load
    /// from the pins in one pass. No effect on a cloth without pinned particles.
    bool longRangeAttachments = true;
    /// r = min(spring path, longRangeSlack * geodesic) (see geodesicAnchors): the room left
    /// for shear; must be >= 1. 1.02 keeps Experiment I's hanging shape within 1 % of the
    /// converged reference and lets the attachments carry a soft cloth's weight at 60 Hz.
    /// Steps shorter than toleranceStep use more room (longRangeSlackAt): where the
    /// attachments are tighter than the springs allow, the two pull against each other in
    /// every step and the limited trajectory stops converging as dt shrinks [-].
    double longRangeSlack = 1.02;
};

/// The narrowest band the limiter works with [-]: springs set to the limit come out of double
/// precision arithmetic up to a few 1e-16 beyond it, so a narrower band (a tolerance of 0)
/// would send the walk after rounding until its cap (a curtain whose rod moved: 125 capped
/// steps and 300 s of CPU in 4 s, against none).
inline constexpr double kMinimumLimiterBand = 1e-12;

/// The band a limiter keeps for settings `s` already at its step (Cloth passes bandAt's):
/// s.tolerance, at least kMinimumLimiterBand [-].
inline double limiterBand(const LimiterSettings& s) {
    return std::max(s.tolerance, kMinimumLimiterBand);
}

/// The limiter's band for a step of dt [s]: tolerance * min(1, (dt / toleranceStep)^2), and at
/// least kMinimumLimiterBand [-].
inline double bandAt(const LimiterSettings& s, double dt) {
    const double r = dt / s.toleranceStep;
    return std::max(kMinimumLimiterBand, r < 1.0 ? s.tolerance * r * r : s.tolerance);
}
/// The room long-range attachments leave at small steps: the slack tends to this as dt -> 0.
inline constexpr double kFineStepLongRangeSlack = 1.05;
/// The long-range slack for a step of dt [s]: longRangeSlack at toleranceStep and longer,
/// moving linearly to max(longRangeSlack, kFineStepLongRangeSlack) as dt goes to 0 [-].
inline double longRangeSlackAt(const LimiterSettings& s, double dt) {
    const double r = dt / s.toleranceStep;
    if (r >= 1.0 || s.longRangeSlack >= kFineStepLongRangeSlack) return s.longRangeSlack;
    return kFineStepLongRangeSlack - (kFineStepLongRangeSlack - s.longRangeSlack) * r;
}
/// The warm start's share for a step of dt [s]: warmStart * min(1, dt / toleranceStep) [-].
inline double warmStartAt(const LimiterSettings& s, double dt) {
    const double r = dt / s.toleranceStep;
    return r < 1.0 ? s.warmStart * r : s.warmStart;
}

/// Implicit Euler settings.
struct ImplicitSettings {
    LinearSolverKind solver = LinearSolverKind::ConjugateGradient;
    double cgTolerance = 1e-10; ///< relative residual at which CG stops, in (0, 1) [-]
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
    /// Largest excursion of a particle during the quiet time [m]. 1 cm: the default contact
    /// thickness (a cloth frozen within it of where it would be is within the gap it keeps
    /// from bodies anyway) and, over the default time, a mean speed of 1 cm/s (Jolt lets a
    /// body sleep at 3 cm/s).
    double distance = 1e-2;
    /// Quiet simulated time before the cloth falls asleep [s] (> 0, checked even with sleep
    /// off). A time shorter than a few steps lets a cloth that barely moved in its first steps
    /// (one released at rest, even in free fall) fall asleep at once. Like Bullet's rigid bodies
    /// (2 s before deactivation): long enough that the turning point of a slow swing is not
    /// mistaken for rest (a swing of period below ~2 s leaves the 1 mm ball within it).
    double time = 1.0;
};

/// Particle-triangle collision of the cloth with itself (the paper's particle against a
/// "triangular patch of fabrics"): every free particle keeps `thickness` from every triangle
/// it is not a corner of, on the side it was on at the step's start, with momentum kept and
/// Coulomb friction between the layers. Runs after the strain limiter. Off by default.
struct SelfCollisionSettings {
    bool enabled = false; ///< run the self-collision pass
    /// Distance a particle keeps from the cloth's other triangles [m], at most 0.4 times the
    /// mesh's spacing there (the shortest rest edge at the particle or of the triangle): a
    /// particle lies 0.71 spacings from the far triangle of its own cell, and a thickness near
    /// that made a cloth squeezed in its plane or folded (there are no bending springs) push
    /// its own cells apart (a 41 x 41 sheet of 2.5 cm with 1.5 cm squeezed to 90 %: 1.2 J to
    /// 7 kJ; folded onto itself, 185 J). Measured folds rest at 0.4 spacings on 21 x 21 to
    /// 61 x 61 sheets; at 0.45-0.5 a fold passed through itself on the coarser ones. A cloth
    /// thicker than that needs a finer mesh. A particle and a triangle within this distance of
    /// each other in the rest shape are neighbours and are left alone (on a mesh finer than the
    /// thickness, the triangles next to a particle's own). The test is of positions after each
    /// step, with no sweep: a layer moving faster than about the thickness per cloth step can
    /// pass through another (the default 1 cm at 22 sub-steps a frame: a folded half thrown
    /// down at 20 m/s went through; 5 mm at 10 m/s, 1 mm at 5 m/s).
    double thickness = 0.01;
    int iterations = 2;    ///< passes over all particle-triangle pairs per step (>= 1)
    double friction = 0.2; ///< Coulomb mu between layers of the cloth [-]
};

/// How two cloths keep apart (drape::collideCloths, drape/cloth_pair.hpp).
struct ClothPairSettings {
    /// Distance a particle of one cloth keeps from the triangles of the other [m] (> 0).
    double thickness = 0.01;
    double friction = 0.3; ///< Coulomb mu between the cloths [-] (>= 0)
    int iterations = 2;    ///< passes over the particle-triangle pairs (>= 1)
};

/// How Cloth::step(dt) divides a step into sub-steps.
struct SubstepSettings {
    /// Take a step as the fewest equal sub-steps of at most `fraction` times the integrator's
    /// stability limit (Cloth::stableTimeStep()); a step within it is one step. false: every
    /// step(dt) is one step, and a dt beyond the limit is refused (rejectUnstableTimeStep).
    bool automatic = true;
    double fraction = 0.9; ///< of the stability limit, in (0, 1] [-]
    /// A step that would need more sub-steps than this is refused (UnstableTimeStep) (>= 1).
    int maxSubsteps = 1000;
};

/// Speed of stretch waves the automatic stiffness gives a cloth [m/s] (ClothSettings::
/// springStiffness): E h = rho_A c^2 in (M1) (material.hpp), rho_A the cloth's mass per rest
/// area. It does not depend on the mesh (a finer mesh of the same cloth stretches the same)
/// nor on the mass (a heavier cloth gets stiffer springs): hanging a height H it stretches
/// about g H / c^2 at the top (2.5 % for 1 m), a 1 m sheet pinned on its edges sags to about
/// 6 % strain at rest, and the strain limiter holds what gusts, pushes and drops add. Its
/// cost: the stability limit is about 0.7 s / c times the spacing s [m], so a 60 Hz step takes
/// about 22 automatic sub-steps on a 2.5 cm mesh and 11 on a 5 cm mesh. Softer springs need
/// fewer sub-steps but leave the limiter more to carry, which costs more than they save
/// (samples/benchmarks/GAMES.md).
inline constexpr double kAutomaticStretchWaveSpeed = 20.0;

/// The automatic stiffness's springs carry a cloth hanging its full length with at most this
/// strain [-] (half the default bound): a cloth whose largest rest extent L is over about 2 m
/// gets stretch waves faster than ClothSettings::stretchWaveSpeed, sqrt(|g| L / this)
/// (automaticWaveSpeed). Hanging a height H stretches a membrane by |g| H / c^2 at the top, so
/// at 20 m/s a cloth that hangs more than about 4 m leaves its weight to the strain limiter:
/// a 20 m tarp over a 6 m box cost 29 ms a frame for ever and never slept, at 63 m/s it
/// costs 4 ms and sleeps (review 10).
inline constexpr double kAutomaticHangingStrain = 0.05;

/// ClothSettings::relativeDamping's default [1/s]: motion about the cloth's mean velocity
/// decays with a time constant of 0.5 s, so a cloth dropped on a stack of boxes, its flaps
/// swinging, is still within SleepSettings' 1 cm after about 6 s (samples/benchmarks/GAMES.md).
inline constexpr double kDefaultRelativeDamping = 2.0;

/// How often the relative damping acts [s]: once per this much simulated time, with the decay
/// of that time (a step of 1/60 s and its sub-steps share one pass over the particles).
inline constexpr double kRelativeDampingInterval = 1.0 / 60.0;

/// The range of a scene's lengths per metre (ClothSettings::inUnits, BulletClothSettings::
/// unitsPerMetre): beyond it the converted defaults leave the range a double holds them in.
inline constexpr double kMinUnitsPerMetre = 1e-6;
inline constexpr double kMaxUnitsPerMetre = 1e6;

/// Everything a Cloth needs besides its topology. Enum fields must hold one of their
/// enumerators (a value cast from another integer is refused). A default-constructed ClothSettings
/// is valid: a 200 g/m^2 cotton, the automatic stiffness (kAutomaticStretchWaveSpeed) with
/// automatic sub-steps, Velocity-Verlet, the paper's stress-ordered limiting at 10 %,
/// gravity -9.81 m/s^2 along y. Its defaults are in SI units (metres, kilograms, seconds);
/// a scene in another length unit starts from inUnits().
struct ClothSettings {
    /// The defaults for a scene whose lengths are in units of 1 / unitsPerMetre metres (100:
    /// centimetres, as in Unreal; 1: metres, the default-constructed settings), kilograms and
    /// seconds: every default with a length in it converted (gravity -9.81 unitsPerMetre, the
    /// material's thickness times and its density divided by unitsPerMetre^3, the automatic
    /// stiffness's wave speed, the sleep distance and the self-collision thickness times
    /// unitsPerMetre), so that a cloth in centimetres gets the same springs, sub-steps,
    /// strain, sleep and cost as the same cloth in metres. Values set afterwards are in the
    /// scene's units. Throws drape::Error (InvalidArgument) unless unitsPerMetre is in
    /// [1e-6, 1e6]. (Left in SI, a 1 m cloth in centimetres weighs 2,000 kg, its springs hold
    /// none of its weight, it never sleeps and costs about 8 times as much.)
    static ClothSettings inUnits(double unitsPerMetre);

    IntegratorKind integrator = IntegratorKind::VelocityVerlet;

    // Mass: particleMass if given, else totalMass if given, else the material's density
    // times its thickness over the cloth's rest area. Given values must be positive.
    std::optional<double> particleMass;         ///< mass of every particle [kg]
    std::optional<double> totalMass;            ///< mass of the whole cloth [kg]
    MassLumping lumping = MassLumping::Uniform; ///< how totalMass or material mass is spread
    /// k of every spring [N/m] (the paper's C_e); must be positive. Not given: (M1) from
    /// material.youngsModulus if that is given; otherwise automatic: (M1) with
    /// E h = rho_A c^2, c = stretchWaveSpeed (kAutomaticStretchWaveSpeed) and rho_A the cloth's
    /// mass per rest area, the same for any mesh of the cloth. With a 60 Hz step that needs a few
    /// sub-steps, which Cloth::step (substeps) and drape::bullet take automatically.
    std::optional<double> springStiffness;
    FabricMaterial material; ///< used for whatever is not given directly
    /// Speed of the stretch waves of the automatic stiffness [m/s] (> 0; used when neither
    /// springStiffness nor material.youngsModulus is given): kAutomaticStretchWaveSpeed, or
    /// that many scene units per second after inUnits(). The least speed: a cloth larger than
    /// about 2 m gets faster waves, so that its springs carry its weight
    /// (kAutomaticHangingStrain, automaticWaveSpeed).
    double stretchWaveSpeed = kAutomaticStretchWaveSpeed;

    Vec3 gravity = Vec3(0.0, -9.81, 0.0); ///< g [m/s^2]; eq. (6)
    double damping = 0.0; ///< C_d of eq. (8): force -C_d v on every particle [N s/m]
    /// Damping of the free particles' motion relative to their mass-weighted mean velocity
    /// [1/s] (>= 0; 0 turns it off): each free particle's velocity relative to that mean
    /// decays by exp(-rate t), applied once per kRelativeDampingInterval. Stretch waves, flutter,
    /// swinging flaps and spin die out, so a cloth at rest comes to rest and can sleep; its
    /// momentum is left exactly as it was (free fall is untouched, the body a cape hangs from feels
    /// its whole weight). The default, kDefaultRelativeDamping, is the game's choice; experiments
    /// that measure undamped motion set 0. The mean is the whole cloth's: a part pushed at speed u
    /// drags the rest at rate * (its mass share) * u (a fifth of g for a tenth of the cloth at 1
    /// m/s).
    double relativeDamping = kDefaultRelativeDamping;
    double springDamping = 0.0;          ///< damping along springs: -c (dv . n) n [N s/m]
    AeroSettings aero;                   ///< air drag and lift; off by default
    LimiterSettings limiter;             ///< strain limiting; stress-ordered 10 % by default
    ImplicitSettings implicit;           ///< used by ImplicitEuler only
    FailureSettings failure;             ///< blow-up detection and retry
    SleepSettings sleep;                 ///< sleeping at rest; off by default
    SubstepSettings substeps;            ///< automatic sub-steps of Cloth::step; on by default
    SelfCollisionSettings selfCollision; ///< the cloth against itself; off by default

    /// Threads a step may use (>= 1, the caller's included). Springs, gravity, damping, the
    /// explicit integrators' particle loops and the limiter's scan are split over them; results
    /// are bit-identical for any thread count. Worth it from about 1e4 particles; smaller
    /// loops run on the calling thread only. The limiter's walk and aerodynamics run on one
    /// thread. With more than 1 the cloth's first step starts a small pool of its own, unless a
    /// program that owns threads gave the cloth an Executor over them (Cloth::setExecutor); a
    /// drape::bullet world gives it the world's (BulletClothSettings::threads), which may have
    /// more threads than this.
    int threads = 1;

    /// Refuse (drape::Error UnstableTimeStep) a step whose dt exceeds the explicit
    /// integrator's stability limit 2/omega_max (see stability.hpp).
    bool rejectUnstableTimeStep = true;
};

} // namespace drape
