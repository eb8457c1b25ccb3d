// Cloth: settings validation, the step pipeline, pins and diagnostics.
#include "drape/cloth.hpp"

#include "self_collision.hpp"

#include "drape/error.hpp"
#include "drape/geometry.hpp"
#include "drape/stability.hpp"

#include "parallel.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <limits>
#include <sstream>
#include <string>

namespace drape {
namespace {

std::string num(double v) {
    std::ostringstream s;
    s.precision(6);
    s << v;
    return s.str();
}

/// A positive limit with six significant digits, rounded down: a value a user copies from an
/// error's advice passes (rounded to nearest, "use dt <= 0.00204128 s" named a step 2e-10 s
/// beyond the limit 0.0020412789 s, and that step was refused in turn; review 16).
std::string numDown(double v) {
    const std::string s = num(v);
    const double shown = std::strtod(s.c_str(), nullptr);
    if (!(v > 0.0) || !std::isfinite(v) || shown <= v) return s;
    return num(shown - std::pow(10.0, std::floor(std::log10(v)) - 5.0));
}

/// A count of sub-steps, ceil(n), as digits (in floating point beyond what an integer holds: a
/// fluid of 1e30 kg/m^3 asked for "-9223372036854775808 sub-steps"; review 19).
std::string countOf(double n) {
    const double c = std::ceil(n);
    return c < 1e15 ? std::to_string(static_cast<long long>(c)) : num(c);
}

/// What an UnstableTimeStep message adds when one particle sets the stable step (its own
/// springs reach at least four times the median particle's frequency, highestLocalFrequency):
/// which particle, and what usually makes one. Empty otherwise.
std::string stiffestSpot(const ClothTopology& topology, const std::vector<double>& stiffness,
                         const std::vector<double>& invMass) {
    const LocalFrequency f = highestLocalFrequency(topology, stiffness, invMass);
    if (!(f.medianOmega > 0.0) || !(f.omega >= 4.0 * f.medianOmega)) return {};
    const Index p = f.particle;
    double shortest = std::numeric_limits<double>::infinity();
    Index other = p;
    const auto& offsets = topology.adjacencyOffsets();
    for (Index e = offsets[p]; e < offsets[p + 1]; ++e)
        if (const double l = topology.springs()[topology.adjacentSprings()[e]].restLength;
            l < shortest) {
            shortest = l;
            other = topology.adjacentParticles()[e];
        }
    return "; particle " + std::to_string(p) + " sets that limit: its own springs reach " +
           num(f.omega) + " rad/s, " + num(f.omega / f.medianOmega) +
           " times the median particle's (its mass " + num(f.mass) + " kg against a median " +
           num(f.medianMass) + " kg, its shortest spring " + num(shortest) + " m, to particle " +
           std::to_string(other) +
           "): a vertex that only sliver triangles touch, or two vertices a hair apart that "
           "should be one, does this; weld them (a mesh importer's weld tolerance) or "
           "remove the sliver";
}

void requireFinite(double v, const std::string& name) {
    if (!std::isfinite(v))
        throw Error(ErrorCode::NonFinite, name + " is not finite (" + num(v) + ")");
}
void requireFinite(const Vec3& v, const std::string& name) {
    if (!v.allFinite()) throw Error(ErrorCode::NonFinite, name + " is not finite");
}
void requirePositive(double v, const std::string& name) {
    requireFinite(v, name);
    if (!(v > 0.0))
        throw Error(ErrorCode::InvalidArgument, name + " must be positive, got " + num(v));
}
/// Particle i of n exists, or an IndexOutOfRange error names `what`.
void checkIndex(Index i, std::size_t n, const char* what) {
    if (i >= n) {
        throw Error(ErrorCode::IndexOutOfRange,
                    std::string(what) + ": particle " + std::to_string(i) +
                        " does not exist (the cloth has " + std::to_string(n) + " particles)");
    }
}

/// A time step must be finite and positive.
void requireStepValue(double dt) {
    if (!std::isfinite(dt)) throw Error(ErrorCode::NonFinite, "time step is not finite");
    if (!(dt > 0.0))
        throw Error(ErrorCode::InvalidArgument, "time step must be positive, got " + num(dt));
}

void requireNonNegative(double v, const std::string& name) {
    requireFinite(v, name);
    if (v < 0.0) throw Error(ErrorCode::InvalidArgument, name + " must be >= 0, got " + num(v));
}
/// A given value must be positive and finite; returns whether it is given.
bool given(const std::optional<double>& v, const std::string& name) {
    if (!v) return false;
    requirePositive(*v, name);
    return true;
}

std::vector<double> buildMasses(const ClothTopology& topo, const ClothSettings& s) {
    if (given(s.particleMass, "particleMass")) {
        return std::vector<double>(topo.particleCount(), *s.particleMass);
    }
    double total = 0.0;
    if (given(s.totalMass, "totalMass")) {
        total = *s.totalMass;
    } else {
        requirePositive(s.material.density, "material.density");
        requirePositive(s.material.thickness, "material.thickness");
        if (s.lumping == MassLumping::AreaLumped) {
            return areaLumpedMasses(topo, s.material.density, s.material.thickness);
        }
        total = s.material.density * s.material.thickness * topo.totalRestArea();
    }
    if (s.lumping == MassLumping::Uniform) return uniformMasses(topo, total);
    // Area-lumped shares of the given total.
    std::vector<double> m(topo.particleCount(), 0.0);
    for (std::size_t t = 0; t < topo.triangleCount(); ++t) {
        const double share = total * topo.triangleRestAreas()[t] / (3.0 * topo.totalRestArea());
        for (Index v : topo.triangles()[t])
            m[v] += share;
    }
    return m;
}

} // namespace

double automaticWaveSpeed(const ClothTopology& topology, const ClothSettings& settings) {
    Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
    for (const Vec3& p : topology.restPositions()) {
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
    }
    const double extent = topology.restPositions().empty() ? 0.0 : (hi - lo).maxCoeff();
    const double hanging = std::sqrt(settings.gravity.norm() * extent / kAutomaticHangingStrain);
    return std::max(settings.stretchWaveSpeed, std::isfinite(hanging) ? hanging : 0.0);
}

namespace {

std::vector<double> buildStiffness(const ClothTopology& topo, const ClothSettings& s,
                                   const std::vector<double>& masses) {
    if (given(s.springStiffness, "springStiffness")) {
        return std::vector<double>(topo.springCount(), *s.springStiffness);
    }
    if (s.material.youngsModulus) {
        return springStiffnessFromMaterial(topo, *s.material.youngsModulus, s.material.thickness);
    }
    // Automatic: a membrane whose stretch waves travel at c, E h = rho_A c^2, by (M1).
    double mass = 0.0;
    for (double m : masses)
        mass += m;
    const double area = topo.totalRestArea();
    if (!(area > 0.0) || !(mass > 0.0)) return std::vector<double>(topo.springCount(), 1.0);
    requirePositive(s.stretchWaveSpeed, "stretchWaveSpeed");
    const double c = automaticWaveSpeed(topo, s);
    const double eh = mass / area * c * c;
    return springStiffnessFromMaterial(topo, eh, 1.0);
}

void validateAero(const AeroSettings& a) {
    requireNonNegative(a.airDensity, "aero.airDensity");
    // Drag takes energy out: a negative coefficient would feed the flow's energy in.
    requireNonNegative(a.dragCoefficient, "aero.dragCoefficient");
    requireFinite(a.liftCoefficient, "aero.liftCoefficient");
    requireFinite(a.wind, "aero.wind");
}

void validateSelfCollision(const SelfCollisionSettings& sc) {
    if (!sc.enabled) return; // the values matter only when it runs
    requirePositive(sc.thickness, "selfCollision.thickness");
    if (sc.iterations < 1)
        throw Error(ErrorCode::InvalidArgument,
                    "selfCollision.iterations must be >= 1, got " + std::to_string(sc.iterations));
    requireNonNegative(sc.friction, "selfCollision.friction");
}

/// An enum value cast from an integer outside the enum's values (`Kind(99)`) is refused,
/// naming the setting and the values it takes.
template <class E> void requireEnum(E value, E last, const char* name, const char* values) {
    const auto v = static_cast<long long>(value);
    if (v < 0 || v > static_cast<long long>(last))
        throw Error(ErrorCode::InvalidArgument, std::string(name) + " is not one of its values (" +
                                                    std::to_string(v) + "); use one of " + values);
}

void validateSettings(const ClothSettings& s) {
    requireEnum(s.integrator, IntegratorKind::ImplicitEuler, "integrator",
                "IntegratorKind::VelocityVerlet, ExplicitEuler, SymplecticEuler, RungeKutta4, "
                "ImplicitEuler");
    requireEnum(s.limiter.kind, LimiterKind::StressOrderedOneSided, "limiter.kind",
                "LimiterKind::None, StressOrdered, Provot, StressOrderedOneSided");
    requireEnum(s.lumping, MassLumping::AreaLumped, "lumping", "MassLumping::Uniform, AreaLumped");
    requireEnum(s.implicit.solver, LinearSolverKind::LDLT, "implicit.solver",
                "LinearSolverKind::ConjugateGradient, LDLT");
    requireFinite(s.gravity, "gravity");
    validateSelfCollision(s.selfCollision);
    requireNonNegative(s.damping, "damping");
    requireNonNegative(s.relativeDamping, "relativeDamping");
    requireNonNegative(s.springDamping, "springDamping");
    validateAero(s.aero);
    requirePositive(s.limiter.maxStrain, "limiter.maxStrain");
    requireNonNegative(s.limiter.tolerance, "limiter.tolerance");
    requirePositive(s.limiter.toleranceStep, "limiter.toleranceStep");
    requirePositive(s.substeps.fraction, "substeps.fraction");
    if (s.substeps.fraction > 1.0) {
        throw Error(ErrorCode::InvalidArgument,
                    "substeps.fraction must be in (0, 1], got " + num(s.substeps.fraction));
    }
    if (s.substeps.maxSubsteps < 1) {
        throw Error(ErrorCode::InvalidArgument, "substeps.maxSubsteps must be >= 1, got " +
                                                    std::to_string(s.substeps.maxSubsteps));
    }
    requireFinite(s.limiter.warmStart, "limiter.warmStart");
    if (s.limiter.warmStart < 0.0 || s.limiter.warmStart >= 1.0) {
        throw Error(ErrorCode::InvalidArgument,
                    "limiter.warmStart must be in [0, 1), got " + num(s.limiter.warmStart));
    }
    requireFinite(s.limiter.longRangeSlack, "limiter.longRangeSlack");
    if (s.limiter.longRangeSlack < 1.0) {
        throw Error(ErrorCode::InvalidArgument,
                    "limiter.longRangeSlack must be >= 1, got " + num(s.limiter.longRangeSlack));
    }
    if (s.limiter.maxRounds < 1) {
        throw Error(ErrorCode::InvalidArgument,
                    "limiter.maxRounds must be >= 1, got " + std::to_string(s.limiter.maxRounds));
    }
    requirePositive(s.implicit.cgTolerance, "implicit.cgTolerance");
    if (s.implicit.cgTolerance >= 1.0) { // CG starts at a relative residual of 1
        throw Error(ErrorCode::InvalidArgument,
                    "implicit.cgTolerance must be below 1, got " + num(s.implicit.cgTolerance) +
                        ": CG would stop before its first iteration and the implicit step "
                        "would move nothing");
    }
    if (s.failure.maxStrain) requirePositive(*s.failure.maxStrain, "failure.maxStrain");
    if (s.failure.maxEnergyGrowth)
        requirePositive(*s.failure.maxEnergyGrowth, "failure.maxEnergyGrowth");
    if (s.failure.retrySubsteps < 0 || s.failure.retrySubsteps > 1024) {
        throw Error(ErrorCode::InvalidArgument,
                    "failure.retrySubsteps must be between 0 and 1024, got " +
                        std::to_string(s.failure.retrySubsteps));
    }
    if (s.threads < 1 || s.threads > 256) {
        throw Error(ErrorCode::InvalidArgument,
                    "threads must be between 1 and 256, got " + std::to_string(s.threads));
    }
    requirePositive(s.sleep.distance, "sleep.distance");
    requirePositive(s.sleep.time, "sleep.time");
    if (s.implicit.cgMaxIterations < 1) {
        throw Error(ErrorCode::InvalidArgument, "implicit.cgMaxIterations must be >= 1, got " +
                                                    std::to_string(s.implicit.cgMaxIterations));
    }
}

} // namespace

ClothSettings ClothSettings::inUnits(double unitsPerMetre) {
    if (!(unitsPerMetre >= kMinUnitsPerMetre && unitsPerMetre <= kMaxUnitsPerMetre))
        throw Error(ErrorCode::InvalidArgument,
                    "ClothSettings::inUnits: unitsPerMetre must be in [1e-6, 1e6] (100 for "
                    "centimetres, 1 for metres), got " +
                        num(unitsPerMetre));
    const double u = unitsPerMetre;
    ClothSettings s;
    s.gravity *= u;
    s.material.thickness *= u;
    s.material.density /= u * u * u;
    s.stretchWaveSpeed *= u;
    s.sleep.distance *= u;
    s.selfCollision.thickness *= u;
    return s;
}

Cloth::Cloth(TopologyPtr topology, const ClothSettings& settings)
    : topology_(std::move(topology)), settings_(settings) {
    if (!topology_) throw Error(ErrorCode::InvalidArgument, "cloth topology is null");
    validateSettings(settings_);
    std::vector<double> mass = buildMasses(*topology_, settings_);
    invMass_.resize(mass.size());
    for (std::size_t i = 0; i < mass.size(); ++i)
        invMass_[i] = 1.0 / mass[i];
    state_.x = topology_->restPositions();
    state_.v.assign(state_.x.size(), Vec3::Zero());
    state_.f.assign(state_.x.size(), Vec3::Zero());
    state_.pinned.assign(state_.x.size(), 0);
    state_.bound = ownBound();
    std::vector<double> stiffness = buildStiffness(*topology_, settings_, mass);
    // The masses live in the force model (gravity reads them); masses() returns its copy.
    forceModel_ = std::make_unique<ForceModel>(topology_, std::move(stiffness), std::move(mass),
                                               settings_, timers_);
    integrator_ = makeIntegrator(settings_.integrator, settings_.implicit);
    integrator_->bind(*forceModel_);
    for (const Stage& st : kStages)
        stageSlots_.push_back(timers_.slot(st.name));
}

Cloth::~Cloth() = default;

void Cloth::evaluateForces() {
    forceModel_->evaluate(state_.x, state_.v, state_.f);
    state_.forcesValid = true;
}

void Cloth::checkFinite(const char* where, double dt) {
    // A NaN or infinity anywhere makes the sum non-finite; only then look for the particle.
    double sum = 0.0;
    for (std::size_t i = 0; i < state_.x.size(); ++i)
        sum += state_.x[i].sum() + state_.v[i].sum() + state_.f[i].sum();
    if (std::isfinite(sum)) return;
    // A value already non-finite before the step (the caller wrote it, through
    // mutablePositions() or mutableVelocities()) is the cause, not the step: name it. Inside
    // the step, step_.x0 and step_.v0 hold the state from before it (stageIntegrate).
    if (step_.x0.size() == state_.x.size() && step_.v0.size() == state_.v.size()) {
        for (std::size_t i = 0; i < step_.x0.size(); ++i) {
            const bool x = !step_.x0[i].allFinite();
            if (!x && step_.v0[i].allFinite()) continue;
            throw Error(ErrorCode::NonFinite,
                        std::string("the ") + (x ? "position" : "velocity") + " of particle " +
                            std::to_string(i) + " was not finite before step " +
                            std::to_string(state_.steps + 1) + " (t = " + num(state_.time) +
                            " s): set by the caller (through " +
                            (x ? "mutablePositions()" : "mutableVelocities()") +
                            ", for example), not by the step; the cloth keeps its state from "
                            "before the step. Write finite values (setPosition and setVelocity "
                            "check them)");
        }
    }
    // The first particle whose position or velocity went non-finite (a free one: what blew
    // up), else the first force (a held particle's springs pull with its neighbours': review
    // 16 saw a pin named). The advice names the stability limit when the step was beyond it.
    std::size_t culprit = state_.x.size();
    const char* what = "";
    for (std::size_t i = 0; i < state_.x.size() && culprit == state_.x.size(); ++i)
        if (!state_.x[i].allFinite() || !state_.v[i].allFinite()) {
            culprit = i;
            what = !state_.x[i].allFinite() ? "position" : "velocity";
        }
    for (std::size_t i = 0; i < state_.x.size() && culprit == state_.x.size(); ++i)
        if (!state_.f[i].allFinite()) {
            culprit = i;
            what = "force";
        }
    if (culprit < state_.x.size()) {
        const double h = dt, limit = stableTimeStep();
        const std::string advice =
            h > limit ? " The step of " + num(h) + " s is beyond the stability limit " +
                            numDown(limit) + " s of " + toString(settings_.integrator) +
                            " (rejectUnstableTimeStep is off): use dt <= " + numDown(limit) +
                            " s, the automatic sub-steps, or implicit Euler."
                      : std::string(" Reduce the time step or the stiffness.");
        throw Error(ErrorCode::SimulationFailure,
                    std::string("state became non-finite at particle ") + std::to_string(culprit) +
                        " (its " + what + ", " + (invMass_[culprit] == 0.0 ? "held" : "free") +
                        ") after " + where + " of the cloth's step " +
                        std::to_string(state_.steps + 1) + " (t = " + num(state_.time) +
                        " s); the cloth keeps its state from before the step." + advice);
    }
    // Finite values whose sum overflows: the state is out of any sensible range.
    throw Error(ErrorCode::SimulationFailure,
                std::string("state magnitude overflowed after ") + where + " of the cloth's step " +
                    std::to_string(state_.steps + 1) +
                    "; the cloth keeps its state from before the step");
}

int Cloth::substepsFor(double dt) const {
    requireStepValue(dt);
    const SubstepSettings& sub = settings_.substeps;
    if (!sub.automatic) return 1;
    const double springs = stableTimeStep(), drag = aeroTimeStep(dt);
    const double limit = std::min(springs, drag);
    if (!(limit < std::numeric_limits<double>::infinity())) return 1; // implicit, or nothing moves
    const double needed = std::ceil(dt / (sub.fraction * limit));
    if (needed <= 1.0) return 1;
    if (!(needed <= static_cast<double>(sub.maxSubsteps))) {
        throw Error(
            ErrorCode::UnstableTimeStep,
            "time step " + num(dt) + " s would need " + num(needed) +
                " automatic sub-steps of at most " + numDown(sub.fraction * limit) +
                (drag < springs
                     ? std::string(" s (the stability limit of the explicit aerodynamic drag: "
                                   "aero.airDensity = ") +
                           num(settings_.aero.airDensity) +
                           " kg/m^3 at a relative speed of up to " + num(aeroSpeedBound(dt)) +
                           " m/s), more than substeps.maxSubsteps = " +
                           std::to_string(sub.maxSubsteps) +
                           "; use a smaller dt, a thinner fluid or a heavier cloth"
                     : std::string(" s (the stability limit of ") + toString(settings_.integrator) +
                           " for this cloth, omega_max = " + num(maxAngularFrequency()) +
                           " rad/s), more than substeps.maxSubsteps = " +
                           std::to_string(sub.maxSubsteps) +
                           stiffestSpot(*topology_, forceModel_->stiffness(), invMass_) +
                           "; use a smaller dt, softer springs, heavier particles or "
                           "implicit Euler (IntegratorKind::ImplicitEuler)"));
    }
    return static_cast<int>(needed);
}

void Cloth::step(double dt) {
    stepPart(dt, 1);
}

void Cloth::checkStateSizes(const std::string& who) const {
    const std::size_t n = particleCount();
    auto check = [&](const Vec3List& list, const char* what, const char* access) {
        if (list.size() == n) return;
        throw Error(ErrorCode::InvalidArgument,
                    who + ": the " + what + " hold " + std::to_string(list.size()) +
                        " entries but the cloth has " + std::to_string(n) +
                        " particles (the vector returned by " + access +
                        " was resized); change its values, not its size: resize it back to "
                        "particleCount() entries");
    };
    check(state_.x, "positions", "mutablePositions()");
    check(state_.v, "velocities", "mutableVelocities()");
}

void Cloth::refuseInStep(const char* who) const {
    if (!inStep_) return;
    throw Error(ErrorCode::InvalidArgument,
                std::string(who) +
                    ": not allowed during the cloth's own step (from a stage); a stage runs "
                    "once per step with the step's dt: call it before or after the step");
}

void Cloth::stepPart(double dt, int parts) {
    refuseInStep("Cloth::step");
    checkStateSizes("Cloth::step");
    if (parts < 1)
        throw Error(ErrorCode::InvalidArgument,
                    "stepPart: parts must be >= 1, got " + std::to_string(parts));
    const int n = substepsFor(dt);
    // The limiter's band follows the caller's whole step (see limiterAt).
    struct Whole {
        double& step;
        Whole(double& s, double v) : step(s) { step = v; }
        ~Whole() { step = 0.0; }
        Whole(const Whole&) = delete;
        Whole& operator=(const Whole&) = delete;
    } whole(wholeStep_, dt * parts);
    const double h = dt / n;
    // What a step reports (limiter stats, the held particles' impulses) sums its sub-steps; a
    // step taken asleep reports nothing.
    limiterStats_ = StrainLimitStats{};
    selfStats_ = SelfCollisionStats{};
    if (selfCollider_) selfCollider_->invalidate(); // a step depends on its start state only
    heldImpulse_.resize(state_.x.size(), Vec3::Zero());
    for (Index i : heldImpulsed_)
        heldImpulse_[i].setZero();
    heldImpulsed_.clear();
    if (state_.asleep) {
        checkTimeStep(h);
        if (!kinematicTargetsMove(dt)) { // frozen: only the clock runs
            state_.time += dt;
            ++state_.steps;
            ++sleptSteps_;
            return;
        }
        wake();
    }
    if (n == 1) {
        stepWithRetry(dt);
    } else {
        // A failure in any sub-step leaves the cloth as it was before the whole step.
        save(wholeStepStart_);
        try {
            for (int k = 0; k < n; ++k) {
                if (state_.asleep) { // fell asleep in an earlier sub-step: frozen from here
                    state_.time += h;
                    continue;
                }
                stepWithRetry(h);
            }
        } catch (...) {
            restore(wholeStepStart_);
            throw;
        }
        state_.steps = wholeStepStart_.steps + 1; // the sub-steps count as the caller's one step
    }
    if (limiterStats_.capHit) ++limiterCapHits_;
}

void Cloth::stepWithRetry(double dt) {
    if (settings_.failure.retrySubsteps < 2) {
        stepOnce(dt);
        return;
    }
    try {
        stepOnce(dt);
    } catch (const Error& e) {
        if (e.code() != ErrorCode::SimulationFailure) throw;
        // Retry the step as sub-steps; if that fails too, restore the state from before it.
        Saved before;
        save(before);
        const int k = settings_.failure.retrySubsteps;
        try {
            for (int i = 0; i < k; ++i)
                stepOnce(dt / k);
        } catch (const Error& again) {
            restore(before);
            throw Error(again.code(), std::string(e.what()) + " Retrying as " + std::to_string(k) +
                                          " sub-steps failed too: " + again.what());
        }
        ++retries_;
        state_.steps = before.steps + 1; // the sub-steps count as the one step the caller asked for
    }
}

void Cloth::save(Saved& s) const {
    s.x.assign(state_.x.begin(), state_.x.end());
    s.v.assign(state_.v.begin(), state_.v.end());
    const auto& lambda = limiter_.warmStartState();
    s.lambda.assign(lambda.begin(), lambda.end());
    s.time = state_.time;
    s.steps = state_.steps;
    s.overBound = state_.overBound;
}

void Cloth::restore(const Saved& s) {
    state_.x = s.x;
    state_.v = s.v;
    if (settings_.limiter.kind == LimiterKind::StressOrdered) limiter_.setWarmStartState(s.lambda);
    state_.time = s.time;
    state_.steps = s.steps;
    state_.overBound = s.overBound;
    state_.forcesValid = false;
}

double Cloth::energyScale() const {
    // Kinetic plus elastic energy, floored by the work gravity does over one mean spring
    // length, so that a cloth at rest still has a finite scale.
    double meanRest = 0.0;
    for (const auto& s : topology_->springs())
        meanRest += s.restLength;
    meanRest /= static_cast<double>(std::max<std::size_t>(topology_->springCount(), 1));
    return kineticEnergy() + springEnergy() + totalMass() * settings_.gravity.norm() * meanRest;
}

// --- the step driver --------------------------------------------------------------------------
//
// A step is the table below, run in order. Each stage says whether this cloth needs it (a
// stage it does not need is neither run nor timed nor listed by pipeline()) and what it does.
// The order is the paper's loop (section 5) in Velocity-Verlet's kick-drift-kick form:
//   forces_refresh  f(t), only when the cached forces are stale (first step, after edits)
//   integrate       the integrator's advance(): for Velocity-Verlet v += f dt / 2m, x += v dt
//   kinematic       pinned particles held, kinematic particles put on their paths
//   grab            grabbed particles pulled toward their targets (setGrab), exactly over dt
//   <stages before limit> the caller's stages' beforeLimit (drape::bullet finds its contacts
//                   and puts their planes into the cloth's ContactSet), in order
//   strain_limit    the limiter (its walk keeps the contact planes); what it moved gets
//                   v += dx / dt
//   self_collision  particles kept off the cloth's own triangles (if set)
//   <stages>        the caller's stages (drape::bullet's contacts), in order
//   forces          f(t + dt) at the corrected state (one timer per force term)
//   integrate_finish Velocity-Verlet's closing half kick
//   relative_damping the free particles' velocities relative to their mean decay (if set)
//   verify          finiteness, the strain cap, the energy check (always)
// A failure anywhere restores the state from before the step (see step()).

struct Cloth::StepContext {
    double dt = 0.0;
    bool checkEnergy = false;
    double energyBefore = 0.0, scaleBefore = 0.0;
    IntegratorContext integrator;
};

const Cloth::Stage Cloth::kStages[] = {
    {"forces_refresh", true, [](const Cloth& c) { return !c.state_.forcesValid; },
     &Cloth::stageForcesRefresh},
    {"integrate", true, [](const Cloth&) { return true; }, &Cloth::stageIntegrate},
    {"kinematic", true, [](const Cloth& c) { return !c.kinematic_.empty(); },
     &Cloth::stageKinematic},
    {"grab", true, [](const Cloth& c) { return !c.grabs_.empty(); }, &Cloth::stageGrab},
    {"<stages before limit>", false, [](const Cloth& c) { return !c.stages_.empty(); },
     &Cloth::stageCallerStagesBefore},
    {"strain_limit", true,
     [](const Cloth& c) { return c.settings_.limiter.kind != LimiterKind::None; },
     &Cloth::stageLimit},
    {"self_collision", true, [](const Cloth& c) { return c.settings_.selfCollision.enabled; },
     &Cloth::stageSelfCollision},
    {"<stages>", false, [](const Cloth& c) { return !c.stages_.empty(); },
     &Cloth::stageCallerStages},
    {"forces", false, [](const Cloth&) { return true; }, &Cloth::stageForces},
    {"integrate_finish", true,
     [](const Cloth& c) { return c.settings_.integrator == IntegratorKind::VelocityVerlet; },
     &Cloth::stageFinish},
    {"relative_damping", true, [](const Cloth& c) { return c.settings_.relativeDamping > 0.0; },
     &Cloth::stageRelativeDamping},
    {"verify", true, [](const Cloth&) { return true; }, &Cloth::stageVerify},
};

void Cloth::checkTimeStep(double dt) const {
    requireStepValue(dt);
    if (settings_.rejectUnstableTimeStep) {
        const double limit = stableTimeStep();
        if (dt > limit) {
            throw Error(ErrorCode::UnstableTimeStep,
                        std::string("time step ") + num(dt) + " s exceeds the stability limit " +
                            numDown(limit) + " s of " + toString(settings_.integrator) +
                            " for this cloth (omega_max = " + num(maxAngularFrequency()) +
                            " rad/s)" +
                            stiffestSpot(*topology_, forceModel_->stiffness(), invMass_) +
                            "; use dt <= " + numDown(limit) + " s, " + countOf(dt / limit) +
                            " sub-steps of this step, or implicit Euler "
                            "(IntegratorKind::ImplicitEuler)");
        }
        // The drag's limit falls as the cloth speeds up against the air. Automatic sub-steps
        // split each step as its speed asks (substepsFor); a fixed step is checked here, at the
        // speed of the moment, so that a cloth outrunning it is refused before it blows up (a
        // sheet in a dense fluid falling in fixed sub-steps reached 1e63 m: review 17).
        if (!settings_.substeps.automatic && settings_.aero.airDensity > 0.0) {
            const double drag = aeroTimeStep(dt);
            if (dt > drag) {
                // Automatic sub-steps help only within their count.
                const bool splitFits = dt / (settings_.substeps.fraction * drag) <=
                                       static_cast<double>(settings_.substeps.maxSubsteps);
                throw Error(
                    ErrorCode::UnstableTimeStep,
                    std::string("time step ") + num(dt) + " s exceeds the stability limit " +
                        numDown(drag) +
                        " s of the explicit aerodynamic drag at the cloth's speed against the "
                        "air now (up to " +
                        num(aeroSpeedBound(dt)) +
                        " m/s, aero.airDensity = " + num(settings_.aero.airDensity) +
                        " kg/m^3); the limit falls as the cloth speeds up against the air: " +
                        (splitFits ? "turn substeps.automatic on (each step is then split as "
                                     "the speed asks), or "
                                   : "") +
                        "use dt <= " + numDown(drag) + " s (" + countOf(dt / drag) +
                        " sub-steps of this step), a thinner fluid or a heavier cloth");
            }
        }
    }
}

void Cloth::stepOnce(double dt) {
    checkTimeStep(dt);
    // Reactions on held particles are worth recording only where a body may take them: the
    // kinematic (attached) ones (see constraintImpulses()).
    limiter_.setRecordHeld(!kinematic_.empty());
    bindLoops(true);
    StepContext ctx{
        dt, false, 0.0, 0.0,
        IntegratorContext{state_.x, state_.v, state_.f, invMass_, dt, *forceModel_, loops_}};
    // The closing kick's aerodynamics stand for this step's opening ones only when nothing
    // changed the state since (every edit clears forcesValid; read before forces_refresh).
    ctx.integrator.aeroCarry = &state_.aero;
    ctx.integrator.aeroCarried = state_.forcesValid && state_.aero.size() == state_.x.size();
    // Energy can only grow through wind, user forces, kinematic particles, grabs and stages
    // (contacts with moving bodies): check it only without those sources.
    ctx.checkEnergy = settings_.failure.maxEnergyGrowth.has_value() && kinematic_.empty() &&
                      grabs_.empty() && stages_.empty() &&
                      forceModel_->activeTerms().size() == forceModel_->passiveTermCount();
    if (ctx.checkEnergy) {
        ctx.energyBefore = kineticEnergy() + springEnergy() + gravityEnergy();
        ctx.scaleBefore = energyScale();
    }
    // The state from before the step is kept (state_.x, state_.v swapped into the scratch buffers
    // by stageIntegrate) so that a failure leaves the cloth as it was.
    const bool keepWarmStart = settings_.limiter.kind == LimiterKind::StressOrdered;
    if (keepWarmStart) {
        const auto& lambda = limiter_.warmStartState();
        step_.lambdaBefore.assign(lambda.begin(),
                                  lambda.end()); // no allocation after the first step
    }
    bool swapped = false;
    inStep_ = true; // edits by stages do not count as wake-ups
    try {
        for (std::size_t k = 0; k < std::size(kStages); ++k) {
            const Stage& st = kStages[k];
            if (!st.active(*this)) continue;
            if (st.timed) {
                ScopedPhase t(timers_, stageSlots_[k]);
                (this->*st.run)(ctx);
            } else { // timed inside, one timer per caller stage or force term
                (this->*st.run)(ctx);
            }
            if (st.run == &Cloth::stageIntegrate) swapped = true;
        }
    } catch (...) {
        inStep_ = false;
        state_.quietTime = 0.0;
        if (swapped) {
            state_.x.swap(step_.x0);
            state_.v.swap(step_.v0);
        }
        if (keepWarmStart) limiter_.setWarmStartState(step_.lambdaBefore);
        state_.forcesValid = false;
        throw;
    }
    inStep_ = false;
    updateSleep(dt);
    state_.time += dt;
    ++state_.steps;
}

// --- sleeping ---------------------------------------------------------------------------------

void Cloth::checkState(const ClothState& state, const std::vector<double>& warmStart) const {
    const std::size_t n = particleCount();
    auto requireSize = [](std::size_t got, std::size_t want, const char* what) {
        if (got != want)
            throw Error(ErrorCode::InvalidArgument,
                        std::string("cloth state: ") + what + " has " + std::to_string(got) +
                            " entries, the cloth " + std::to_string(want));
    };
    requireSize(state.x.size(), n, "x");
    requireSize(state.v.size(), n, "v");
    requireSize(state.f.size(), n, "f");
    requireSize(state.pinned.size(), n, "pinned");
    if (!state.anchor.empty()) requireSize(state.anchor.size(), n, "anchor");
    if (!state.aero.empty()) requireSize(state.aero.size(), n, "aero");
    if (!warmStart.empty()) requireSize(warmStart.size(), topology_->springCount(), "warmStart");
    auto requireFinite = [](const Vec3List& list, const char* what) {
        for (std::size_t i = 0; i < list.size(); ++i)
            if (!list[i].allFinite())
                throw Error(ErrorCode::NonFinite, std::string("cloth state: ") + what +
                                                      " of particle " + std::to_string(i) +
                                                      " is not finite");
    };
    requireFinite(state.x, "x");
    requireFinite(state.v, "v");
    requireFinite(state.f, "f");
    requireFinite(state.anchor, "sleep anchor");
    requireFinite(state.aero, "aero");
    if (!std::isfinite(state.time))
        throw Error(ErrorCode::NonFinite, "cloth state: time is not finite");
    if (!(state.quietTime >= 0.0 && std::isfinite(state.quietTime)))
        throw Error(ErrorCode::NonFinite, "cloth state: quietTime must be >= 0 and finite");
    if (state.asleep && state.anchor.empty())
        throw Error(ErrorCode::InvalidArgument, "cloth state: asleep without sleep anchors");
    for (std::size_t s = 0; s < warmStart.size(); ++s)
        if (!(warmStart[s] >= 0.0 && std::isfinite(warmStart[s])))
            throw Error(ErrorCode::NonFinite, "cloth state: the limiter's warm start at spring " +
                                                  std::to_string(s) + " is negative or not finite");
}

void Cloth::restoreState(ClothState state, std::vector<double> warmStart) {
    refuseInStep("Cloth::restoreState");
    checkState(state, warmStart);
    const bool asleep = state.asleep && settings_.sleep.enabled;
    const double own = ownBound();
    const bool tighter = !(state.bound <= own); // not known (NaN) counts as tighter
    state_ = std::move(state);
    state_.asleep = asleep;
    state_.bound = own;
    if (tighter && !state_.overBound && settings_.limiter.kind == LimiterKind::StressOrdered &&
        maxSpringStrain(*topology_, state_.x) > own + limiterBand(settings_.limiter))
        state_.overBound = true;
    // The contact records describe the state that was (the force term would read them in the
    // first step's force evaluation): none, as in a cloth just added to its world.
    if (ContactSet* contacts = forceModel_->contacts()) contacts->contacts.clear();
    // A kinematic path on a particle the state frees goes with its hold (review 20: a drag in
    // progress when an editor restored its snapshot moved a particle that reported itself free).
    kinematic_.erase(
        std::remove_if(kinematic_.begin(), kinematic_.end(),
                       [this](const Kinematic& k) { return state_.pinned[k.particle] == 0; }),
        kinematic_.end());
    aeroExtent_.known = false;
    limiter_.setWarmStartState(std::move(warmStart));
    for (std::size_t i = 0; i < particleCount(); ++i)
        invMass_[i] = state_.pinned[i] ? 0.0 : 1.0 / masses()[i];
    invalidateOmega();
}

double Cloth::ownBound() const {
    return settings_.limiter.kind == LimiterKind::StressOrdered
               ? settings_.limiter.maxStrain
               : std::numeric_limits<double>::infinity();
}

void Cloth::wake() {
    state_.asleep = false;
    state_.quietTime = 0.0;
    state_.anchor.clear();
    aeroExtent_.known = false;
}

void Cloth::setSleep(const SleepSettings& sleep) {
    requirePositive(sleep.distance, "sleep.distance");
    requirePositive(sleep.time, "sleep.time");
    settings_.sleep = sleep;
    wake();
}

// A target within kKinematicWakeShare of sleep.distance of its frozen particle does not wake
// the cloth: the offset is measured from the frozen position, so a target that keeps moving
// wakes it once it has gone that far. (Exactly equal, a cape on a 20 kg box hanging asleep
// from a Bullet joint never slept: the limiter's walk lets such a body give way by a
// micrometre, which Bullet, the body asleep, never takes, so the frozen particles were 1.3 um
// from their targets and woke the cloth the step after it fell asleep, every second.)
bool Cloth::kinematicTargetsMove(double dt) const {
    const double tol = kKinematicWakeShare * settings_.sleep.distance;
    for (const auto& k : kinematic_) {
        if (!((k.at(state_.time + dt) - state_.x[k.particle]).norm() <= tol))
            return true; // NaN too: the real step reports it
    }
    return false;
}

// After a successful step. The quiet time starts with the positions of its first step
// (state_.anchor); a particle farther than sleep.distance from its anchor restarts it from here.
void Cloth::updateSleep(double dt) {
    const auto& sl = settings_.sleep;
    if (!sl.enabled) return;
    const double d2 = sl.distance * sl.distance;
    bool quiet = !limiterStats_.capHit && state_.anchor.size() == state_.x.size();
    // By blocks without branches inside (a NaN distance is not quiet), stopping at the first
    // block with a particle beyond the distance.
    constexpr std::size_t kBlock = 64;
    for (std::size_t b = 0; quiet && b < state_.x.size(); b += kBlock) {
        const std::size_t e = std::min(state_.x.size(), b + kBlock);
        bool far = false;
        for (std::size_t i = b; i < e; ++i)
            far |= !((state_.x[i] - state_.anchor[i]).squaredNorm() <= d2);
        quiet = !far;
    }
    if (!quiet) {
        state_.anchor = state_.x;
        state_.quietTime = 0.0;
        return;
    }
    state_.quietTime += dt;
    if (state_.quietTime >= sl.time) {
        state_.asleep = true;
        aeroExtent_.known = false;
    }
}

void Cloth::stageForcesRefresh(StepContext&) {
    try {
        evaluateForces();
    } catch (...) {
        state_.forcesValid = false;
        throw;
    }
}

void Cloth::stageIntegrate(StepContext& ctx) {
    const std::size_t n = state_.x.size();
    step_.x0.resize(n);
    step_.v0.resize(n);
    if (!kinematic_.empty()) {
        step_.kinematicStart.clear();
        for (const auto& k : kinematic_)
            step_.kinematicStart.push_back(state_.x[k.particle]);
    }
    // Integrators that can write the new state to other buffers get the old one swapped out
    // of state_.x, state_.v (no copy); the others work in place on a copy.
    state_.x.swap(step_.x0);
    state_.v.swap(step_.v0);
    if (!integrator_->advanceFrom(ctx.integrator, step_.x0, step_.v0)) {
        std::copy(step_.x0.begin(), step_.x0.end(), state_.x.begin());
        std::copy(step_.v0.begin(), step_.v0.end(), state_.v.begin());
        integrator_->advance(ctx.integrator);
    }
}

// Each grabbed free particle follows the exact motion of a critically damped spring toward
// its target over dt from the step's start, with its other forces held at their value there
// (state_.f: the cloth's springs and gravity), in place of the integrator's move. So any
// stiffness is stable, and where the springs carry the load the grab holds it with no error
// of the step: F = k (x - target) at rest. With z = x - target - F / k and w = sqrt(k / m),
// z(t) = (z0 + (v0 + w z0) t) e^(-w t). (A damper critical for the whole cloth on the grab,
// c = 2 sqrt(k M), took the limiter's corrections of the particle, velocity in the next step,
// as a load: a 21 x 21 sheet hanging from its grab sagged 0.24 m instead of 0.05.)
void Cloth::stageGrab(StepContext& ctx) {
    const double dt = ctx.dt;
    // Velocity-Verlet's closing kick (grabs need that integrator: setGrab) adds dt/2 of the
    // forces after the step: taken off here, so that at rest the particle ends the step at rest.
    const double kickBack = 0.5 * dt;
    for (const Grab& g : grabs_) {
        const Index i = g.particle;
        if (invMass_[i] == 0.0) continue; // held: its pin, path or body decides
        const double w = std::sqrt(g.stiffness * invMass_[i]);
        const Vec3& f = state_.f[i];
        const Vec3 rest = g.target + f / g.stiffness;
        const Vec3 z0 = step_.x0[i] - rest;
        const Vec3& v0 = step_.v0[i];
        const Vec3 c = v0 + w * z0;
        const double decay = std::exp(-w * dt);
        state_.x[i] = rest + (z0 + dt * c) * decay;
        state_.v[i] = (v0 - (w * dt) * c) * decay - (kickBack * invMass_[i]) * f;
    }
}

void Cloth::stageKinematic(StepContext& ctx) {
    for (std::size_t k = 0; k < kinematic_.size(); ++k) {
        const Index i = kinematic_[k].particle;
        const Vec3 target = kinematic_[k].at(state_.time + ctx.dt);
        if (!target.allFinite()) {
            throw Error(ErrorCode::NonFinite, "kinematic path of particle " + std::to_string(i) +
                                                  " returned a non-finite position");
        }
        state_.x[i] = target;
        state_.v[i] = (target - step_.kinematicStart[k]) / ctx.dt;
    }
}

void Cloth::applyLimiterMoves(double dt, const StrainLimitStats& walk) {
    const double invDt = 1.0 / dt;
    const auto& moved = limiter_.movedIndex();
    const auto& from = limiter_.movedFrom();
    for (std::size_t j = 0; j < moved.size(); ++j)
        state_.v[moved[j]] += (state_.x[moved[j]] - from[j]) * invDt;
    // A walk that stopped at its cap (maxRounds, or held particles too far apart) was
    // fighting constraints it cannot meet together: each round trip of its corrections pulled
    // the held ends again, and what they summed is what the fight pumped, not a load the cloth
    // carries (a banner pressed between a heavy box and two light posts passed the posts
    // hundreds of N s and threw them kilometres). Its held particles take no pull.
    if (walk.capHit) return;
    const auto& pull = limiter_.heldPull();
    for (Index i : limiter_.heldIndex()) {
        if (heldImpulse_[i] == Vec3::Zero()) heldImpulsed_.push_back(i);
        heldImpulse_[i] += pull[i] * invDt;
    }
}

void Cloth::addLimiterStats(const StrainLimitStats& st) {
    StrainLimitStats& sum = limiterStats_;
    sum.rounds += st.rounds;
    sum.corrections += st.corrections;
    sum.work += st.work;
    sum.capHit = sum.capHit || st.capHit;
    sum.pinsApart = sum.pinsApart || st.pinsApart;
    sum.maxStrainBefore = std::max(sum.maxStrainBefore, st.maxStrainBefore);
    if (st.corrections || st.capHit)
        sum.maxStrainAfter = std::max(sum.maxStrainAfter, st.maxStrainAfter);
}

LimiterSettings Cloth::limiterAt(double dt) const {
    // Sub-steps (step()'s automatic ones, or stepPart's) share the band of the caller's step:
    // sub-steps are there for stability, the tolerance is the caller's to choose by its step.
    if (wholeStep_ > 0.0) dt = wholeStep_;
    LimiterSettings lim = settings_.limiter;
    lim.tolerance = bandAt(lim, dt);
    lim.warmStart = warmStartAt(lim, dt);
    lim.longRangeSlack = longRangeSlackAt(lim, dt);
    return lim;
}

void Cloth::stageLimit(StepContext& ctx) {
    const LimiterSettings lim = limiterAt(ctx.dt);
    if (lim.kind == LimiterKind::StressOrdered) {
        if (state_.overBound) repairStart(lim);
        limiter_.clearMoved();
        // The walk keeps the planes of the ContactSet (setContacts) a stage filled before it.
        ContactSet* contacts = forceModel_->contacts();
        const StrainLimitStats walk =
            limiter_.limit(*topology_, invMass_, forceModel_->stiffness(), lim, state_.x,
                           contacts ? &contacts->planes : nullptr);
        addLimiterStats(walk);
        applyLimiterMoves(ctx.dt, walk);
        state_.overBound = walk.capHit;
        return;
    }
    // The comparison limiters: displacements from a copy (no repair: overBound is for the
    // stress-ordered walk).
    state_.overBound = false;
    step_.beforeLimit = state_.x;
    const StrainLimitStats st =
        lim.kind == LimiterKind::Provot
            ? limitStrainProvot(*topology_, invMass_, lim, state_.x)
            : limitStrainOneSided(*topology_, invMass_, forceModel_->stiffness(), lim, state_.x);
    addLimiterStats(st);
    if (st.corrections == 0) return;
    const double invDt = 1.0 / ctx.dt;
    for (std::size_t i = 0; i < state_.x.size(); ++i)
        state_.v[i] += (state_.x[i] - step_.beforeLimit[i]) * invDt;
}

// The step started beyond the bound (ClothState::overBound): a walk on the step's starting
// positions brings them within it, and the drifted positions move with them. Only the rest
// of the correction, what this step's drift stretched, becomes velocity in the walk after.
// Particles with a contact plane in this step are held where they are (the walk after keeps
// their planes; this one, on other positions, has none): a net that caught a rod is not
// pulled back through it.
void Cloth::repairStart(const LimiterSettings& lim) {
    limiter_.clearMoved();
    step_.repaired.assign(step_.x0.begin(), step_.x0.end());
    const ContactSet* contacts = forceModel_->contacts();
    const std::vector<double>* invMass = &invMass_;
    if (contacts && !contacts->planes.of.empty()) {
        step_.repairInvMass.assign(invMass_.begin(), invMass_.end());
        for (std::size_t i = 0; i < contacts->planes.of.size(); ++i)
            if (contacts->planes.of[i] >= 0) step_.repairInvMass[i] = 0.0;
        invMass = &step_.repairInvMass;
    }
    // A walk that stopped at its cap with nothing impossible left (a teleported pin row drags
    // the whole cloth: far more sweeps than a step's drift asks) goes on, up to
    // kRepairWalks walks: what is left becomes velocity in the walk after.
    for (int walk = 0; walk < kRepairWalks; ++walk) {
        const StrainLimitStats repair =
            limiter_.limit(*topology_, *invMass, forceModel_->stiffness(), lim, step_.repaired);
        limiterStats_.rounds += repair.rounds;
        limiterStats_.corrections += repair.corrections;
        limiterStats_.work += repair.work;
        if (!repair.capHit || repair.pinsApart) break;
    }
    for (Index i : limiter_.movedIndex())
        state_.x[i] += step_.repaired[i] - step_.x0[i];
}

void Cloth::stageCallerStagesBefore(StepContext& ctx) {
    runCallerStages(ctx.dt, true);
}

void Cloth::stageCallerStages(StepContext& ctx) {
    runCallerStages(ctx.dt, false);
}

// A stage may add or remove stages (itself included) while it runs: the loop goes over the
// stages as they were when it began, each kept alive while it runs, and skips one removed
// before its turn. The copies reuse their storage (no allocation after the first step).
void Cloth::runCallerStages(double dt, bool beforeLimit) {
    struct Running {
        std::vector<std::shared_ptr<ClothStage>>& list;
        explicit Running(std::vector<std::shared_ptr<ClothStage>>& l) : list(l) {}
        ~Running() { list.clear(); } // the last owner of a removed stage lets it go here
        Running(const Running&) = delete;
        Running& operator=(const Running&) = delete;
    } running(runningStages_);
    runningStages_.assign(stages_.begin(), stages_.end());
    const auto& slots = beforeLimit ? callerStageBeforeSlots_ : callerStageSlots_;
    runningSlots_.assign(slots.begin(), slots.end());
    stagesRemoved_ = false;
    for (std::size_t s = 0; s < runningStages_.size(); ++s) {
        ClothStage* stage = runningStages_[s].get();
        if (stagesRemoved_ && std::none_of(stages_.begin(), stages_.end(),
                                           [stage](const std::shared_ptr<ClothStage>& p) {
                                               return p.get() == stage;
                                           }))
            continue;
        {
            ScopedPhase t(timers_, runningSlots_[s]);
            if (beforeLimit)
                stage->beforeLimit(*this, dt);
            else
                stage->run(*this, dt);
        }
        if (state_.x.size() != particleCount() || state_.v.size() != particleCount())
            checkStateSizes("stage '" + stage->name() + "'" +
                            (beforeLimit ? " (beforeLimit)" : ""));
    }
}

// For Velocity-Verlet this evaluation leaves out the velocity-dependent terms (damping,
// aerodynamics): its advance() and finish() apply them at the right velocities, so it stays
// second order (integrators.cpp). Other integrators get them here.
void Cloth::stageForces(StepContext&) {
    evaluateForces();
}

void Cloth::stageFinish(StepContext& ctx) {
    integrator_->finish(ctx.integrator);
}

// Every free particle's velocity relative to the free particles' mass-weighted mean velocity
// vbar decays as exp(-rate t): sum m_i (v_i - vbar) = 0, so the free particles' momentum is
// exactly what it was (a rigid translation, free fall included, is untouched, and nothing is
// owed to the bodies holding the others); stretch waves, flutter and spin die out. Applied
// after the step (a first-order splitting of the damping), once per kRelativeDampingInterval
// of simulated time that the step completes (counted from time 0, so a restored snapshot
// damps where the original did): sub-steps of a 60 Hz frame share one pass.
void Cloth::stageRelativeDamping(StepContext& ctx) {
    // The interval a time falls in, a millionth of an interval early: a step that ends on a
    // boundary ends there whatever the rounding of the clock (a cloth woken after sleeping
    // and one restored from the frozen state reach the same boundary by different sums; after
    // 1000 sleeping steps of 1/240 s they damped one step apart).
    auto interval = [](double t) { return std::floor(t / kRelativeDampingInterval + 1e-6); };
    const double k0 = interval(state_.time);
    const double k1 = interval(state_.time + ctx.dt);
    if (!(k1 > k0)) return;
    const double decay =
        std::exp(-settings_.relativeDamping * (k1 - k0) * kRelativeDampingInterval);
    state_.aero.clear(); // the velocities change after the closing kick: nothing to carry
    const auto& m = masses();
    Vec3 p = Vec3::Zero();
    double mass = 0.0;
    for (std::size_t i = 0; i < state_.v.size(); ++i) {
        if (invMass_[i] == 0.0) continue;
        p += m[i] * state_.v[i];
        mass += m[i];
    }
    if (!(mass > 0.0)) return;
    const Vec3 vbar = p / mass;
    for (std::size_t i = 0; i < state_.v.size(); ++i) {
        if (invMass_[i] != 0.0) state_.v[i] = vbar + decay * (state_.v[i] - vbar);
    }
}

void Cloth::stageSelfCollision(StepContext&) {
    if (!selfCollider_) selfCollider_ = std::make_unique<detail::SelfCollider>();
    const auto& sc = settings_.selfCollision;
    const auto counts = selfCollider_->run(*topology_, invMass_, step_.x0, state_.x, state_.v,
                                           sc.thickness, sc.friction, sc.iterations);
    selfStats_.pairTests += counts.pairTests;
    selfStats_.contacts += counts.contacts;
}

void Cloth::setSelfCollision(const SelfCollisionSettings& self) {
    validateSelfCollision(self);
    settings_.selfCollision = self;
    edited();
}

void Cloth::stageVerify(StepContext& ctx) {
    // Velocity-Verlet's finish() looked at every value on its way; a full pass is only needed
    // to find the culprit, or for integrators whose finish() did not look.
    if (!integrator_->finishChecksFinite() || ctx.integrator.nonFiniteSeen)
        checkFinite("the step", ctx.dt);
    if (settings_.failure.maxStrain) {
        const double strain = maxStrain();
        if (strain > *settings_.failure.maxStrain) {
            throw Error(ErrorCode::SimulationFailure,
                        "strain " + num(strain) + " exceeds the hard cap failure.maxStrain = " +
                            num(*settings_.failure.maxStrain) + " in the cloth's step " +
                            std::to_string(state_.steps + 1) + " (t = " + num(state_.time) +
                            " s); the cloth keeps its state from before the step");
        }
    }
    if (ctx.checkEnergy) {
        const double after = kineticEnergy() + springEnergy() + gravityEnergy();
        if (after - ctx.energyBefore > *settings_.failure.maxEnergyGrowth * ctx.scaleBefore) {
            throw Error(ErrorCode::SimulationFailure,
                        "mechanical energy grew by " + num(after - ctx.energyBefore) +
                            " J in the cloth's step " + std::to_string(state_.steps + 1) +
                            " (t = " + num(state_.time) +
                            " s), more than failure.maxEnergyGrowth = " +
                            num(*settings_.failure.maxEnergyGrowth) + " times the energy scale " +
                            num(ctx.scaleBefore) +
                            " J, with no energy source; the cloth keeps "
                            "its state from before the step");
        }
    }
}

StrainLimitStats Cloth::relimit(const std::vector<Index>& touched, double dt,
                                ContactPlanes* planes) {
    requireStepValue(dt);
    for (Index i : touched)
        checkIndex(i, state_.x.size(), "relimit");
    StrainLimitStats st;
    limiter_.clearMoved();
    if (settings_.limiter.kind == LimiterKind::None || touched.empty()) return st;
    const LimiterSettings lim = limiterAt(dt);
    if (lim.kind == LimiterKind::StressOrdered) {
        st = limiter_.relimit(*topology_, invMass_, forceModel_->stiffness(), lim, touched,
                              state_.x, planes);
        applyLimiterMoves(dt, st);
        if (st.capHit) state_.overBound = true; // as the step's walk (repairStart)
    } else {
        // The comparison limiters have no worklist: they run whole, and report what moved.
        step_.beforeLimit = state_.x;
        st = lim.kind == LimiterKind::Provot
                 ? limitStrainProvot(*topology_, invMass_, lim, state_.x)
                 : limitStrainOneSided(*topology_, invMass_, forceModel_->stiffness(), lim,
                                       state_.x);
        step_.relimitMoved.clear();
        const double invDt = 1.0 / dt;
        for (std::size_t i = 0; i < state_.x.size(); ++i) {
            if (state_.x[i] == step_.beforeLimit[i]) continue;
            state_.v[i] += (state_.x[i] - step_.beforeLimit[i]) * invDt;
            step_.relimitMoved.push_back(static_cast<Index>(i));
        }
    }
    addLimiterStats(st);
    state_.forcesValid = false;
    edited();
    return st;
}

const std::vector<Index>& Cloth::relimitMoved() const {
    return settings_.limiter.kind == LimiterKind::StressOrdered ? limiter_.movedIndex()
                                                                : step_.relimitMoved;
}

std::vector<std::string> Cloth::pipeline() const {
    std::vector<std::string> p;
    for (const Stage& st : kStages) {
        if (!st.active(*this)) continue;
        if (st.run == &Cloth::stageCallerStagesBefore) {
            continue; // the caller's stages are listed once, where they run after the limiter
        } else if (st.run == &Cloth::stageCallerStages) {
            for (const auto& s : stages_)
                p.push_back(s->name());
        } else if (st.run == &Cloth::stageForces) {
            for (const auto& t : forceModel_->activeTerms())
                p.push_back(t);
        } else {
            p.push_back(st.name);
        }
    }
    return p;
}

// --- pins ---------------------------------------------------------------------------------

void Cloth::setHeld(Index i, bool held) {
    state_.pinned[i] = held ? 1 : 0;
    invMass_[i] = held ? 0.0 : 1.0 / masses()[i];
    kinematic_.erase(std::remove_if(kinematic_.begin(), kinematic_.end(),
                                    [&](const Kinematic& k) { return k.particle == i; }),
                     kinematic_.end());
    state_.forcesValid = false;
    invalidateOmega();
    edited();
}

void Cloth::pin(Index i) {
    checkIndex(i, state_.x.size(), "pin");
    state_.v[i] = Vec3::Zero();
    setHeld(i, true);
}

void Cloth::pin(Index i, const Vec3& position) {
    checkIndex(i, state_.x.size(), "pin");
    requireFinite(position, "pin position of particle " + std::to_string(i));
    pin(i);
    movedHeld(i, position);
    edited();
}

// A held particle put somewhere else is a teleport: the next step brings the cloth within its
// bound as positions (ClothState::overBound), so the jump does not become speed (21 pins moved
// 0.5 m at once threw a curtain at 133 m/s, 186 J).
void Cloth::movedHeld(Index i, const Vec3& position) {
    if (state_.x[i] != position && settings_.limiter.kind == LimiterKind::StressOrdered)
        state_.overBound = true;
    state_.x[i] = position;
}

void Cloth::setKinematic(Index i, KinematicPath path) {
    checkIndex(i, state_.x.size(), "setKinematic");
    if (!path)
        throw Error(ErrorCode::InvalidArgument,
                    "kinematic path of particle " + std::to_string(i) + " is empty");
    const Vec3 start = path(state_.time);
    requireFinite(start, "kinematic path of particle " + std::to_string(i));
    pin(i);
    state_.x[i] = start;
    Kinematic k;
    k.particle = i;
    k.path = std::move(path);
    kinematic_.push_back(std::move(k));
    edited();
}

Vec3 Cloth::Kinematic::at(double t) const {
    if (path) return path(t);
    if (t >= t1) return to;
    if (t <= t0) return from;
    return from + ((t - t0) / (t1 - t0)) * (to - from);
}

void Cloth::setKinematicTarget(Index i, const Vec3& target, double arrival) {
    checkIndex(i, state_.x.size(), "setKinematicTarget");
    // Called for every attachment in every Bullet sub-step: the message is built on failure only.
    if (!target.allFinite())
        requireFinite(target, "kinematic target of particle " + std::to_string(i));
    if (!std::isfinite(arrival))
        throw Error(ErrorCode::InvalidArgument, "kinematic target of particle " +
                                                    std::to_string(i) +
                                                    ": the arrival time is not finite");
    auto it = std::find_if(kinematic_.begin(), kinematic_.end(),
                           [i](const Kinematic& k) { return k.particle == i; });
    if (it == kinematic_.end()) { // a new kinematic particle: held where it is, an edit
        pin(i);
        Kinematic k;
        k.particle = i;
        kinematic_.push_back(k);
        it = kinematic_.end() - 1;
    }
    it->path = nullptr;
    it->to = target;
    if (arrival <= state_.time) { // there now
        it->from = target;
        it->t0 = it->t1 = state_.time;
        if (state_.x[i] != target) {
            state_.x[i] = target;
            state_.forcesValid = false;
            edited();
        }
        return;
    }
    it->from = state_.x[i];
    it->t0 = state_.time;
    it->t1 = arrival;
}

void Cloth::unpin(Index i) {
    checkIndex(i, state_.x.size(), "unpin");
    setHeld(i, false);
}

void Cloth::setGrab(Index i, const Vec3& target, double stiffness) {
    checkIndex(i, state_.x.size(), "setGrab");
    if (!target.allFinite()) requireFinite(target, "grab target of particle " + std::to_string(i));
    if (!(stiffness == 0.0 || (stiffness >= kMinGrabStiffness && stiffness <= kMaxGrabStiffness)))
        throw Error(ErrorCode::InvalidArgument,
                    "grab stiffness of particle " + std::to_string(i) +
                        " must be 0 (automatic) or in [1e-6, 1e12] N/m, got " + num(stiffness));
    // The grab replaces the integrator's move of its particle with its own exact one: only
    // Velocity-Verlet's move is that particle's alone. An implicit or multi-stage integrator
    // moves the particle's neighbours with it as free (review 22: with implicit Euler a sheet
    // hanging from its grab fell 10 m, with RK4 it sagged three times too far).
    if (settings_.integrator != IntegratorKind::VelocityVerlet)
        throw Error(ErrorCode::InvalidArgument,
                    "setGrab needs the Velocity-Verlet integrator (ClothSettings::integrator, "
                    "the default); this cloth uses " +
                        std::string(toString(settings_.integrator)));
    if (stiffness == 0.0) stiffness = totalMass() * 9.81 / kGrabSag;
    auto it =
        std::find_if(grabs_.begin(), grabs_.end(), [i](const Grab& g) { return g.particle == i; });
    if (it != grabs_.end() && it->target == target && it->stiffness == stiffness) return;
    if (it == grabs_.end()) it = grabs_.insert(grabs_.end(), Grab{i, target, stiffness});
    it->target = target;
    it->stiffness = stiffness;
    edited();
}

void Cloth::releaseGrab(Index i) {
    checkIndex(i, state_.x.size(), "releaseGrab");
    auto it =
        std::find_if(grabs_.begin(), grabs_.end(), [i](const Grab& g) { return g.particle == i; });
    if (it == grabs_.end()) return;
    grabs_.erase(it);
    edited();
}

void Cloth::releaseGrabs() {
    if (grabs_.empty()) return;
    grabs_.clear();
    edited();
}

bool Cloth::isPinned(Index i) const {
    checkIndex(i, state_.x.size(), "isPinned");
    return state_.pinned[i] != 0;
}

// --- forces and stages ----------------------------------------------------------------------

void Cloth::setUserForce(Index i, const Vec3& force) {
    forceModel_->setUserForce(i, force);
    state_.forcesValid = false;
    edited();
}
void Cloth::clearUserForces() {
    forceModel_->clearUserForces();
    state_.forcesValid = false;
    edited();
}
// A value equal to the one in force is no edit: a game that sets the wind, the gravity or the
// air every frame does not keep its cloths awake (review 18: a tablecloth given the same
// still wind each frame never slept, 1.3-1.8 ms a frame for ever).
void Cloth::setWind(const Vec3& wind) {
    if (wind == settings_.aero.wind) return;
    forceModel_->setWind(wind);
    settings_.aero.wind = wind;
    state_.forcesValid = false;
    edited();
}
void Cloth::setAero(const AeroSettings& aero) {
    validateAero(aero);
    const AeroSettings& now = settings_.aero;
    if (aero.airDensity == now.airDensity && aero.dragCoefficient == now.dragCoefficient &&
        aero.liftCoefficient == now.liftCoefficient && aero.wind == now.wind)
        return;
    forceModel_->setAero(aero);
    settings_.aero = aero;
    state_.forcesValid = false;
    edited();
}
void Cloth::setRelativeDamping(double rate) {
    requireNonNegative(rate, "relativeDamping");
    if (rate == settings_.relativeDamping) return;
    settings_.relativeDamping = rate;
    edited();
}

void Cloth::setGravity(const Vec3& g) {
    if (g == settings_.gravity) return;
    forceModel_->setGravity(g);
    settings_.gravity = g;
    state_.forcesValid = false;
    edited();
}
void Cloth::addExternalForce(std::string name, ForceModel::ExternalForce force) {
    forceModel_->addExternalForce(std::move(name), std::move(force));
    state_.forcesValid = false;
    edited();
}
void Cloth::setContacts(std::shared_ptr<ContactSet> contacts) {
    forceModel_->setContacts(std::move(contacts));
    state_.forcesValid = false;
    edited();
}

void Cloth::setExecutor(std::shared_ptr<Executor> executor) {
    refuseInStep("Cloth::setExecutor");
    if (executor && executor->concurrency() < 1)
        throw Error(ErrorCode::InvalidArgument,
                    "Cloth::setExecutor: the executor's concurrency() is " +
                        std::to_string(executor->concurrency()) +
                        "; it must be >= 1 (the threads its parallelFor runs the pieces on, the "
                        "caller's included)");
    executor_ = std::move(executor);
    bindLoops(false);
}

void Cloth::bindLoops(bool startPool) {
    Executor* want = executor_.get();
    if (!want && settings_.threads > 1) {
        // The cloth's own pool, started by the first step that needs it (a cloth that is
        // given an executor before it steps never starts one).
        if (!poolStorage_ && startPool)
            poolStorage_ = std::make_unique<detail::ThreadPool>(settings_.threads);
        want = poolStorage_.get();
    }
    if (want == loops_) return;
    loops_ = want;
    forceModel_->setExecutor(want);
    limiter_.setExecutor(want);
}

void Cloth::addStage(std::shared_ptr<ClothStage> stage) {
    if (!stage) throw Error(ErrorCode::InvalidArgument, "addStage: stage is null");
    callerStageSlots_.push_back(timers_.slot(stage->name()));
    callerStageBeforeSlots_.push_back(timers_.slot(stage->name() + "_before_limit"));
    stages_.push_back(std::move(stage));
    edited();
}

void Cloth::removeStage(const ClothStage* stage) {
    for (std::size_t s = 0; s < stages_.size(); ++s) {
        if (stages_[s].get() == stage) {
            stages_.erase(stages_.begin() + static_cast<std::ptrdiff_t>(s));
            callerStageSlots_.erase(callerStageSlots_.begin() + static_cast<std::ptrdiff_t>(s));
            callerStageBeforeSlots_.erase(callerStageBeforeSlots_.begin() +
                                          static_cast<std::ptrdiff_t>(s));
            stagesRemoved_ = true;
            edited();
            return;
        }
    }
}

// --- state ------------------------------------------------------------------------------------

Vec3List& Cloth::mutablePositions() {
    state_.forcesValid = false;
    edited();
    return state_.x;
}
Vec3List& Cloth::mutableVelocities() {
    state_.forcesValid = false;
    edited();
    return state_.v;
}
void Cloth::setPosition(Index i, const Vec3& x) {
    checkIndex(i, state_.x.size(), "setPosition");
    requireFinite(x, "position of particle " + std::to_string(i));
    if (state_.pinned[i])
        movedHeld(i, x);
    else
        state_.x[i] = x;
    state_.forcesValid = false;
    edited();
}
void Cloth::setVelocity(Index i, const Vec3& v) {
    checkIndex(i, state_.x.size(), "setVelocity");
    requireFinite(v, "velocity of particle " + std::to_string(i));
    if (state_.pinned[i]) return; // pinned and kinematic particles keep their prescribed motion
    state_.v[i] = v;
    state_.forcesValid = false;
    edited();
}

// --- queries -------------------------------------------------------------------------------

std::optional<ClothHit> Cloth::rayCast(const Vec3& from, const Vec3& to) const {
    requireFinite(from, "rayCast: from");
    requireFinite(to, "rayCast: to");
    checkDiagnosticSizes("Cloth::rayCast");
    const auto& x = state_.x;
    const auto& tris = topology_->triangles();
    std::optional<ClothHit> best;
    for (std::size_t k = 0; k < tris.size(); ++k) {
        const Triangle& t = tris[k];
        double along = 0.0;
        Vec3 bary;
        if (!segmentCrossesTriangle(from, to, x[t[0]], x[t[1]], x[t[2]], along, bary)) continue;
        if (best && along >= best->fraction) continue;
        ClothHit hit;
        hit.fraction = along;
        hit.point = bary[0] * x[t[0]] + bary[1] * x[t[1]] + bary[2] * x[t[2]];
        hit.triangle = static_cast<Index>(k);
        hit.barycentric = bary;
        int corner = 0; // nearest by distance (the largest weight is not, in a right triangle)
        for (int c = 1; c < 3; ++c)
            if ((x[t[c]] - hit.point).squaredNorm() < (x[t[corner]] - hit.point).squaredNorm())
                corner = c;
        hit.particle = t[corner];
        const Vec3 face = (x[t[1]] - x[t[0]]).cross(x[t[2]] - x[t[0]]).normalized();
        hit.normal = face.dot(from - to) >= 0.0 ? face : Vec3(-face);
        best = hit;
    }
    return best;
}

// --- diagnostics ----------------------------------------------------------------------------

// Each reads the positions or velocities by particle (or by spring end): a vector resized
// through mutablePositions() or mutableVelocities() is refused by name, not read past its end.
void Cloth::checkDiagnosticSizes(const char* who) const {
    if (state_.x.size() == invMass_.size() && state_.v.size() == invMass_.size()) return;
    checkStateSizes(who);
}
double Cloth::maxStrain() const {
    checkDiagnosticSizes("Cloth::maxStrain");
    return maxSpringStrain(*topology_, state_.x);
}
double Cloth::meanStrain() const {
    checkDiagnosticSizes("Cloth::meanStrain");
    return meanSpringStrain(*topology_, state_.x);
}
double Cloth::kineticEnergy() const {
    checkDiagnosticSizes("Cloth::kineticEnergy");
    if (state_.asleep) return 0.0; // at rest; state_.v keeps the frozen state to resume from
    const std::vector<double>& m = masses();
    double e = 0.0;
    for (std::size_t i = 0; i < state_.v.size(); ++i)
        e += 0.5 * m[i] * state_.v[i].squaredNorm();
    return e;
}
double Cloth::totalMass() const {
    double sum = 0.0;
    for (double m : masses())
        sum += m;
    return sum;
}
Vec3 Cloth::momentum() const {
    checkDiagnosticSizes("Cloth::momentum");
    Vec3 p = Vec3::Zero();
    if (state_.asleep) return p;
    const std::vector<double>& m = masses();
    for (std::size_t i = 0; i < state_.v.size(); ++i)
        p += m[i] * state_.v[i];
    return p;
}
double Cloth::springEnergy() const {
    checkDiagnosticSizes("Cloth::springEnergy");
    return drape::springEnergy(topology_->springs(), forceModel_->stiffness(), state_.x);
}
double Cloth::gravityEnergy() const {
    checkDiagnosticSizes("Cloth::gravityEnergy");
    const std::vector<double>& m = masses();
    double e = 0.0;
    for (std::size_t i = 0; i < state_.x.size(); ++i)
        e -= m[i] * settings_.gravity.dot(state_.x[i]);
    return e;
}
double Cloth::maxAngularFrequency() const {
    if (omegaMax_ < 0.0) {
        omegaMax_ = estimateMaxAngularFrequency(*topology_, forceModel_->stiffness(), invMass_);
    }
    return omegaMax_;
}
double Cloth::stableTimeStep() const {
    return drape::stableTimeStep(settings_.integrator, maxAngularFrequency());
}

// The fastest the air can move against a particle in a step of dt: the fastest free particle
// relative to the wind, and what gravity adds in the step. (The wind's speed plus the fastest
// particle's counted a cloth carried along by the wind as twice as fast against it: a sheet
// blown at 10 m/s, at rest relative to the air, was refused at 20; review 19.)
double Cloth::aeroSpeedBound(double dt) const {
    return std::sqrt(aeroExtent().fastest2) + settings_.gravity.norm() * dt;
}

// The state's part of the drag's limit: the fastest free particle and the largest area per
// mass. Asleep, the state and the air are frozen (any change wakes the cloth): measured once,
// not in an O(triangles) pass every step (review 18: a sleeping flag cost 0.126 ms a frame
// against 0.001 without air).
const Cloth::AeroExtent& Cloth::aeroExtent() const {
    if (state_.asleep && aeroExtent_.known) return aeroExtent_;
    AeroExtent& e = aeroExtent_;
    e.fastest2 = 0.0;
    const Vec3& wind = settings_.aero.wind;
    for (std::size_t i = 0; i < state_.v.size(); ++i)
        if (invMass_[i] != 0.0)
            e.fastest2 = std::max(e.fastest2, (state_.v[i] - wind).squaredNorm());
    aeroArea_.assign(state_.x.size(), 0.0);
    const auto& x = state_.x;
    for (const Triangle& t : topology_->triangles()) {
        const double area = 0.5 * (x[t[1]] - x[t[0]]).cross(x[t[2]] - x[t[0]]).norm();
        for (Index i : t)
            aeroArea_[i] += area;
    }
    const std::vector<double>& m = masses();
    e.areaPerMass = 0.0;
    for (std::size_t i = 0; i < x.size(); ++i)
        if (invMass_[i] != 0.0) e.areaPerMass = std::max(e.areaPerMass, aeroArea_[i] / m[i]);
    e.known = state_.asleep;
    return e;
}

// Drag and lift are explicit in every integrator: a particle's velocity relaxes toward the
// air's at a rate r = d|F| / d|u| / m, and an explicit step is stable for r dt < 2. A corner's
// share of a triangle's force is rho C A |u|^2 / 6 (C = C_d + |C_l|), whose derivative in the
// corner's velocity (a third of the triangle's mean) is below rho C A |u| / 3; summed over the
// particle's triangles, divided by its mass. Infinite without aerodynamics. (A cloth in water,
// airDensity 1000, in a 1 m/s current went non-finite in its first 60 Hz frame.)
double Cloth::aeroTimeStep(double dt) const {
    const AeroSettings& a = settings_.aero;
    const double coefficient = a.airDensity * (a.dragCoefficient + std::abs(a.liftCoefficient));
    if (!(coefficient > 0.0)) return std::numeric_limits<double>::infinity();
    const AeroExtent& e = aeroExtent();
    const double speed = std::sqrt(e.fastest2) + settings_.gravity.norm() * dt;
    if (!(speed > 0.0)) return std::numeric_limits<double>::infinity();
    double rate = e.areaPerMass;
    rate *= coefficient * speed / 3.0;
    return rate > 0.0 ? 2.0 / rate : std::numeric_limits<double>::infinity();
}

} // namespace drape
