// drape/cloth.hpp: one simulated cloth: shared topology, per-instance settings and state,
// and the step driver.
//
// A step runs a fixed table of stages (Cloth::kStages in cloth.cpp), each only when this
// cloth needs it: forces_refresh (stale cached forces), integrate, kinematic, grab, the caller's
// stages' beforeLimit (contacts found; their planes go to the limiter through the cloth's
// ContactSet), strain_limit, the caller's stages (collisions...), forces (one timer per active
// force term), integrate_finish (Velocity-Verlet) and verify. pipeline() lists what a step runs,
// from the same table; timers() reports each stage's calls and seconds.
//
// Sleeping (settings.sleep, off by default): after settings.sleep.time seconds in which no
// particle strayed farther than settings.sleep.distance (see SleepSettings) the cloth falls asleep
// with its state frozen exactly; a step of a sleeping cloth only checks dt, evaluates the kinematic
// paths and advances time() and stepCount(). Anything that could change the motion wakes it before
// the next step: the state edits below (setPosition, setVelocity, mutablePositions/Velocities, pin,
// unpin, setKinematic, setGrab and releaseGrab), forces (setUserForce, clearUserForces, setWind,
// setGravity, setAero, setRelativeDamping: each only when it changes the value; the same value set
// every frame is no edit), addExternalForce), stages (addStage, removeStage), setSleep,
// loadSnapshot, wake(), and a kinematic path whose target for the step is farther from where its
// particle is than kKinematicWakeShare of sleep.distance (10 um by default). Waking restarts the
// quiet count and continues from the frozen state: the trajectory after waking is that of a cloth
// (sleeping or not) restored from a snapshot of the frozen state. An external force term or a
// caller stage that would act on a sleeping cloth must have its owner call wake() (drape::bullet
// does, for moving bodies). Snapshots store sleep (asleep, the quiet time and where it is measured
// from): a loaded cloth sleeps or counts on as the saved one did.
#pragma once

#include "drape/contacts.hpp"
#include "drape/executor.hpp"
#include "drape/forces.hpp"
#include "drape/integrators.hpp"
#include "drape/settings.hpp"
#include "drape/strain_limit.hpp"
#include "drape/timers.hpp"
#include "drape/topology.hpp"

#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace drape {

class Cloth;
namespace detail {
class SelfCollider;
}
namespace detail {
class ThreadPool;
}

/// A stage the caller plugs into the step (a collision stage, for example): beforeLimit runs
/// before the strain limiter, run after it. It may move particles (Cloth::mutablePositions())
/// and change velocities.
class ClothStage {
  public:
    virtual ~ClothStage() = default;
    /// Name used for the stage's timer.
    virtual std::string name() const = 0;
    /// Runs once per step after the strain limiter; dt is the step's time step [s].
    virtual void run(Cloth& cloth, double dt) = 0;
    /// Runs once per step before the strain limiter, after integration and the kinematic
    /// targets (a collision stage finds its contacts here, and puts their planes into the
    /// cloth's ContactSet, which the limiter's walk then keeps). Default: nothing.
    virtual void beforeLimit(Cloth& cloth, double dt) {
        (void)cloth;
        (void)dt;
    }
    /// What the stage carries from one step to the next, for the cloth's snapshots
    /// (drape/snapshot.hpp). Default: nothing.
    virtual std::vector<unsigned char> saveState() const { return {}; }
    /// Restores what saveState returned; empty bytes mean "start afresh" (the snapshot did not
    /// name this stage). Throws drape::Error on bytes it cannot take, before changing itself.
    virtual void loadState(const std::vector<unsigned char>& bytes) { (void)bytes; }
};

/// What a cloth carries from one step to the next besides its limiter's warm start
/// (StrainLimiter::warmStartState) and its stages' own states: what a snapshot saves
/// (drape/snapshot.hpp). Cloth::state() reads it and Cloth::restoreState puts it back;
/// everything else a cloth holds is built from its topology and settings, or is one step's
/// scratch.
struct ClothState {
    Vec3List x; ///< positions [m]
    Vec3List v; ///< velocities [m/s]
    Vec3List f; ///< last evaluated forces [N] (Cloth::forces())
    /// f is the force of (x, v) under the cloth's force terms (else the next step evaluates it).
    bool forcesValid = false;
    /// Per particle: held (pinned or kinematic: zero inverse mass) or free.
    std::vector<unsigned char> pinned;
    double time = 0.0;       ///< simulated time [s]
    std::uint64_t steps = 0; ///< steps taken
    bool asleep = false;     ///< Cloth::isAsleep()
    double quietTime = 0.0;  ///< consecutive quiet simulated time while awake [s]
    Vec3List anchor;         ///< positions at the start of the quiet time (empty: none yet)
    /// Velocity-Verlet with aerodynamics and no damping flows: the aerodynamic forces [N] of the
    /// last closing kick (at x and the predicted end velocity), which the next opening kick
    /// takes instead of evaluating them again when forcesValid (integrators.cpp). Empty: none.
    /// (Last, so that a ClothState built field by field in order stays as it was.)
    Vec3List aero;
    /// The last step's strain limiter left springs beyond its bound (it stopped at its cap,
    /// or held particles were too far apart): the next step first brings its starting
    /// positions within the bound as positions only, so that repairing stretch left from
    /// before does not become speed (dragging a cloth past its reach and letting go threw
    /// it apart at 114 m/s).
    bool overBound = false;
    /// The strain bound the state was stepped under (LimiterSettings::maxStrain; infinity
    /// without the stress-ordered limiter; NaN: not known, as in a hand-made state or a
    /// snapshot before version 6). restoreState into a cloth whose bound is tighter, with
    /// springs beyond it (and its band), sets overBound: the stretch the looser bound allowed
    /// is taken back as positions, not thrown (a hanging curtain restored into a cloth with
    /// maxStrain 0.02 instead of 0.1 flew apart at 25 m/s).
    double bound = std::numeric_limits<double>::quiet_NaN();
};

/// Where a segment first meets a cloth (Cloth::rayCast): what a game needs to pick the cloth
/// with the mouse and drag it.
struct ClothHit {
    double fraction = 0.0;           ///< of the way from `from` to `to`, in [0, 1]
    Vec3 point = Vec3::Zero();       ///< [m]
    Index triangle = 0;              ///< into topology().triangles()
    Vec3 barycentric = Vec3::Zero(); ///< the point's weights on the triangle's corners
    Index particle = 0;              ///< the triangle's corner nearest the point (to pin or drag)
    Vec3 normal = Vec3::Zero();      ///< the triangle's unit normal, on the side of `from`
};

/// A prescribed path for a kinematic particle: position [m] at simulated time t [s].
using KinematicPath = std::function<Vec3(double t)>;

/// The stretch-wave speed of the automatic stiffness for `topology` under `settings` [m/s, or
/// scene units per second]: settings.stretchWaveSpeed, or sqrt(|g| L / kAutomaticHangingStrain)
/// if that is more, L the largest side of the rest shape's bounding box (drape/settings.hpp).
/// Taken when the cloth is built, with the settings' gravity: a later Cloth::setGravity (or a
/// Bullet world's gravity, BulletClothSettings::useWorldGravity) does not change the springs.
double automaticWaveSpeed(const ClothTopology& topology, const ClothSettings& settings);

class ClothPairCollider;

class Cloth {
  public:
    /// Builds masses and stiffnesses from the settings and validates everything; throws
    /// drape::Error naming the bad parameter.
    Cloth(TopologyPtr topology, const ClothSettings& settings);
    ~Cloth();
    Cloth(const Cloth&) = delete;
    Cloth& operator=(const Cloth&) = delete;

    /// Advances the cloth by dt [s]. Throws drape::Error on a non-positive or non-finite dt,
    /// on a dt beyond the stability limit (if settings.rejectUnstableTimeStep), and when the
    /// state stops being finite or fails a check of settings.failure (the state is then left
    /// as it was before the step). With failure.retrySubsteps >= 2 a failed step is first
    /// retried as that many sub-steps. Throws drape::Error (InvalidArgument) when the positions
    /// or velocities (mutablePositions(), mutableVelocities()) no longer hold particleCount()
    /// entries, and when called during the cloth's own step (from a stage: inStep()).
    /// With settings.substeps.automatic (the default) a dt beyond substeps.fraction of the
    /// stability limit is taken as substepsFor(dt) equal sub-steps; the step then counts once
    /// (stepCount()), and what it reports (lastLimiterStats(), constraintImpulses()) sums them.
    void step(double dt);
    /// The sub-steps step(dt) takes (1 without automatic sub-steps). Throws drape::Error on a
    /// non-positive or non-finite dt, and on a dt that would need more than
    /// substeps.maxSubsteps.
    int substepsFor(double dt) const;
    /// step(dt) taken as one of `parts` equal sub-steps of a longer step (parts * dt) that the
    /// caller cuts itself (drape::bullet does, to exchange impulses with bodies after every
    /// cloth step): the same step, except that the strain limiter's band, warm start and
    /// long-range slack (bandAt, warmStartAt, longRangeSlackAt) are those of the whole step,
    /// as they are for step()'s own automatic sub-steps. Throws drape::Error on parts < 1.
    void stepPart(double dt, int parts);
    /// Steps that failed and succeeded when retried as sub-steps.
    std::uint64_t retriedSteps() const { return retries_; }
    /// Whether the cloth is inside its own step (true while its stages run). step, stepPart,
    /// restoreState, loadSnapshot and setExecutor refuse to run then (drape::Error
    /// InvalidArgument).
    bool inStep() const { return inStep_; }

    // --- sleeping (see the top of this file and SleepSettings) -----------------------------
    bool isAsleep() const { return state_.asleep; }
    /// Wakes the cloth (if asleep) and restarts its quiet time.
    void wake();
    /// Changes the sleep settings (validated; throws drape::Error) and wakes the cloth.
    void setSleep(const SleepSettings& sleep);

    // --- self-collision (settings.selfCollision, off by default) ---------------------------
    /// Changes ClothSettings::selfCollision (validated; throws drape::Error) and wakes the
    /// cloth.
    void setSelfCollision(const SelfCollisionSettings& self);
    /// What the self-collision stage did in the last step (its sub-steps summed).
    struct SelfCollisionStats {
        std::size_t pairTests = 0; ///< particle-triangle pairs given to the exact test
        std::size_t contacts = 0;  ///< pairs closer than the thickness that were corrected
    };
    const SelfCollisionStats& lastSelfCollision() const { return selfStats_; }
    /// Steps taken asleep (each cost O(number of kinematic particles)).
    std::uint64_t sleptSteps() const { return sleptSteps_; }
    /// Consecutive quiet simulated time so far while awake [s].
    double quietTime() const { return state_.quietTime; }

    // --- pins -----------------------------------------------------------------------------
    /// Fixes particle i where it is now (or at `position`); it never moves until unpinned.
    /// Moving a held particle with pin(i, position) or setPosition is a teleport: the next
    /// step brings the cloth within its strain bound as positions, and the jump gives it no
    /// speed. To move pins as motion (a curtain rod carried along), use setKinematicTarget.
    void pin(Index i);
    void pin(Index i, const Vec3& position);
    /// Drives particle i along a path: x(t) = path(t); its velocity follows the path.
    void setKinematic(Index i, KinematicPath path);
    /// Drives particle i by data: from where it is now in a straight line to `target` [m],
    /// arriving at simulated time `arrival` [s] and held there after (steps and sub-steps in
    /// between interpolate). An arrival at or before time() puts it at `target` now. Called
    /// again, the move starts afresh from where the particle is; the first call makes the
    /// particle kinematic (zero inverse mass), later ones do not count as edits (a sleeping
    /// cloth wakes only when the target moves). drape::bullet's attachments are these.
    void setKinematicTarget(Index i, const Vec3& target, double arrival);
    /// Returns particle i to free motion with its mass.
    void unpin(Index i);
    bool isPinned(Index i) const; ///< pinned or kinematic

    // --- grabs (picking with the mouse) -----------------------------------------------------
    /// A spring pulling one free particle toward a target: how a mouse drags a cloth.
    struct Grab {
        Index particle = 0;
        Vec3 target = Vec3::Zero(); ///< [m]
        double stiffness = 0.0;     ///< in force [N/m] (the automatic one resolved)
    };
    /// The automatic grab stiffness is the cloth's weight per this length: a grab lifting the
    /// whole cloth at 9.81 m/s^2 stays this far below its target [m].
    static constexpr double kGrabSag = 0.05;
    /// The stiffest grab [N/m]: far stiffer than any cloth pulls (a grab this stiff is a pin
    /// that the cloth can still pull a little), and the exact motion stays within double's range.
    static constexpr double kMaxGrabStiffness = 1e12;
    /// The softest grab [N/m] other than 0 (automatic): below it the held forces over the
    /// stiffness leave double precision (a grab of 1e-20 N/m threw its particle at 3.5e5 m/s).
    static constexpr double kMinGrabStiffness = 1e-6;
    /// A sleeping cloth wakes when a kinematic target is farther than this share of
    /// SleepSettings::distance from its frozen particle [-].
    static constexpr double kKinematicWakeShare = 1e-3;
    /// Pulls particle i toward `target` [m] with a critically damped spring of `stiffness`
    /// [N/m] (0: automatic, the cloth's mass times 9.81 m/s^2 over kGrabSag). Unlike
    /// setKinematicTarget, which puts the particle on its target whatever the cloth does, the
    /// cloth pulls back: a drag it cannot follow (a flat curtain dragged sideways in its own
    /// plane) leaves the particle short of the target instead of locking the limiter at
    /// hundreds of ms a frame (README, "Picking and dragging a cloth"). The spring is solved
    /// exactly over each step and sub-step, from the step's start with the particle's other
    /// forces held there, in place of the integrator's move (the stage "grab", before the
    /// limiter), so any stiffness is stable: it enters no stability limit and changes no
    /// sub-step count, and at rest it carries what the cloth pulls.
    /// The damper is critical for the particle alone: the cloth as a whole swings past the
    /// target before it settles (a free sheet pulled 1 m without gravity went 0.73 m past).
    /// A target far beyond the cloth's reach pulls it as hard as the stiffness says (a target
    /// 10 m from a sheet's pinned edge: 7 ms a frame, 47 ms at 1e12 N/m), and what it pumped in
    /// the cloth keeps when let go (67-79 m/s); the energy check (failure.maxEnergyGrowth) is
    /// off while a grab holds. A held particle (pinned, kinematic, attached) is not moved by
    /// its grab. Called again for the same particle, target and stiffness are replaced: the
    /// same values are no edit (a sleeping cloth stays asleep), others wake the cloth. Grabs
    /// are inputs, as user forces: snapshots do not store them. Throws drape::Error (nothing
    /// changed) on an index out of range, a non-finite target, a stiffness other than 0 outside
    /// [kMinGrabStiffness, kMaxGrabStiffness], or a cloth whose integrator is not
    /// Velocity-Verlet (the default): with implicit Euler or RK4 the integrator moves the
    /// particle's neighbours as if it were free (a grabbed sheet fell 10 m).
    void setGrab(Index i, const Vec3& target, double stiffness = 0.0);
    /// Lets particle i go; no grab on it: nothing. Wakes the cloth when it held one.
    void releaseGrab(Index i);
    void releaseGrabs();                                      ///< every grab
    const std::vector<Grab>& grabs() const { return grabs_; } ///< in the order first grabbed

    // --- forces ---------------------------------------------------------------------------
    void setUserForce(Index i, const Vec3& force); ///< persistent until cleared [N]
    void clearUserForces();
    void setWind(const Vec3& wind); ///< [m/s]; needs aero.airDensity > 0 (setAero) to act
    /// Replaces ClothSettings::aero (air density, drag and lift coefficients, wind): turns
    /// aerodynamics on or off after construction. Throws drape::Error (InvalidArgument or
    /// NonFinite) for a negative density or drag coefficient or a non-finite value, leaving
    /// the cloth unchanged.
    void setAero(const AeroSettings& aero);
    void setGravity(const Vec3& g); ///< [m/s^2]
    /// Sets ClothSettings::relativeDamping [1/s] (>= 0; throws drape::Error otherwise).
    void setRelativeDamping(double rate);
    /// Adds a force term from outside the core (for example contact penalties).
    void addExternalForce(std::string name, ForceModel::ExternalForce force);
    /// Contacts as data (drape/contacts.hpp): a collision stage fills `contacts` during the
    /// step, the cloth's contact force term ("contact_force") reads it and writes back the
    /// force each record got, which the caller passes on to its bodies after the step. Null
    /// removes the term.
    void setContacts(std::shared_ptr<ContactSet> contacts);

    // --- threads --------------------------------------------------------------------------
    /// Runs the step's data-parallel loops (springs, gravity, damping, integration, the
    /// limiter's scan) on `executor` (drape/executor.hpp) from the next step on, instead of the
    /// cloth's own pool (ClothSettings::threads > 1, started by the first step that needs it);
    /// null goes back to that pool (or to the calling thread when threads is 1). The cloth
    /// shares ownership. Results are bit-identical for any executor and thread count. Not
    /// during a step (drape::Error InvalidArgument); like every edit, not while another thread
    /// steps the cloth. In a drape::bullet world, a cloth with threads > 1 is given the
    /// world's executor unless it has one of its program's (BulletClothSettings::threads).
    void setExecutor(std::shared_ptr<Executor> executor);
    /// The executor the loops run on now, to tell which it is: the one given with
    /// setExecutor, the cloth's own pool (once started), or null (the calling thread).
    const Executor* executor() const { return loops_; }
    /// Whether the loops run on an executor given with setExecutor (a drape::bullet world's
    /// included).
    bool hasCallerExecutor() const { return executor_ != nullptr; }

    // --- stages ---------------------------------------------------------------------------
    /// Adds a stage after the others. During a step (from a stage) it runs from the next pass
    /// over the stages (its run() in the same step when added from a beforeLimit).
    void addStage(std::shared_ptr<ClothStage> stage);
    /// Removes a stage (nothing if it is not one of this cloth's). During a step (from a stage,
    /// itself included) the stages after it still run in that step, and it does not run again.
    void removeStage(const ClothStage* stage);

    // --- state ----------------------------------------------------------------------------
    const ClothTopology& topology() const { return *topology_; }
    const TopologyPtr& topologyPtr() const { return topology_; }
    const ClothSettings& settings() const { return settings_; }
    /// The topology's particle count (what positions() and velocities() must hold).
    std::size_t particleCount() const { return invMass_.size(); }
    const Vec3List& positions() const { return state_.x; } ///< [m]
    /// [m/s]. While the cloth sleeps (isAsleep), the velocities it fell asleep with, which it
    /// resumes from when woken: the cloth is at rest (kineticEnergy() and momentum() read 0).
    const Vec3List& velocities() const { return state_.v; }
    /// Last evaluated forces [N]. With Velocity-Verlet the velocity-dependent terms (linear and
    /// spring damping, aerodynamics) of free particles are not in it (the integrator applies
    /// them itself, see integrators.hpp); held particles' entries include them.
    const Vec3List& forces() const { return state_.f; }
    /// Mutable access for stages and users; marks the cached forces stale. Moving a pinned
    /// particle re-pins it where it is put. Change the values, not the size: a step (and
    /// saveSnapshot) refuses vectors that do not hold particleCount() entries.
    Vec3List& mutablePositions();
    Vec3List& mutableVelocities();
    void setPosition(Index i, const Vec3& x);
    void setVelocity(Index i, const Vec3& v);
    const std::vector<double>& masses() const { return forceModel_->mass(); } ///< [kg]
    const std::vector<double>& inverseMasses() const { return invMass_; }     ///< 0 if pinned
    const std::vector<double>& stiffness() const { return forceModel_->stiffness(); } ///< [N/m]
    double time() const { return state_.time; } ///< simulated time [s]
    std::uint64_t stepCount() const { return state_.steps; }

    /// The state a step carries to the next (ClothState).
    const ClothState& state() const { return state_; }
    /// Puts back a state read from this cloth or one with the same topology, and the limiter's
    /// warm start (one value per spring, >= 0, or empty for none), after checkState (the cloth
    /// unchanged when it throws). The inverse masses follow `pinned` (kinematic paths and
    /// targets are not part of the state); a cloth whose sleep is off stays awake. Not during
    /// the cloth's own step (from a stage: drape::Error InvalidArgument).
    void restoreState(ClothState state, std::vector<double> warmStart);
    /// Throws drape::Error (InvalidArgument or NonFinite, naming it) unless `state` and
    /// `warmStart` fit this cloth: every size, finite values, a quiet time >= 0, sleep anchors
    /// when asleep, a warm start >= 0. What restoreState checks, for a caller that must know
    /// before it changes anything else (loadSnapshot, before its stages take their states).
    void checkState(const ClothState& state, const std::vector<double>& warmStart) const;
    /// The caller's stages, in the order they run (addStage).
    const std::vector<std::shared_ptr<ClothStage>>& stages() const { return stages_; }

    // --- queries --------------------------------------------------------------------------
    /// The first place the segment from `from` to `to` [m] crosses the cloth's triangles at
    /// their current positions, from either side; nothing if it crosses none. Picking: cast
    /// the mouse ray, then pull ClothHit::particle toward the mouse with setGrab each frame
    /// and releaseGrab to let go (README, "Picking and dragging a cloth"; the laundry_line
    /// sample game). Every triangle is tested:
    /// O(triangles), about 10 ns each. Throws drape::Error (NonFinite) for a non-finite end.
    std::optional<ClothHit> rayCast(const Vec3& from, const Vec3& to) const;

    // --- diagnostics ----------------------------------------------------------------------
    double maxStrain() const;  ///< largest (l - L0) / L0 [-]
    double meanStrain() const; ///< mean (l - L0) / L0 [-]
    /// sum m v^2 / 2 [J]; 0 while asleep (velocities() then keep the frozen state the cloth
    /// resumes from when it wakes).
    double kineticEnergy() const;
    /// sum m of every particle, held ones included [kg].
    double totalMass() const;
    /// sum m v of every particle (held ones move with their paths; pinned ones are still)
    /// [kg m/s]; zero while asleep.
    Vec3 momentum() const;
    double springEnergy() const;  ///< sum k (l - L0)^2 / 2 [J]
    double gravityEnergy() const; ///< -sum m g . x [J]
    /// Upper bound on the largest angular frequency of the spring network [rad/s].
    double maxAngularFrequency() const;
    /// Largest stable time step of the cloth's integrator [s] (its springs).
    double stableTimeStep() const;
    /// Largest stable time step of the explicit aerodynamic drag and lift for a step of dt
    /// [s]: 2 / the fastest rate at which a particle's velocity relaxes toward the air's, at
    /// the fastest particle's speed relative to the wind (plus g dt). Infinite without
    /// aerodynamics. Automatic sub-steps keep within both (a cloth in water, or in a gale); without
    /// them step() refuses a dt beyond it at the speed of the moment (rejectUnstableTimeStep;
    /// an O(triangles) pass each step of a cloth with air, about a quarter of a 150 x 150
    /// sheet's step without a limiter: turn rejectUnstableTimeStep off to skip it).
    double aeroTimeStep(double dt) const;
    /// The fastest relative speed of the air a step of dt can see, as aeroTimeStep takes it:
    /// the fastest free particle's speed relative to the wind, plus g dt [m/s]. aeroTimeStep is
    /// inversely proportional to it: a step dt stays within the drag's limit up to a relative
    /// speed of aeroSpeedBound(dt) * aeroTimeStep(dt) / dt.
    double aeroSpeedBound(double dt) const;
    /// What the limiter did in the last step (its sub-steps and relimit() calls summed; the
    /// strains are the largest of them).
    const StrainLimitStats& lastLimiterStats() const { return limiterStats_; }
    /// Steps whose limiter stopped at its safety cap (LimiterSettings::maxRounds), or early
    /// because its held particles were too far apart (StrainLimitStats::pinsApart): steps in
    /// which the strain bound was not promised.
    std::uint64_t limiterCapHits() const { return limiterCapHits_; }
    /// The stress-ordered limiter (its warm start and long-range attachments).
    const StrainLimiter& limiter() const { return limiter_; }
    /// Per particle, the impulse the stress-ordered limiter's corrections (relimit() calls
    /// included) gave each kinematic particle (setKinematic; drape::bullet's attachments) in
    /// the last step [N s]: the reaction to the momentum its corrections gave the free
    /// particles next to it. Zero for free and pinned particles (nothing takes a pin's
    /// reaction, so it is not recorded; empty before the first step). A body holding the particle
    /// must take it (drape::bullet does for attachments), or the limiter's share of the load never
    /// reaches the body. Forces on held particles (forces()) are the springs' share. A walk that
    /// stopped at its cap (StrainLimitStats::capHit, counted in limiterCapHits()) adds nothing:
    /// its pulls are what a fight between constraints it cannot meet pumped, not a load.
    const Vec3List& constraintImpulses() const { return heldImpulse_; }

    // --- for stages ------------------------------------------------------------------------
    /// A stage moved the particles `touched` (a contact projection): their springs go into
    /// the limiter's worklist and the walk runs again from there; the particles it moves get
    /// v += dx / dt. relimitMoved() lists them (so the stage can re-check them). With
    /// `planes`, the stress-ordered walk keeps those particles above their contact planes
    /// (see StrainLimiter). The comparison limiters run whole and ignore the planes.
    StrainLimitStats relimit(const std::vector<Index>& touched, double dt,
                             ContactPlanes* planes = nullptr);
    const std::vector<Index>& relimitMoved() const;
    /// Inside a step (for stages): the positions at its start, before integration [m]. A
    /// collision stage sweeps each particle from here to where it is now. Outside a step: the
    /// start of the last step taken (empty before the first).
    const Vec3List& stepStartPositions() const { return step_.x0; }
    const PhaseTimers& timers() const { return timers_; }
    PhaseTimers& timers() { return timers_; }
    /// Names of the phases a step runs, in order (what the pipeline holds for this cloth).
    std::vector<std::string> pipeline() const;
    const Integrator& integrator() const { return *integrator_; }

    /// Throws drape::Error (InvalidArgument) naming `who` unless the positions and velocities
    /// still hold particleCount() entries (a vector from mutablePositions() or
    /// mutableVelocities() resized); step() and saveSnapshot check it (O(1)).
    void checkStateSizes(const std::string& who) const;

  private:
    friend class ClothPairCollider; // moves particles of a cloth at rest without waking it
    /// checkStateSizes for the diagnostics (maxStrain, energies, momentum): the common case,
    /// sizes unchanged, without building the message.
    void checkDiagnosticSizes(const char* who) const;
    struct StepContext;
    /// Per-step scratch, as Jolt keeps its update context apart from the body's state: what a
    /// step fills and reads, kept between steps only so that no step allocates. None of it is
    /// state (snapshots do not need it); x0 is the step's start (stepStartPositions()).
    struct StepBuffers {
        Vec3List x0, v0;                   ///< positions and velocities at the step's start
        Vec3List repaired;                 ///< x0 brought within the bound (overBound)
        std::vector<double> repairInvMass; ///< its inverse masses, contacts held
        Vec3List beforeLimit;              ///< positions before a comparison limiter or relimit
        std::vector<Vec3> kinematicStart;  ///< kinematic particles at the step's start
        std::vector<double> lambdaBefore;  ///< the limiter's warm start (restored on failure)
        std::vector<Index> relimitMoved;   ///< particles the last relimit() moved
    };
    /// The state a step with sub-steps (or a retry) puts back when one of them fails.
    struct Saved {
        Vec3List x, v;
        std::vector<double> lambda; ///< the limiter's warm start
        double time = 0.0;
        std::uint64_t steps = 0;
        bool overBound = false;
    };
    /// Copies the state into `s` (reusing its storage) / puts it back.
    void save(Saved& s) const;
    void restore(const Saved& s);
    /// Puts held particle i at `position`; a move sets overBound (a teleport).
    void movedHeld(Index i, const Vec3& position);
    /// The state's part of aeroTimeStep: the fastest free particle's squared speed relative to
    /// the wind [m^2/s^2]
    /// and the largest area of a free particle's triangles per its mass [m^2/kg].
    struct AeroExtent {
        double fastest2 = 0.0;
        double areaPerMass = 0.0;
        bool known = false; ///< measured while asleep: stands until the cloth wakes
    };
    const AeroExtent& aeroExtent() const;
    mutable std::vector<double> aeroArea_; ///< aeroTimeStep's scratch: area per particle
    /// aeroExtent's result (known: that of a sleeping cloth's frozen state, which stands;
    /// cleared whenever the cloth falls asleep, wakes or is restored).
    mutable AeroExtent aeroExtent_;
    /// The most walks repairStart takes.
    static constexpr int kRepairWalks = 4;
    /// Brings the step's starting positions within the bound, positions only (overBound).
    void repairStart(const LimiterSettings& lim);
    Saved wholeStepStart_; ///< stepPart's, kept between steps so that no step allocates
    /// One entry of the step table (see cloth.cpp): name, whether this cloth runs it,
    /// whether the driver times it (stages timed inside have their own timers), the stage.
    struct Stage {
        const char* name;
        bool timed;
        bool (*active)(const Cloth&);
        void (Cloth::*run)(StepContext&);
    };
    static const Stage kStages[12];
    void stepOnce(double dt);
    void stepWithRetry(double dt);
    void addLimiterStats(const StrainLimitStats& st);
    void stageForcesRefresh(StepContext& ctx);
    void stageIntegrate(StepContext& ctx);
    void stageKinematic(StepContext& ctx);
    void stageGrab(StepContext& ctx);
    /// The bound this cloth's states are stepped under (ClothState::bound).
    double ownBound() const;
    void stageLimit(StepContext& ctx);
    void stageCallerStages(StepContext& ctx);
    void stageCallerStagesBefore(StepContext& ctx);
    /// Runs the caller's stages' beforeLimit (or run) in order, robust to stages added or
    /// removed by a stage during the loop.
    void runCallerStages(double dt, bool beforeLimit);
    /// Throws drape::Error (InvalidArgument) naming `who` when called during the step.
    void refuseInStep(const char* who) const;
    void stageForces(StepContext& ctx);
    void stageFinish(StepContext& ctx);
    void stageRelativeDamping(StepContext& ctx);
    void stageSelfCollision(StepContext& ctx);
    void stageVerify(StepContext& ctx);
    void applyLimiterMoves(double dt, const StrainLimitStats& walk);
    /// The limiter's settings for a step of dt, its band narrowed by bandAt.
    LimiterSettings limiterAt(double dt) const;
    double energyScale() const;
    void evaluateForces();
    void checkFinite(const char* where, double dt);
    void invalidateOmega() { omegaMax_ = -1.0; }
    void checkTimeStep(double dt) const;
    /// A state or force edit: wakes the cloth, unless a stage makes it inside a step.
    void edited() {
        if (!inStep_) wake();
    }
    bool kinematicTargetsMove(double dt) const;
    /// Pins (held) or frees particle i, dropping any kinematic path it had.
    void setHeld(Index i, bool held);
    void updateSleep(double dt);

    TopologyPtr topology_;
    ClothSettings settings_;
    std::vector<double> invMass_;
    ClothState state_; ///< what a step carries to the next (see ClothState)
    StepBuffers step_; ///< per-step scratch (see StepBuffers)
    /// A kinematic particle: a caller's path, or (path empty) a straight move from `from` at
    /// t0 to `to` at t1 (setKinematicTarget).
    struct Kinematic {
        Index particle = 0;
        KinematicPath path;
        Vec3 from = Vec3::Zero(), to = Vec3::Zero();
        double t0 = 0.0, t1 = 0.0;
        Vec3 at(double t) const;
    };
    std::vector<Kinematic> kinematic_;
    std::vector<Grab> grabs_;
    std::unique_ptr<detail::ThreadPool> poolStorage_; ///< ClothSettings::threads > 1
    std::shared_ptr<Executor> executor_;              ///< the caller's (setExecutor)
    Executor* loops_ = nullptr; ///< executor_, else poolStorage_, else null (this thread)
    /// Points loops_ (and the force model's and limiter's) at executor_, else at the cloth's
    /// own pool when threads > 1 (starting it if `startPool`), else at null.
    void bindLoops(bool startPool);
    std::unique_ptr<ForceModel> forceModel_;
    std::unique_ptr<Integrator> integrator_;
    std::vector<std::shared_ptr<ClothStage>> stages_;
    std::vector<std::size_t> stageSlots_;       ///< timer slot of each kStages entry
    std::vector<std::size_t> callerStageSlots_; ///< timer slot of each caller stage
    /// Timer slot of each caller stage's beforeLimit ("<name>_before_limit").
    std::vector<std::size_t> callerStageBeforeSlots_;
    /// runCallerStages' copy of the stages and their timer slots as its loop began (a stage
    /// may remove stages, itself included, while it runs); empty outside the loop.
    std::vector<std::shared_ptr<ClothStage>> runningStages_;
    std::vector<std::size_t> runningSlots_;
    bool stagesRemoved_ = false; ///< removeStage was called since that loop began
    StrainLimiter limiter_;
    StrainLimitStats limiterStats_;
    std::unique_ptr<detail::SelfCollider> selfCollider_; ///< scratch of the self-collision stage
    SelfCollisionStats selfStats_;
    std::uint64_t limiterCapHits_ = 0;
    PhaseTimers timers_;
    mutable double omegaMax_ = -1.0;
    std::uint64_t retries_ = 0;
    bool inStep_ = false;
    Vec3List heldImpulse_;            ///< see constraintImpulses()
    std::vector<Index> heldImpulsed_; ///< the particles whose heldImpulse_ is nonzero
    double wholeStep_ = 0.0; ///< inside a step: the caller's whole step (limiterAt); else 0
    std::uint64_t sleptSteps_ = 0;
};

} // namespace drape
