// BulletCloth: a drape::Cloth stepped by a Bullet dynamics world (see bullet_cloth.hpp). This
// file wires the parts together and holds the Bullet sub-step (Impl::step); the parts are:
//   proxy.*              the broadphase proxy (which bodies the cloth may touch)
//   body_snapshot.*      the bodies in double precision, and the impulses they get back
//   contacts.*           the contact stage (particle_contacts.cpp, triangle_contacts.cpp,
//                        particle_boxes.*: the cheap tests before a particle's query)
//   (the contact force term, eq. (7) and Coulomb friction, is the core's: drape/contacts.hpp)
//   attachments.*        attached particles as kinematic targets
//   shape_queries.*, validate.*, pose.hpp, drape/bullet/convert.hpp,
//   drape/bullet/settings.hpp
// (Self-collision is the cloth's own stage: ClothSettings::selfCollision.)
//
// One Bullet sub-step (btDiscreteDynamicsWorld::internalSingleStepSimulation) runs: rigid
// bodies predicted, broadphase and narrow-phase, constraints solved, transforms integrated,
// then the actions -- the world's cloth Stepper (one action for all of the world's cloths, see
// Impl::Stepper: steps 1-2 and 4-5 below on the world's thread, step 3 of every cloth as one
// task, in parallel with BulletClothSettings::threads). So when the cloth steps, the bodies are
// already at the end of the sub-step, and the cloth ends the sub-step at the same instant. The
// cloth's own steps see each moving body on its way there: it starts where its velocities say
// it was at the start of the sub-step and advances with them, step by step, as the cloth's
// impulses change them (BodySnapshot::startSweep/advance; a fast body cannot jump over the
// cloth between two of its steps). The impulses the cloth gives dynamic bodies change their
// velocities for the next sub-step (the same one-step lag as every Bullet action, e.g. the
// character controller and the raycast vehicle); a free body (in no contact with other bodies) also
// ends the sub-step where its sweep took it, so a body the cloth stopped does not stay inside it.
//
// Per sub-step (Impl::prepare: 1-2, Impl::advance: 3, Impl::finish: 4-5):
//   1. bodies:  the ghost's broadphase overlaps, filtered (no ghosts, soft bodies, triggers),
//               snapshotted in double precision (pose, velocities, inverse mass and inertia;
//               dynamic bodies in contact with others in Bullet marked supported);
//   2. attach:  attached particles get the body's new attachment point as a kinematic target;
//   3. step:    cloth.step(dt / n), n times (settings.substeps, or automatic: the fewest within
//               the cloth's stability limit); our contact stage runs inside it, before
//               the strain limiter (contacts found, their planes given to the limiter's
//               walk) and after it (what the walk moved projected again, the planes' pushes
//               to the bodies), and the eq. (7) penalty is one of the cloth's force terms;
//   4. impulses: a spring between two bodies' attachments holds them as a rope
//               (Attachments::holdTethers); the impulses accumulated on dynamic bodies
//               are applied;
//   5. proxy:   the ghost's AABB becomes the cloth's bounding box plus margin.
// A sleeping cloth (Cloth::isAsleep) is first woken if a candidate body is new, gone or
// moving (wakeForBodies); if it stays asleep, step 3 only advances its clock and steps 4 and
// 5 have nothing to do. After an awake sub-step in which it pushed an active dynamic body,
// its quiet time restarts.
#include "drape/bullet/bullet_cloth.hpp"

#include "attachments.hpp"
#include "body_snapshot.hpp"
#include "contacts.hpp"
#include "proxy.hpp"
#include "shape_queries.hpp"
#include "validate.hpp"

#include "drape/bullet/convert.hpp"
#include "drape/cloth_pair.hpp"
#include "drape/error.hpp"

#include <btBulletDynamicsCommon.h>
#include <oneapi/tbb/blocked_range.h>
#include <oneapi/tbb/info.h>
#include <oneapi/tbb/parallel_for.h>
#include <oneapi/tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <exception>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

namespace drape::bullet {

using detail::num;
using detail::require;

namespace {

/// total += s, count by count.
void accumulate(ContactStats& total, const ContactStats& s) {
    total.candidateBodies += s.candidateBodies;
    total.substeps = s.substeps; // (the latest)
    total.particleBoxTests += s.particleBoxTests;
    total.narrowphaseQueries += s.narrowphaseQueries;
    total.rayQueries += s.rayQueries;
    total.triangleQueries += s.triangleQueries;
    total.triangleContacts += s.triangleContacts;
    total.sweptTriangles += s.sweptTriangles;
    total.edgeContacts += s.edgeContacts;
    total.teleports += s.teleports;
    total.jumpedBodies += s.jumpedBodies;
    total.contacts += s.contacts;
    total.projections += s.projections;
    total.heldBetween += s.heldBetween;
    total.maxDepth = std::max(total.maxDepth, s.maxDepth);
    total.maxStrain = std::max(total.maxStrain, s.maxStrain);
    total.boundBroken += s.boundBroken;
    total.selfContacts += s.selfContacts;
    total.selfPairTests += s.selfPairTests;
    total.clothContacts += s.clothContacts;
    total.clothPairTests += s.clothPairTests;
    total.impulseOnBodies += s.impulseOnBodies;
    total.impulseOnCloth += s.impulseOnCloth;
    total.refusedBodyImpulses += s.refusedBodyImpulses;
    total.planesLetGo += s.planesLetGo;
    total.relimitWalks += s.relimitWalks;
    total.steps += s.steps;
    total.proxyRefreshes += s.proxyRefreshes;
}

/// The world's rigid bodies that move: the kinematic ones, and the dynamic ones with a
/// velocity (Bullet's sleeping bodies have none). Every object is looked at (a flag test for
/// static ones): a kinematic body added as a static one and flagged kinematic afterwards is in
/// no shorter list of Bullet's.
void listMovers(const btCollisionWorld& world, std::vector<const btRigidBody*>& out) {
    out.clear();
    const btCollisionObjectArray& objects = world.getCollisionObjectArray();
    for (int k = 0; k < objects.size(); ++k) {
        const btCollisionObject* obj = objects[k];
        if (obj->isStaticObject() && !obj->isKinematicObject()) continue;
        const btRigidBody* rb = btRigidBody::upcast(obj);
        if (rb && (rb->isKinematicObject() || !rb->getLinearVelocity().fuzzyZero()))
            out.push_back(rb);
    }
}

/// The speed of the cloth's fastest free particle [m/s].
double fastestParticle(const Cloth& c) {
    double v2 = 0.0;
    for (std::size_t i = 0; i < c.particleCount(); ++i)
        if (c.inverseMasses()[i] != 0.0) v2 = std::max(v2, c.velocities()[i].squaredNorm());
    return std::sqrt(v2);
}

} // namespace

namespace {
/// The cloths in a world, with their handles: a cloth can be in one world once (a second
/// handle would step it twice per world step). Guarded: handles may live on several threads.
struct Registry {
    std::mutex lock;
    std::vector<std::pair<const Cloth*, const BulletCloth::Impl*>> entries;
};
Registry& registry() {
    static Registry r;
    return r;
}
} // namespace

namespace {
/// The world's threads as a cloth's Executor: a oneTBB arena of `threads` (the calling thread
/// included) in which the world's cloths take their steps, one task each, and the loops of a
/// cloth that asks for threads run as nested parallel_for (work stealing shares the arena's
/// threads between both levels). A loop of fewer than two of its pieces runs on the calling
/// thread. A cloth's loop is isolated: a thread that waits for its pieces takes no other
/// cloth's step meanwhile (which would hold this cloth's step, and its timers, until that one
/// ended).
class ArenaExecutor final : public Executor {
  public:
    static constexpr std::size_t kReadyDivisor = 8;
    explicit ArenaExecutor(int threads) : arena_(threads), threads_(threads) {}
    int concurrency() const override { return threads_; }
    void parallelFor(std::size_t n, std::size_t grain, const Body& body) override {
        // The core's grains are set for its own pool, whose workers sleep between steps; the
        // arena's stay ready, and pieces 8 times smaller pay (drape-bench-cloths, one cloth
        // with ClothSettings::threads 2: 180 x 180 0.94 -> 1.17-1.22x, 250 x 250 1.03 -> 1.27x
        // the one-thread speed; samples/benchmarks/PERF.md).
        grain = std::max<std::size_t>(grain / kReadyDivisor, 1);
        if (n < 2 * grain) {
            if (n > 0) body(0, n);
            return;
        }
        arena_.execute([&] {
            tbb::this_task_arena::isolate([&] {
                tbb::parallel_for(
                    tbb::blocked_range<std::size_t>(0, n, grain),
                    [&](const tbb::blocked_range<std::size_t>& r) { body(r.begin(), r.end()); });
            });
        });
    }
    tbb::task_arena& arena() { return arena_; }

  private:
    tbb::task_arena arena_;
    int threads_;
};

/// Whether `e` is a world's arena lent to a cloth (by any world's stepper, a destroyed one's
/// included), not an executor of the cloth's program.
bool isWorldLoan(const Executor* e) {
    return dynamic_cast<const ArenaExecutor*>(e) != nullptr;
}
} // namespace

struct BulletCloth::Impl {
    class Stepper;
    class Stage;

    Impl(btDynamicsWorld* w, std::shared_ptr<Cloth> c, const BulletClothSettings& s, double b,
         void* owner)
        : world(w), cloth(std::move(c)), settings(s), band(b), proxy(owner),
          contacts(settings, band) {}

    btDynamicsWorld* world = nullptr;
    std::shared_ptr<Cloth> cloth;
    BulletClothSettings settings;
    double band = 0.0;   ///< eq. (7) band width [m]
    double margin = 0.0; ///< broadphase margin [m]
    bool inWorld = false;
    /// The world stepped with the proxy out of it (the program removed it; prepare): the
    /// world lived then, so remove() takes the stepper out of it.
    bool proxyLost = false;
    /// The stepper stepping this cloth right now (Stepper::Stepping), else null.
    Stepper* steppingIn = nullptr;

    detail::ClothProxy proxy;
    detail::ContactSolver contacts;      ///< the contact stage's state, and the bodies
    ContactStats& last = contacts.stats; ///< this Bullet sub-step's counts
    ContactStats total;
    /// The cloth's fastest free particle at the start of the Bullet sub-step [m/s] (computed
    /// when a dynamic body is among the candidates; see ContactStats::refusedBodyImpulses).
    double clothSpeed = 0.0;
    detail::Attachments attachments;
    detail::BodyPoses poses; ///< the candidate bodies at the previous sub-step (for waking)
    std::vector<const btCollisionObject*> candidates;
    /// Scratch of checkAttachmentBodies (kept: it runs every sub-step with attachments).
    std::vector<const btCollisionObject*> attachedBodies;
    /// Where checkAttachmentBodies last found each attachment body in the world's object
    /// array, sorted by body: while every body is still at its index (compared as pointers,
    /// never dereferenced: a deleted body is only looked up), the array is not scanned again.
    std::vector<std::pair<const btCollisionObject*, int>> attachedAt;
    /// The world's moving rigid bodies (listMovers), listed once per Bullet sub-step by the
    /// world's stepper for all its cloths (addFastBodies); null: this cloth lists them itself.
    const std::vector<const btRigidBody*>* worldMovers = nullptr;
    /// The bodies in an enabled joint of the world, sorted (gatherBodies, scratch).
    std::vector<unsigned char> bodyFound;
    /// The action that steps the world's cloths (shared by every cloth of the world).
    std::shared_ptr<Stepper> stepper;
    /// The world's executor this handle gave the cloth (Stepper::lendExecutor), null if none.
    std::shared_ptr<Executor> lent;
    std::shared_ptr<Stage> stage;
    /// Timer slot in the cloth's PhaseTimers of the handle's work around the cloth's steps
    /// (body snapshot, proxy, impulses on bodies).
    std::size_t slotBodies = 0;
    /// "bullet_cloth_pairs": the collisions with other cloths this cloth is the first of.
    std::size_t slotPairs = 0;

    /// One Bullet sub-step of dt [s]: prepare, advance, finish.
    void step(double dt);
    /// Before the cloth's steps (on the world's thread): the bodies, the attachment targets,
    /// waking, the number of cloth steps.
    void prepare(double dt);
    /// The cloth's steps. Touches no Bullet object but the shapes it queries (read only), so
    /// the cloths of a world may advance in parallel (BulletClothSettings::threads).
    void advance();
    /// One cloth step of advance (false: the cloth left the world in it).
    bool advanceOne();
    /// What advance does after its cloth steps: the strain at the end, the proxy's next box.
    void advanceEnd();
    /// Steps the cloth in `n` steps of the Bullet sub-step stepDt: sets stepSubsteps, stepH and
    /// last.substeps (the cloth steps in all: its own automatic sub-steps split each further).
    /// With the cloth's automatic sub-steps off, a step beyond its stability limit is refused
    /// here with the count BulletClothSettings::substeps needs (UnstableTimeStep).
    void planSubsteps(int n);
    /// After them (on the world's thread): the impulses on the bodies, the proxy, the counts.
    void finish();
    /// The step being taken: its dt [s], cloth steps, their length [s], and timing.
    double stepDt = 0.0, stepH = 0.0, bodySeconds = 0.0;
    int stepSubsteps = 1;
    bool slept = true; ///< every cloth step of this sub-step was taken asleep
    std::vector<detail::Attachments::OutsideImpulse> outside;
    /// Draws the cloth's springs (debugDraw).
    void draw(btIDebugDraw* drawer) const;
    /// Joins the world's stepper (creating it, and adding it to the world, for the first
    /// cloth) and leaves it (removing it from a live world with the last cloth).
    void joinStepper();
    void leaveStepper(bool worldAlive);
    /// Snapshots the bodies among the proxy's overlaps (and the broadphase's answer for a
    /// larger box when the cloth would sweep out of the proxy in this step).
    /// `carried`: the cloth was carried with its attachment bodies (a teleport) in this
    /// sub-step (the bodies that jumped with it are then sweepAfterTeleport's).
    void gatherBodies(double dt, bool carried);
    /// A kinematic body's pose in this Bullet sub-step of dt: followKinematic from its pose in
    /// the last one (Bullet puts it at the end of the frame's motion in every sub-step),
    /// recorded for the next; nothing for any other body.
    std::optional<detail::Pose> followed(const btCollisionObject* obj, double dt);
    /// Kinematic bodies' (and characters') poses in the last Bullet sub-step and in this one
    std::unordered_map<const btCollisionObject*, detail::Pose> kinematicBefore, kinematicNow;
    /// The cloth was carried by `motion` (a teleport or a snap turn,
    /// Attachments::carryTeleported): a kinematic body that jumped or turned with it (a
    /// character's other parts set where it respawns: Bullet's velocity is the jump over the
    /// sub-step) sweeps only what it moved relative to the carried cloth, not the jump.
    void sweepAfterTeleport(const detail::Pose& motion, double dt);
    std::vector<const btCollisionObject*> inWalk; ///< gatherBodies' scratch, sorted
    /// Adds to the candidates the moving bodies that swept through the box lo..hi in the
    /// sub-step of dt [s] although the broadphase did not pair them with the proxy.
    void addFastBodies(const Vec3& lo, const Vec3& hi, double dt);
    /// The cloth's automatic sub-steps of a world sub-step dt; a refusal says what to change in
    /// the world's stepping.
    int substepsOfWorldStep(double dt) const;
    /// The refusal of a fixed count of cloth steps beyond the drag's limit, in the world's terms.
    Error dragRefusal() const;
    /// addFastBodies' list when no stepper gave one (scratch).
    std::vector<const btRigidBody*> ownMovers;
    double lastStrain = 0.0;     ///< Cloth::maxStrain() at the end of the last sub-step
    bool strainMeasured = false; ///< lastStrain holds a measurement
    /// Follows the world's gravity when the program changes it (that wakes the cloth); a
    /// gravity set on the cloth itself stays until then.
    void followWorldGravity();
    Vec3 worldGravity = Vec3::Zero(); ///< the world's gravity the cloth last followed
    /// Wakes a sleeping cloth when a candidate body is new, gone or moving; records the poses.
    void wakeForBodies(double dt);
    /// After a cloth step of h [s] taken awake: the bodies get the contact forces' and the
    /// attachments' reactions.
    void pushBodies(double h);
    /// Gives the dynamic bodies the impulses accumulated on them.
    void applyImpulses();
    /// The proxy's box: where the particles can get in the next step of dt [s] (nextBounds),
    /// set (updateBounds).
    void nextBounds(double dt, Vec3& lo, Vec3& hi) const;
    void updateBounds(double dt);
    Vec3 nextLo = Vec3::Zero(), nextHi = Vec3::Zero(); ///< advance's nextBounds, for finish
    /// The positions when the cloth was last kept apart from the cloths of its group
    /// (BulletClothSettings::collideWithCloths), kept from one Bullet sub-step to the next
    /// while it stays in a group.
    Vec3List pairStart;
    bool pairStartValid = false; ///< pairStart is from the last Bullet sub-step's group
    /// Where the cloth can get in this Bullet sub-step: its proxy's box and its particles'
    /// sweep at their speeds, grown by the contact reach (gatherBodies).
    Vec3 reachLo = Vec3::Zero(), reachHi = Vec3::Zero();
    /// Detaches the particles whose body is no longer in the world (removed, maybe deleted:
    /// its pointer is only compared, never read) and throws drape::Error naming them.
    void checkAttachmentBodies();
    /// In the world, and the world alive (a world destroyed first cleared the proxy's handle).
    bool live() const { return inWorld && proxy.inLiveWorld(); }
};

// The cloths of one world are stepped by one action, the world's Stepper: every Bullet sub-step
// it prepares each cloth in the order they were added, advances them (in parallel on up to the
// largest BulletClothSettings::threads of its cloths, one task per cloth, in a oneTBB arena of
// that many threads; each cloth's result is the same on any number of threads), and finishes
// them in order. A cloth that throws is left out of the rest of that sub-step; the first error,
// by cloth order, is rethrown after the others finished.
/// The lock of the worlds' steppers (joinStepper, leaveStepper, a stepper's graveyard).
std::mutex& steppersLock();

class BulletCloth::Impl::Stepper final : public btActionInterface,
                                         public std::enable_shared_from_this<Stepper> {
  public:
    std::vector<Impl*> cloths; ///< in the order they were added
    bool inWorld = false;

    /// A handle destroyed while its cloth is listed in a step of this stepper (by a stage of a
    /// cloth, a callback; Impl::steppingIn) leaves the world at once, but its state lives on
    /// here until the step's loops, which still list it, are done with it.
    std::vector<std::unique_ptr<Impl>> graveyard;

    /// While it lives, `list` is being stepped by stepper `s` (updateAction, stepInWorld).
    struct Stepping {
        Stepper& s;
        const std::vector<Impl*>& list;
        Stepping(Stepper& st, const std::vector<Impl*>& l) : s(st), list(l) {
            for (Impl* c : list)
                c->steppingIn = &s;
        }
        ~Stepping() {
            std::vector<std::unique_ptr<Impl>> gone;
            {
                std::lock_guard<std::mutex> guard(steppersLock());
                for (Impl* c : list) // alive, or in the graveyard: not freed yet
                    c->steppingIn = nullptr;
                gone.swap(s.graveyard);
            }
        }
        Stepping(const Stepping&) = delete;
        Stepping& operator=(const Stepping&) = delete;
    };

    void updateAction(btCollisionWorld* collisionWorld, btScalar dt) override {
        // This stepper and the cloths it steps, as the step begins: a handle removed during
        // it (it leaves `cloths`, and may take the last reference to this stepper) is passed
        // over from then on.
        const std::shared_ptr<Stepper> keep = shared_from_this();
        detail::shapesMayHaveChanged(); // (the program's edits before this sub-step)
        const std::vector<Impl*> list = cloths;
        const Stepping during(*this, list);
        const std::size_t n = list.size();
        errors_.assign(n, nullptr);
        // A cloth whose proxy the program took out of the world said so in one step
        // (prepare) and is out of the world since (inWorld() false): not stepped again, so the
        // rest of the world steps on until the program removes the handle.
        skip_.assign(n, 0);
        for (std::size_t k = 0; k < n; ++k)
            skip_[k] = !list[k]->inWorld || list[k]->proxyLost;
        // The world's moving bodies, listed once for all its cloths (addFastBodies).
        if (collisionWorld) listMovers(*collisionWorld, movers_);
        for (std::size_t k = 0; k < n; ++k) {
            if (skip_[k]) continue;
            const std::optional<double>& exact = list[k]->settings.timeStep;
            list[k]->worldMovers =
                collisionWorld && list[k]->world == collisionWorld ? &movers_ : nullptr;
            try {
                list[k]->prepare(exact && btScalar(*exact) == dt ? *exact : double(dt));
            } catch (...) {
                errors_[k] = std::current_exception();
            }
            list[k]->worldMovers = nullptr;
        }
        // Cloths that may meet in this sub-step take their steps together (formGroups); every
        // other cloth is a group of its own.
        formGroups(list, double(dt));
        auto advance = [this, &list](std::size_t g) { advanceGroup(list, g); };
        // The cloths step in parallel on up to the largest BulletClothSettings::threads; the
        // arena also serves the loops of the cloths that ask for threads of their own and have
        // no executor of their program (lendExecutor), so it has the largest of both. No more
        // than the machine has (oneTBB would refuse the extra workers, with a warning).
        int worldThreads = 1, arenaThreads = 1;
        for (const Impl* c : list) {
            worldThreads = std::max(worldThreads, c->settings.threads);
            arenaThreads = std::max(arenaThreads, c->settings.threads);
            if (borrows(*c->cloth))
                arenaThreads = std::max(arenaThreads, c->cloth->settings().threads);
        }
        const int machine = tbb::info::default_concurrency();
        worldThreads = std::min(worldThreads, machine);
        arenaThreads = std::min(arenaThreads, machine);
        if (arenaThreads <= 1) {
            executor_.reset();
        } else if (!executor_ || executor_->concurrency() != arenaThreads) {
            executor_ = std::make_shared<ArenaExecutor>(arenaThreads);
        }
        for (Impl* c : list)
            if (c->inWorld) lendExecutor(*c);
        const std::size_t groups = groupStart_.size() - 1;
        parallelMembers_ = worldThreads > 1;
        if (worldThreads > 1 && (groups > 1 || groups < n)) {
            executor_->arena().execute([&] {
                tbb::parallel_for(tbb::blocked_range<std::size_t>(0, groups, 1),
                                  [&](const tbb::blocked_range<std::size_t>& r) {
                                      for (std::size_t g = r.begin(); g != r.end(); ++g)
                                          advance(g);
                                  });
            });
        } else {
            for (std::size_t g = 0; g < groups; ++g)
                advance(g);
        }
        for (std::size_t k = 0; k < n; ++k) {
            if (errors_[k] || skip_[k] || !list[k]->inWorld) continue;
            try {
                list[k]->finish();
            } catch (...) {
                errors_[k] = std::current_exception();
            }
        }
        for (const std::exception_ptr& e : errors_)
            if (e) std::rethrow_exception(e);
    }
    void debugDraw(btIDebugDraw* drawer) override {
        if (!drawer) return;
        for (const Impl* c : cloths)
            c->draw(drawer);
    }

    /// A cloth that asks for threads of its own and has no executor of its program (a loan of
    /// a world, this one's or a destroyed one's, may be replaced).
    static bool borrows(const Cloth& cloth) {
        return cloth.settings().threads > 1 &&
               (!cloth.hasCallerExecutor() || isWorldLoan(cloth.executor()));
    }
    /// Gives a cloth that borrows the world's executor, so that its loops and the world's
    /// cloths share one set of threads; takes it back when the world has none (any more).
    /// Runs on the world's thread before the cloths step.
    void lendExecutor(Impl& c) const {
        Cloth& borrower = *c.cloth;
        if (borrower.hasCallerExecutor() && !isWorldLoan(borrower.executor())) {
            c.lent.reset(); // the program's own choice
            return;
        }
        const std::shared_ptr<Executor> want =
            borrows(borrower) && executor_ ? std::shared_ptr<Executor>(executor_) : nullptr;
        if (want ? borrower.executor() != want.get() : borrower.hasCallerExecutor())
            borrower.setExecutor(want);
        c.lent = want;
    }

  private:
    /// Whether cloth k of the step takes its steps (prepared, in the world, no error yet).
    bool stepping(const std::vector<Impl*>& list, std::size_t k) const {
        return !errors_[k] && !skip_[k] && list[k]->inWorld;
    }

    /// Puts the cloths that may meet in this sub-step into groups (groupStart_, members_, in
    /// the order they were added): two cloths that collide with each other (collideWithCloths,
    /// filters both ways) whose reach in the sub-step (prepare's box: the proxy's and the
    /// particles' sweep, grown by g dt^2 and the thickness) overlap. Every other cloth is a
    /// group of its own.
    void formGroups(const std::vector<Impl*>& list, double dt) {
        const std::size_t n = list.size();
        root_.resize(n);
        boxLo_.resize(n);
        boxHi_.resize(n);
        // Cloths asleep do not move: while all are, no two meet that did not already rest.
        std::size_t pairing = 0, awake = 0;
        for (std::size_t k = 0; k < n; ++k) {
            root_[k] = k;
            if (stepping(list, k) && list[k]->settings.collideWithCloths) {
                ++pairing;
                awake += !list[k]->cloth->isAsleep();
            }
        }
        if (awake == 0) pairing = 0;
        for (std::size_t k = 0; k < n && pairing >= 2; ++k) {
            if (!stepping(list, k) || !list[k]->settings.collideWithCloths) continue;
            const Impl& c = *list[k];
            const double grow =
                c.cloth->settings().gravity.norm() * dt * dt + c.settings.clothCollision.thickness;
            boxLo_[k] = c.reachLo.array() - grow;
            boxHi_[k] = c.reachHi.array() + grow;
        }
        const auto find = [this](std::size_t k) {
            while (root_[k] != k)
                k = root_[k] = root_[root_[k]];
            return k;
        };
        for (std::size_t i = 0; i < n && pairing >= 2; ++i)
            for (std::size_t j = i + 1; j < n; ++j)
                if (meet(list, i, j) && (boxLo_[i].array() <= boxHi_[j].array()).all() &&
                    (boxLo_[j].array() <= boxHi_[i].array()).all())
                    root_[find(j)] = find(i);
        // Groups by their first cloth, members in order.
        groupOf_.assign(n, n);
        groupStart_.assign(1, 0);
        members_.clear();
        std::vector<std::size_t> count;
        for (std::size_t k = 0; k < n; ++k) {
            const std::size_t r = find(k);
            if (groupOf_[r] == n) {
                groupOf_[r] = count.size();
                count.push_back(0);
            }
            groupOf_[k] = groupOf_[r];
            ++count[groupOf_[k]];
        }
        for (const std::size_t c : count)
            groupStart_.push_back(groupStart_.back() + c);
        members_.resize(n);
        std::vector<std::size_t> fill(groupStart_.begin(), groupStart_.end() - 1);
        for (std::size_t k = 0; k < n; ++k)
            members_[fill[groupOf_[k]]++] = k;
        for (std::size_t k = 0; k < n; ++k)
            if (count[groupOf_[k]] == 1) list[k]->pairStartValid = false;
        // The colliders of the pairs that may meet, kept from the last sub-step (their pair
        // lists) while the two keep meeting.
        std::map<std::pair<const Impl*, const Impl*>, ClothPairCollider> kept;
        for (std::size_t g = 0; g + 1 < groupStart_.size(); ++g)
            for (std::size_t m = groupStart_[g]; m < groupStart_[g + 1]; ++m)
                for (std::size_t o = m + 1; o < groupStart_[g + 1]; ++o) {
                    const std::size_t i = members_[m], j = members_[o];
                    if (!meet(list, i, j)) continue;
                    const std::pair<const Impl*, const Impl*> key(list[i], list[j]);
                    const auto it = colliders_.find(key);
                    if (it != colliders_.end()) {
                        kept.emplace(key, std::move(it->second));
                    } else {
                        kept.emplace(key, ClothPairCollider{});
                    }
                }
        colliders_.swap(kept);
    }

    /// Whether cloths i and j of the step collide with each other: both take their steps and
    /// collide with cloths, and their filters let them meet.
    bool meet(const std::vector<Impl*>& list, std::size_t i, std::size_t j) const {
        if (!stepping(list, i) || !stepping(list, j)) return false;
        const BulletClothSettings& a = list[i]->settings;
        const BulletClothSettings& b = list[j]->settings;
        return a.collideWithCloths && b.collideWithCloths && (a.collisionGroup & b.collisionMask) &&
               (b.collisionGroup & a.collisionMask);
    }

    /// Advances group g: a cloth on its own as BulletCloth::Impl::advance; the cloths of a
    /// larger group take the same number of cloth steps (the most any of them needs), one after
    /// the other, and between them every two that meet and may have come nearer are kept apart
    /// (drape::collideCloths, from their positions when they last were).
    void advanceGroup(const std::vector<Impl*>& list, std::size_t g) {
        const std::size_t first = groupStart_[g], past = groupStart_[g + 1];
        const auto guarded = [&](std::size_t k, auto&& f) {
            if (!stepping(list, k)) return;
            try {
                f(*list[k]);
            } catch (...) {
                errors_[k] = std::current_exception();
            }
        };
        if (past - first == 1) {
            guarded(members_[first], [](Impl& c) { c.advance(); });
            return;
        }
        int steps = 1;
        for (std::size_t m = first; m < past; ++m)
            guarded(members_[m], [&](Impl& c) { steps = std::max(steps, c.stepSubsteps); });
        double h = 0.0; // the cloth step [s]
        for (std::size_t m = first; m < past; ++m)
            guarded(members_[m], [&](Impl& c) {
                c.planSubsteps(steps);
                h = std::max(h, c.stepH);
            });
        std::vector<unsigned char> done(past - first, 0);
        // The pairs of the group that meet and whose reach in the sub-step overlaps (indices
        // into the group), each with its thickness and friction.
        struct Near {
            std::size_t m, o;
            ClothPairSettings both;
        };
        std::vector<Near> pairs;
        for (std::size_t m = first; m < past; ++m)
            for (std::size_t o = m + 1; o < past; ++o) {
                const std::size_t i = members_[m], j = members_[o];
                if (!meet(list, i, j) || (boxLo_[i].array() > boxHi_[j].array()).any() ||
                    (boxLo_[j].array() > boxHi_[i].array()).any())
                    continue;
                const ClothPairSettings& sa = list[i]->settings.clothCollision;
                const ClothPairSettings& sb = list[j]->settings.clothCollision;
                ClothPairSettings both;
                both.thickness = std::max(sa.thickness, sb.thickness);
                both.friction = std::sqrt(sa.friction * sb.friction);
                both.iterations = std::max(sa.iterations, sb.iterations);
                pairs.push_back({m - first, o - first, both});
            }
        // Where each cloth was when the group was last kept apart: from the last Bullet
        // sub-step if it was in a group then, else where it is now.
        for (std::size_t m = first; m < past; ++m)
            guarded(members_[m], [&](Impl& c) {
                if (!c.pairStartValid || c.pairStart.size() != c.cloth->particleCount())
                    c.pairStart = c.cloth->positions();
                c.pairStartValid = true;
            });
        const auto keepApart = [&]() {
            for (const Near& pr : pairs) {
                const std::size_t i = members_[first + pr.m], j = members_[first + pr.o];
                if (done[pr.m] || done[pr.o] || !stepping(list, i) || !stepping(list, j)) continue;
                Impl& a = *list[i];
                Impl& b = *list[j];
                const auto start = std::chrono::steady_clock::now();
                guarded(i, [&](Impl&) {
                    const ClothPairStats st = colliders_.at({&a, &b}).collide(
                        *a.cloth, a.pairStart, *b.cloth, b.pairStart, pr.both, a.stepH);
                    for (Impl* c : {&a, &b}) {
                        c->last.clothContacts += st.contacts;
                        c->last.clothPairTests += st.pairTests;
                        if (!c->cloth->isAsleep()) c->slept = false; // woken
                    }
                });
                a.cloth->timers().add(a.slotPairs, std::chrono::duration<double>(
                                                       std::chrono::steady_clock::now() - start)
                                                       .count());
            }
            for (std::size_t m = first; m < past; ++m)
                guarded(members_[m], [&](Impl& c) { c.pairStart = c.cloth->positions(); });
        };
        double thinnest = std::numeric_limits<double>::infinity();
        for (const Near& pr : pairs)
            thinnest = std::min(thinnest, pr.both.thickness);
        std::vector<double> speed(past - first, 0.0);
        // Between passes the cloths of the group do not touch each other's state: on the
        // world's threads they take their step in parallel (each the same on any count).
        const auto stepOne = [&](std::size_t m) {
            guarded(members_[m], [&](Impl& c) {
                if (done[m - first]) return;
                done[m - first] = !c.advanceOne();
                speed[m - first] = done[m - first] ? 0.0 : fastestParticle(*c.cloth);
            });
        };
        double travel = 0.0, closing = 0.0;
        for (int s = 0; s < steps; ++s) {
            // The pairs are kept apart before the first step (what the last step of the Bullet
            // sub-step before did) and before any step by which their fastest particles may
            // have closed a quarter of their thickness since the last time (the largest sum of
            // two speeds): a cloth at rest on another once per Bullet sub-step, a cloth falling
            // onto it at 2 m/s every other step. Each cloth step's limiter follows the pass, so
            // a frame ends within the strain bound. (Half the thickness let a pile of four
            // sheets jitter awake: 32 ms frames instead of asleep after 3 s.)
            if (s == 0 || travel + closing * h >= 0.25 * thinnest) {
                keepApart();
                travel = 0.0;
            }
            if (parallelMembers_) {
                tbb::parallel_for(tbb::blocked_range<std::size_t>(first, past, 1),
                                  [&](const tbb::blocked_range<std::size_t>& r) {
                                      for (std::size_t m = r.begin(); m != r.end(); ++m)
                                          stepOne(m);
                                  });
            } else {
                for (std::size_t m = first; m < past; ++m)
                    stepOne(m);
            }
            closing = 0.0;
            for (const Near& pr : pairs)
                closing = std::max(closing, speed[pr.m] + speed[pr.o]);
            travel += closing * h;
        }
        for (std::size_t m = first; m < past; ++m)
            guarded(members_[m], [&](Impl& c) {
                if (!done[m - first]) c.advanceEnd();
            });
    }

    /// Per pair of cloths that may meet in this sub-step (formGroups; read by the groups' tasks).
    std::map<std::pair<const Impl*, const Impl*>, ClothPairCollider> colliders_;
    bool parallelMembers_ = false;     ///< a group's cloths step in parallel (the world's threads)
    std::vector<std::size_t> root_;    ///< formGroups' union-find
    std::vector<std::size_t> groupOf_; ///< per cloth of the step: its group
    std::vector<std::size_t> groupStart_; ///< group g: members_[groupStart_[g], ...[g + 1])
    std::vector<std::size_t> members_;    ///< the cloths of the step by group, in order
    std::vector<Vec3> boxLo_, boxHi_;     ///< per cloth: its box grown by its reach in the sub-step
    std::vector<std::exception_ptr> errors_;
    std::vector<const btRigidBody*> movers_; ///< the world's moving bodies this sub-step
    std::vector<unsigned char> skip_; ///< per cloth of the step: not stepped (out of the world)
    std::shared_ptr<ArenaExecutor> executor_; ///< the world's threads (more than one)
};

namespace {
/// The worlds' steppers (a stepper lives while one of its cloths' handles does).
struct Steppers {
    std::mutex lock;
    std::vector<std::pair<const btDynamicsWorld*, std::weak_ptr<BulletCloth::Impl::Stepper>>>
        entries;
};
Steppers& steppers() {
    static Steppers s;
    return s;
}
} // namespace

std::mutex& steppersLock() {
    return steppers().lock;
}

void BulletCloth::Impl::joinStepper() {
    Steppers& all = steppers();
    std::lock_guard<std::mutex> guard(all.lock);
    auto& entries = all.entries;
    entries.erase(std::remove_if(entries.begin(), entries.end(),
                                 [](const auto& e) { return e.second.expired(); }),
                  entries.end());
    for (auto& e : entries) {
        if (e.first != world) continue;
        std::shared_ptr<Stepper> found = e.second.lock();
        // A stepper whose cloths all left, or whose world was destroyed (a new world may
        // have its address), is not reused.
        if (!found->inWorld) continue;
        bool live = false;
        for (const Impl* c : found->cloths)
            live = live || c->proxy.inLiveWorld();
        if (!live) {
            found->inWorld = false;
            continue;
        }
        stepper = std::move(found);
        break;
    }
    if (!stepper) {
        stepper = std::make_shared<Stepper>();
        world->addAction(stepper.get());
        stepper->inWorld = true;
        entries.emplace_back(world, stepper);
    }
    stepper->cloths.push_back(this);
}

void BulletCloth::Impl::leaveStepper(bool worldAlive) {
    if (!stepper) return;
    {
        std::lock_guard<std::mutex> guard(steppers().lock);
        auto& cs = stepper->cloths;
        cs.erase(std::remove(cs.begin(), cs.end(), this), cs.end());
        // A cloth asleep on this one (its proxy's box meeting this one's) would stay in the
        // air: it wakes, as for a body that leaves. (Not from inside a step, where the others
        // may be stepping on other threads; a cloth removed there wakes no one.)
        if (worldAlive && !steppingIn && settings.collideWithCloths)
            for (Impl* other : cs) {
                if (!other->settings.collideWithCloths || !other->cloth->isAsleep()) continue;
                if (((proxy.min().array() <= other->proxy.max().array()).all() &&
                     (other->proxy.min().array() <= proxy.max().array()).all()))
                    other->cloth->wake();
            }
        if (cs.empty() && stepper->inWorld) {
            if (worldAlive) world->removeAction(stepper.get());
            stepper->inWorld = false;
        }
    }
    if (lent && cloth->executor() == lent.get()) {
        // (Not possible inside the cloth's own step, where a stage destroyed its handle: the
        // cloth then keeps the loan, which it holds, until another world or the program
        // replaces it.)
        try {
            cloth->setExecutor(nullptr);
        } catch (const Error&) {
        }
    }
    lent.reset();
    stepper.reset();
}

void BulletCloth::Impl::draw(btIDebugDraw* drawer) const {
    // As Bullet draws a body: only in a wireframe mode.
    if (!drawer || !(drawer->getDebugMode() & btIDebugDraw::DBG_DrawWireframe)) return;
    const Cloth& c = *cloth;
    const btVector3 colour(0.8f, 0.5f, 0.2f);
    for (const auto& s : c.topology().springs()) {
        drawer->drawLine(toBt(c.positions()[s.a]), toBt(c.positions()[s.b]), colour);
    }
}

class BulletCloth::Impl::Stage final : public ClothStage {
  public:
    Stage(detail::ContactSolver& contacts, std::size_t particles)
        : contacts_(contacts), particles_(particles) {}
    std::string name() const override { return "bullet_contacts"; }
    void beforeLimit(Cloth& c, double dt) override { contacts_.detect(c, dt); }
    void run(Cloth& c, double dt) override { contacts_.finish(c, dt); }
    std::vector<unsigned char> saveState() const override { return contacts_.saveState(); }
    void loadState(const std::vector<unsigned char>& bytes) override {
        contacts_.loadState(particles_, bytes);
    }

  private:
    detail::ContactSolver& contacts_;
    std::size_t particles_;
};

void BulletCloth::Impl::step(double dt) {
    prepare(dt);
    advance();
    finish();
}

void BulletCloth::Impl::prepare(double dt) {
    using Clock = std::chrono::steady_clock;
    const auto start = Clock::now();
    Cloth& c = *cloth;
    // (Cloth::step checks them too, but the body snapshots read the positions first.)
    c.checkStateSizes("the cloth's world step");
    // The world steps, so it lives: a proxy out of it was taken out by the program.
    if (!proxy.inLiveWorld()) {
        proxyLost = true;
        throw Error(ErrorCode::InvalidArgument,
                    "the cloth's proxy (BulletCloth::proxyObject()) was removed from its world: "
                    "take a cloth out with removeCloth or BulletCloth::remove(), not "
                    "btCollisionWorld::removeCollisionObject");
    }
    last = ContactStats{};
    outside.clear();
    stepDt = dt;
    if (!attachments.list().empty()) checkAttachmentBodies();
    // 0. kinematic bodies through the frame's sub-steps: the attachment bodies now, the others
    // as the contact stage finds them
    kinematicBefore.swap(kinematicNow);
    kinematicNow.clear();
    for (const Attachment& a : attachments.list())
        followed(a.body, dt);
    attachments.followPoses(&kinematicNow);
    // attached particles the program moved are put on their bodies, and a teleported
    // attachment body carries the cloth (before the bodies are gathered: the proxy's
    // candidates are found where the cloth is then)
    attachments.placeMoved(c);
    const std::optional<detail::Pose> carried =
        attachments.carryTeleported(c, dt, settings.teleportSpeed, settings.teleportTurn);
    if (carried) ++last.teleports;
    // 1. bodies
    gatherBodies(dt, carried.has_value());
    if (carried) sweepAfterTeleport(*carried, dt);
    // 2. attach
    attachments.advance(c, dt);
    followWorldGravity();
    wakeForBodies(dt); // a moving attachment body wakes it through its kinematic path
    // Given: that many; not given: the fewest within the cloth's stability limit (the cloth's
    // own automatic sub-steps, ClothSettings::substeps), taken here so that every cloth step
    // exchanges its impulses with the bodies.
    planSubsteps(settings.substeps ? *settings.substeps : substepsOfWorldStep(dt));
    slept = true;
    for (auto& b : contacts.bodies)
        b.startSweep(dt);
    const bool dynamic = std::any_of(contacts.bodies.begin(), contacts.bodies.end(),
                                     [](const detail::BodySnapshot& b) { return b.dynamicBody; });
    clothSpeed = dynamic ? fastestParticle(c) : 0.0;
    bodySeconds = std::chrono::duration<double>(Clock::now() - start).count();
}

/// A world sub-step longer than this is taken as a frame's hitch given to Bullet's variable
/// step (maxSubSteps 0), not a fixed step a program chose [s].
constexpr double kLongWorldStep = 0.05;

int BulletCloth::Impl::substepsOfWorldStep(double dt) const {
    try {
        return cloth->substepsFor(dt);
    } catch (const Error& e) {
        if (e.code() != ErrorCode::UnstableTimeStep) throw;
        // In the world's terms: its sub-step is what the program gave stepSimulation (a frame
        // of 2 s with maxSubSteps 0, Bullet's variable step; review 18).
        std::ostringstream m;
        m << e.what() << ". In a Bullet world dt is the world's sub-step (" << dt << " s here)";
        // A long sub-step is a frame's hitch given to Bullet's variable step; a short one is the
        // program's fixed step, and the cloth's own count is what to raise (review 19).
        if (dt > kLongWorldStep)
            m << ": step the world with a fixed sub-step (stepSimulation(frameTime, maxSubSteps "
                 ">= 1, fixedTimeStep)), or clamp the frame time a hitch gives it";
        else
            m << ": make the cloth with a larger ClothSettings::substeps.maxSubsteps, or step "
                 "the world with a smaller fixedTimeStep";
        m << "; the world has moved its bodies by this sub-step, the cloth has not";
        throw Error(ErrorCode::UnstableTimeStep, m.str());
    }
}

Error BulletCloth::Impl::dragRefusal() const {
    const Cloth& c = *cloth;
    const double drag = c.aeroTimeStep(stepH);
    std::ostringstream m;
    m << "the cloth's steps of " << stepH << " s (the Bullet sub-step of " << stepDt << " s in "
      << stepSubsteps << " step" << (stepSubsteps == 1 ? "" : "s")
      << ") exceed the stability limit " << drag
      << " s of the explicit aerodynamic drag at the cloth's speed against the air now (up to "
      << c.aeroSpeedBound(stepH)
      << " m/s) with ClothSettings::substeps.automatic off: turn it on (each step is then split "
         "as the speed asks), or set BulletClothSettings::substeps to at least "
      << std::ceil(2.0 * stepDt / drag)
      << " (twice this speed; a count holds only up to a speed), or use a thinner fluid or a "
         "heavier cloth";
    return Error(ErrorCode::UnstableTimeStep, m.str());
}

void BulletCloth::Impl::planSubsteps(int n) {
    const Cloth& c = *cloth;
    stepSubsteps = n;
    stepH = stepDt / n;
    const ClothSettings& cs = c.settings();
    if (!cs.substeps.automatic && cs.rejectUnstableTimeStep && !c.isAsleep()) {
        const double limit = c.stableTimeStep();
        if (stepH > limit) {
            std::ostringstream m;
            m << "the cloth's steps of " << stepH << " s (the Bullet sub-step of " << stepDt
              << " s in " << n << " step" << (n == 1 ? "" : "s")
              << (settings.substeps ? ", BulletClothSettings::substeps" : ", the default")
              << ") exceed its stability limit of " << limit << " s (" << toString(cs.integrator)
              << ", omega_max = " << c.maxAngularFrequency()
              << " rad/s) with ClothSettings::substeps.automatic off: set "
                 "BulletClothSettings::substeps to at least "
              << static_cast<long long>(std::ceil(stepDt / limit)) << " for this sub-step";
            if (std::ceil(stepDt / limit) > cs.substeps.maxSubsteps)
                m << " (more than the cloth's ClothSettings::substeps.maxSubsteps, "
                  << cs.substeps.maxSubsteps
                  << ", which addCloth holds the count to: a cloth's settings are fixed when it "
                     "is made, so make it with a larger maxSubsteps; or a smaller world step, a "
                     "coarser mesh or softer springs)";
            m << ", or turn ClothSettings::substeps.automatic on (the default) and leave "
                 "BulletClothSettings::substeps unset";
            throw Error(ErrorCode::UnstableTimeStep, m.str());
        }
    }
    // A count of the cloth's own choosing (substepsFor of the whole sub-step, or the most of a
    // group's) is within its limit: the cloth splits no further, and the O(particles) bound of
    // its aerodynamics is not asked for again.
    last.substeps = settings.substeps ? n * c.substepsFor(stepH) : n;
}

void BulletCloth::Impl::advance() {
    for (int s = 0; s < stepSubsteps; ++s)
        if (!advanceOne()) return; // removed during the step (by a stage)
    advanceEnd();
}

bool BulletCloth::Impl::advanceOne() {
    using Clock = std::chrono::steady_clock;
    Cloth& c = *cloth;
    // 3. step
    const detail::ScopedFlag guard(contacts.inStep);
    const bool wasAsleep = c.isAsleep();
    // The bodies move through the Bullet sub-step with the cloth (BodySnapshot::advance).
    for (auto& b : contacts.bodies)
        b.advance(stepH);
    // Particles attached to a free body follow it through the sub-step as the cloth moves
    // it (its snapshot: the walk's share, the impulses), not Bullet's pose alone.
    attachments.followBodies(c, contacts.bodies, c.time() + stepH);
    try {
        c.stepPart(stepH, stepSubsteps); // the contact stage runs inside it, the contact
                                         // force is one of its terms
    } catch (const Error& e) {
        // The drag's limit outrun (the cloth checks it at its speed of each step): in the
        // world's terms (review 19: the cloth's own refusal said "2 sub-steps of this step").
        if (e.code() == ErrorCode::UnstableTimeStep && !c.settings().substeps.automatic &&
            stepH > c.aeroTimeStep(stepH))
            throw dragRefusal();
        throw;
    }
    if (!inWorld) return false; // removed during the step (by a stage): nothing more to give
    ++last.steps;
    last.selfPairTests += c.lastSelfCollision().pairTests;
    last.selfContacts += c.lastSelfCollision().contacts;
    if (wasAsleep && c.isAsleep()) return true; // nothing moved, nothing to hand to bodies
    slept = false;
    const auto afterStep = Clock::now();
    pushBodies(stepH);
    bodySeconds += std::chrono::duration<double>(Clock::now() - afterStep).count();
    return true;
}

void BulletCloth::Impl::advanceEnd() {
    using Clock = std::chrono::steady_clock;
    Cloth& c = *cloth;
    const auto afterSteps = Clock::now();
    // The strain the sub-step ends with, measured (one pass over the springs; a cloth that slept
    // through it has not moved), and the proxy's next box (set by finish): both here, in the
    // cloth's own task.
    if (!slept || !strainMeasured) lastStrain = c.maxStrain();
    strainMeasured = true;
    if (!slept) nextBounds(stepDt, nextLo, nextHi);
    bodySeconds += std::chrono::duration<double>(Clock::now() - afterSteps).count();
}

void BulletCloth::Impl::finish() {
    using Clock = std::chrono::steady_clock;
    Cloth& c = *cloth;
    const auto afterSteps = Clock::now();
    last.maxStrain = lastStrain;
    const LimiterSettings& limiter = cloth->settings().limiter;
    if (limiter.kind != LimiterKind::None && lastStrain > limiter.maxStrain + limiterBand(limiter))
        last.boundBroken = 1;
    // 4. impulses
    if (!slept) attachments.holdTethers(c, stepDt, contacts.bodies, world);
    applyImpulses();
    // 5. proxy
    if (!slept) proxy.setBounds(nextLo, nextHi);
    bodySeconds += std::chrono::duration<double>(Clock::now() - afterSteps).count();
    c.timers().add(slotBodies, bodySeconds);
    accumulate(total, last);
}

void BulletCloth::Impl::sweepAfterTeleport(const detail::Pose& motion, double dt) {
    if (!(dt > 0.0)) return;
    const double limit = settings.teleportSpeed;
    for (detail::BodySnapshot& b : contacts.bodies) {
        if (b.dynamicBody || b.plane || b.still) continue; // Bullet's velocity is its own
        // Where Bullet's velocity says it started, carried with the cloth; what is left of
        // its way to where it is now.
        const detail::Pose start = motion * detail::poseBefore(b.end, b.v, b.w, dt);
        const Vec3 v = (b.end.t - start.t) / dt;
        const Eigen::AngleAxisd turn(Eigen::Matrix3d(b.end.R * start.R.transpose()));
        const Vec3 w = turn.angle() / dt * turn.axis();
        // Only a body that took part in the jump or the turn: relative to the carried cloth it
        // moves at most half as fast as Bullet says, and no faster than a teleport.
        btVector3 centre;
        btScalar bound = 0;
        b.object->getCollisionShape()->getBoundingSphere(centre, bound);
        const double radius = double(bound) + double(centre.length());
        const auto fastest = [radius](const Vec3& lin, const Vec3& ang) {
            return lin.norm() + ang.norm() * radius;
        };
        const double relative = fastest(v, w);
        if (!(relative <= 0.5 * fastest(b.v, b.w)) || (limit > 0.0 && !(relative <= limit)))
            continue;
        b.v = v;
        b.w = w;
    }
}

std::optional<detail::Pose> BulletCloth::Impl::followed(const btCollisionObject* obj, double dt) {
    if (detail::isCharacter(obj)) { // where it is; its way from where it was (moveCharacter)
        const detail::Pose at = detail::toPose(obj->getWorldTransform());
        kinematicNow.emplace(obj, at);
        return at;
    }
    const btRigidBody* rb = btRigidBody::upcast(obj);
    if (!rb || !rb->isKinematicObject()) return std::nullopt;
    if (const auto found = kinematicNow.find(obj); found != kinematicNow.end())
        return found->second;
    const detail::Pose to = detail::toPose(obj->getWorldTransform());
    detail::Pose at = to;
    if (const auto was = kinematicBefore.find(obj); was != kinematicBefore.end())
        at = detail::followKinematic(was->second, to, toVec(rb->getLinearVelocity()),
                                     toVec(rb->getAngularVelocity()), dt);
    kinematicNow.emplace(obj, at);
    return at;
}

void BulletCloth::Impl::gatherBodies(double dt, bool carried) {
    std::vector<detail::BodySnapshot>& bodies = contacts.bodies;
    bodies.clear();
    candidates.clear();
    // The proxy's box was set at the end of the previous step for the motion expected then.
    // If the cloth will sweep beyond it in this step (a first step, velocities set by the user,
    // a longer step), move the proxy now and ask the broadphase directly (a tree query, not
    // a loop over bodies) for what the larger box overlaps.
    // A sleeping cloth does not move: its proxy still holds it (and the sweep is O(particles)).
    const double reach = settings.contact.thickness + band;
    Vec3 lo = proxy.min(), hi = proxy.max();
    if (!cloth->isAsleep()) detail::sweptBounds(*cloth, dt, reach, lo, hi);
    if (proxy.candidates(lo, hi, candidates)) ++last.proxyRefreshes;
    reachLo = lo;
    reachHi = hi;
    addFastBodies(lo, hi, dt);
    // Every dynamic body the cloth is attached to is snapshotted, near the cloth or not (a long
    // attachment): its particles move with it and it takes their load in the cloth's steps.
    // (An attachment body that came and went with the proxy's box was one step a carrier, the
    // next handed the load outside: a sheet hanging 0.4 m below a small ball was thrown about.)
    if (!attachments.list().empty())
        for (const btCollisionObject* obj : attachedBodies)
            if (const btRigidBody* rb = btRigidBody::upcast(obj);
                rb && !rb->isStaticOrKinematicObject() &&
                std::find(candidates.begin(), candidates.end(), obj) == candidates.end())
                candidates.push_back(obj);
    for (const btCollisionObject* obj : candidates) {
        if (!obj || obj == proxy.object()) continue;
        detail::BodySnapshot b;
        const std::optional<detail::Pose> at = followed(obj, dt);
        if (detail::snapshotBody(obj, reach, settings.contact.frictionScale, b, dt,
                                 at ? &*at : nullptr)) {
            if (detail::isCharacter(obj))
                if (const auto was = kinematicBefore.find(obj); was != kinematicBefore.end())
                    detail::moveCharacter(b, was->second, dt);
            // A kinematic body set somewhere in one go (not one the cloth hangs from: those
            // carry it, carryTeleported) appears there.
            const bool attachedTo =
                !attachments.list().empty() &&
                std::binary_search(attachedBodies.begin(), attachedBodies.end(), obj);
            if (at && !carried && !attachedTo &&
                detail::holdIfJumped(b, dt, settings.teleportSpeed, settings.teleportTurn, reach))
                ++last.jumpedBodies;
            // The cloth's spacing: the smallest lever its contacts resolve.
            detail::limitSpin(b, contacts.longestSpring(*cloth));
            bodies.push_back(b);
        }
    }
    // Bodies that do not move for the cloth first (static, kinematic), in the broadphase's
    // order, then the dynamic ones: a particle a dynamic body presses into a body that holds it
    // from behind (a cup lying on a cloth on the floor) has that body's plane by the time the
    // dynamic body's contact looks for it (heldBehind), whatever order the broadphase lists
    // them in. With the cup listed first, it pushed the particle into the floor's thickness,
    // out of which the floor then let it only at contact.depenetrationSpeed: particles stayed
    // 1 cm under the floor for seconds (a new user's review).
    std::stable_partition(bodies.begin(), bodies.end(),
                          [](const detail::BodySnapshot& b) { return b.dynamicBody == nullptr; });
    detail::markSupported(*world->getDispatcher(), bodies);
    // (attachedBodies: the attachment bodies, sorted, from checkAttachmentBodies this sub-step.)
    if (!attachments.list().empty()) {
        // A carrier is an attached dynamic body that rests on nothing. In joints of the world
        // (btRigidBody's constraint references are kept only for joints added with their bodies'
        // collisions disabled: the world's list is asked), it gives way only as they let it
        // (BodySnapshot::joints); a joint that gives no rows makes it an attachment body that
        // takes the reaction after the cloth's steps.
        // A joint to another body that moves in the walk (a free body near the cloth, or
        // another carrier) is one the walk cannot keep: those two would be moved apart walk
        // after walk (a cape between a ragdoll's torso and its head pushed them apart with
        // 60 N s on a 5 kg head). Such a body stays an attachment body.
        inWalk.clear();
        for (const auto& b : bodies)
            if (b.dynamicBody && !b.supported && b.invMass > 0.0) inWalk.push_back(b.object);
        std::sort(inWalk.begin(), inWalk.end());
        for (auto& b : bodies) {
            b.attached = std::binary_search(attachedBodies.begin(), attachedBodies.end(), b.object);
            b.joints.clear();
            b.carrier = b.attached && b.dynamicBody && !b.supported && b.invMass > 0.0;
            if (!b.carrier) continue;
            b.carrier = detail::jointRows(*world, *b.dynamicBody, dt, inWalk, b.joints);
            if (!b.carrier) b.joints.clear();
            if (b.joints.empty()) continue;
            CarrierMatrices alone = carrierMatrices(b.invMass, b.invInertia, {}, {});
            constrainToJoints(alone, b.joints);
            b.jointedWeight = alone.share;
        }
    }
    last.candidateBodies = bodies.size();
}

void BulletCloth::Impl::addFastBodies(const Vec3& lo, const Vec3& hi, double dt) {
    // The broadphase pairs a body with the proxy where the body is at the end of the sub-step
    // (a dynamic body's box also covers its start when the world's dispatch info says
    // m_useContinuous, Bullet's default; a kinematic body's never does). A body that crossed
    // the proxy's box between two sub-steps, farther than the proxy's margin, is found here:
    // its box swept back along its velocity meets the proxy's box. Every object is looked at
    // (a flag test for static ones): a kinematic body added as a static one and flagged
    // kinematic afterwards is in no shorter list of Bullet's.
    // The world's stepper lists them once per sub-step for all its cloths (a level of 22,000
    // objects and ten sleeping curtains: ten scans of the world a sub-step; review 18).
    if (!worldMovers) listMovers(*world, ownMovers);
    for (const btRigidBody* rb : worldMovers ? *worldMovers : ownMovers) {
        const btCollisionObject* obj = rb;
        // Every kinematic body is followed through the frame's sub-steps, near the cloth or
        // not yet: one that comes near in a later sub-step is where its way has taken it.
        const std::optional<detail::Pose> at = followed(obj, dt);
        const Vec3 step = dt * toVec(rb->getLinearVelocity());
        if (!(step.norm() > margin)) continue;  // the proxy's margin covers it
        if (!proxy.collidesWith(obj)) continue; // filtered out as the broadphase would
        btVector3 mn, mx;
        detail::shapeAabb(rb->getCollisionShape(),
                          at ? detail::toBtTransform(*at) : rb->getWorldTransform(), mn, mx);
        const Vec3 bodyLo = toVec(mn).cwiseMin(toVec(mn) - step);
        const Vec3 bodyHi = toVec(mx).cwiseMax(toVec(mx) - step);
        if ((bodyHi.array() < lo.array()).any() || (bodyLo.array() > hi.array()).any()) continue;
        if (std::find(candidates.begin(), candidates.end(), obj) == candidates.end())
            candidates.push_back(obj);
    }
}

void BulletCloth::Impl::checkAttachmentBodies() {
    // The attachment bodies, each once, sorted; the world's objects are looked up among them.
    attachedBodies.clear();
    for (const auto& a : attachments.list())
        attachedBodies.push_back(a.body);
    std::sort(attachedBodies.begin(), attachedBodies.end());
    attachedBodies.erase(std::unique(attachedBodies.begin(), attachedBodies.end()),
                         attachedBodies.end());
    const btCollisionObjectArray& objects = world->getCollisionObjectArray();
    // Each body still where the last scan found it: nothing was removed in between (Bullet
    // moves the last object into a removed one's place).
    const auto stillAt = [&objects](const std::pair<const btCollisionObject*, int>& e) {
        return e.second < objects.size() && objects[e.second] == e.first;
    };
    if (attachedAt.size() == attachedBodies.size() &&
        std::equal(attachedBodies.begin(), attachedBodies.end(), attachedAt.begin(),
                   [](const btCollisionObject* o, const auto& e) { return o == e.first; }) &&
        std::all_of(attachedAt.begin(), attachedAt.end(), stillAt))
        return;
    attachedAt.clear();
    bodyFound.assign(attachedBodies.size(), 0);
    std::size_t found = 0;
    for (int k = 0; k < objects.size() && found < attachedBodies.size(); ++k) {
        const auto it = std::lower_bound(attachedBodies.begin(), attachedBodies.end(), objects[k]);
        if (it == attachedBodies.end() || *it != objects[k]) continue;
        unsigned char& seen = bodyFound[std::size_t(it - attachedBodies.begin())];
        found += seen == 0;
        seen = 1;
        attachedAt.emplace_back(objects[k], k);
    }
    std::sort(attachedAt.begin(), attachedAt.end());
    if (found == attachedBodies.size()) return; // every body is still in the world
    attachedAt.clear();
    std::vector<Index> lost;
    for (const auto& a : attachments.list()) {
        const auto it = std::lower_bound(attachedBodies.begin(), attachedBodies.end(), a.body);
        if (!bodyFound[std::size_t(it - attachedBodies.begin())]) lost.push_back(a.particle);
    }
    std::string names;
    for (std::size_t k = 0; k < lost.size(); ++k) {
        attachments.detach(*cloth, lost[k]);
        if (k < 8) names += (k ? ", " : "") + std::to_string(lost[k]);
    }
    if (lost.size() > 8) names += " and " + std::to_string(lost.size() - 8) + " more";
    throw Error(ErrorCode::InvalidArgument,
                "the body particle(s) " + names +
                    " were attached to is no longer in the world (removed or deleted without "
                    "detaching first); they are detached and fall free from the next step. "
                    "Detach particles (BulletCloth::detach) before removing their body");
}

void BulletCloth::Impl::followWorldGravity() {
    if (!settings.useWorldGravity) return;
    const Vec3 g = toVec(world->getGravity());
    if (g == worldGravity) return;
    worldGravity = g;
    cloth->setGravity(g); // wakes the cloth
}

void BulletCloth::Impl::wakeForBodies(double dt) {
    Cloth& c = *cloth;
    // Body motion that wakes the cloth: what would carry a point farther than sleep.distance
    // within the quiet time (a mean speed of distance / time).
    const auto& sl = c.settings().sleep;
    const double tol = sl.distance / std::max(sl.time, dt);
    if (c.isAsleep() &&
        poses.changed(contacts.bodies, tol, dt, c.positions(), contacts.longestSpring(c)))
        c.wake();
    poses.record(contacts.bodies);
}

void BulletCloth::Impl::pushBodies(double h) {
    contacts.applyContactForces(*cloth, h);
    attachments.pushBodies(*cloth, h, contacts.bodies, last, outside);
}

void BulletCloth::Impl::applyImpulses() {
    // The cloth's weight over the Bullet sub-step (what a supported body may carry); the sum
    // over the particles only when a dynamic body is there to take it.
    double weight = -1.0;
    for (auto& b : contacts.bodies) {
        if (b.dynamicBody == nullptr) continue;
        if (weight < 0.0) weight = cloth->totalMass() * cloth->settings().gravity.norm() * stepDt;
        // It carries or pushes an active body: no sleep (see the header).
        if (b.applyAccumulatedImpulses(clothSpeed, settings.unitsPerMetre, weight)) cloth->wake();
        if (b.refused) {
            ++last.refusedBodyImpulses;
            last.impulseOnBodies -= b.linearImpulse;
        }
    }
    for (const auto& o : outside) {
        o.body->applyImpulse(toBt(o.j), toBt(o.at - toVec(o.body->getCenterOfMassPosition())));
        o.body->activate();
    }
    outside.clear();
}

void BulletCloth::Impl::nextBounds(double dt, Vec3& lo, Vec3& hi) const {
    // Where the particles can get in the next step (at the speed they have now), plus the
    // contact reach, plus the margin for bodies moving toward the cloth.
    detail::sweptBounds(*cloth, dt, settings.contact.thickness + band, lo, hi);
    lo.array() -= margin;
    hi.array() += margin;
}

void BulletCloth::Impl::updateBounds(double dt) {
    Vec3 lo, hi;
    nextBounds(dt, lo, hi);
    proxy.setBounds(lo, hi);
}

// --------------------------------------------------------------------------------------------

BulletCloth::BulletCloth(btDynamicsWorld* world, std::shared_ptr<Cloth> cloth,
                         const BulletClothSettings& settings) {
    require(world != nullptr, ErrorCode::InvalidArgument, "addCloth: the Bullet world is null");
    require(cloth != nullptr, ErrorCode::InvalidArgument, "addCloth: the cloth is null");
    detail::validate(settings);
    // The cloth's own bound on the steps one step may take: a step of the world is never more
    // cloth steps than the cloth would take itself (100000 ran for minutes).
    const int maxSubsteps = cloth->settings().substeps.maxSubsteps;
    if (settings.substeps)
        require(*settings.substeps <= maxSubsteps, ErrorCode::InvalidArgument,
                "addCloth: substeps (" + std::to_string(*settings.substeps) +
                    ") is more than the cloth's ClothSettings::substeps.maxSubsteps (" +
                    std::to_string(maxSubsteps) +
                    "); use fewer cloth steps per Bullet sub-step (or leave substeps unset for "
                    "the automatic count), or raise maxSubsteps");
    {
        Registry& r = registry();
        std::lock_guard<std::mutex> guard(r.lock);
        for (const auto& e : r.entries) {
            require(e.first != cloth.get() || !e.second->live(), ErrorCode::InvalidArgument,
                    "addCloth: this cloth is already in a world (a cloth can be in one world "
                    "once; remove its other handle first)");
        }
    }
    const double h = settings.contact.thickness;
    double band = settings.contact.penaltyBand.value_or(h);
    require(band > 0.0 || settings.contact.penaltyForce == 0.0, ErrorCode::InvalidArgument,
            "contact.penaltyBand must be positive when the penalty force is on");
    if (!(band > 0.0)) band = h;
    if (settings.selfCollision.enabled) cloth->setSelfCollision(settings.selfCollision);
    impl_ = std::make_unique<Impl>(world, std::move(cloth), settings, band, this);
    Impl& m = *impl_;
    if (settings.contact.broadphaseMargin) {
        m.margin = *settings.contact.broadphaseMargin;
    } else {
        double sum = 0.0;
        for (const auto& s : m.cloth->topology().springs())
            sum += s.restLength;
        const auto count = double(std::max<std::size_t>(1, m.cloth->topology().springCount()));
        m.margin = sum / count + 4.0 * h;
    }
    if (settings.useWorldGravity) {
        m.worldGravity = toVec(world->getGravity());
        m.cloth->setGravity(m.worldGravity);
    }
    if (settings.sleep && !m.cloth->settings().sleep.enabled) {
        SleepSettings sleep = m.cloth->settings().sleep;
        sleep.enabled = true;
        m.cloth->setSleep(sleep);
    }

    m.contacts.limiterSlot = m.cloth->timers().slot("bullet_contacts/limiter");
    m.contacts.attached = &m.attachments.list();
    m.slotBodies = m.cloth->timers().slot("bullet_bodies");
    m.slotPairs = m.cloth->timers().slot("bullet_cloth_pairs");
    // The cloth's contact force term reads the records the contact stage makes (removed with
    // this handle).
    m.cloth->setContacts(m.contacts.records);
    m.stage = std::make_shared<Impl::Stage>(m.contacts, m.cloth->particleCount());
    m.cloth->addStage(m.stage);

    m.updateBounds(0.0);
    m.proxy.addTo(world, settings.collisionGroup, settings.collisionMask);
    m.joinStepper();
    m.inWorld = true;
    Registry& r = registry();
    std::lock_guard<std::mutex> guard(r.lock);
    auto& entries = r.entries;
    entries.erase(std::remove_if(entries.begin(), entries.end(),
                                 [&](const auto& e) { return e.first == m.cloth.get(); }),
                  entries.end()); // a handle whose world was destroyed
    entries.emplace_back(m.cloth.get(), &m);
}

BulletCloth::~BulletCloth() {
    // Destroyed inside its world's step (by a cloth's stage, say): it leaves the world now,
    // and its stepper keeps its state until the step's loops are done with it.
    Impl::Stepper* const stepping = impl_ ? impl_->steppingIn : nullptr;
    remove();
    if (stepping) {
        std::lock_guard<std::mutex> guard(steppersLock());
        stepping->graveyard.push_back(std::move(impl_));
    }
}

void BulletCloth::remove() {
    Impl& m = *impl_;
    if (!m.inWorld) return;
    if (m.proxy.inLiveWorld() || m.proxyLost) { // (lost: the world stepped without it)
        m.leaveStepper(true);
        m.proxy.removeFromWorld();
    } else {
        m.leaveStepper(false);
        m.proxy.forgetWorld(); // the world was destroyed first: nothing of it to touch
    }
    {
        Registry& r = registry();
        std::lock_guard<std::mutex> guard(r.lock);
        auto& entries = r.entries;
        entries.erase(std::remove_if(entries.begin(), entries.end(),
                                     [&](const auto& e) { return e.second == &m; }),
                      entries.end());
    }
    m.cloth->removeStage(m.stage.get());
    m.cloth->setContacts(nullptr);
    m.contacts.records->contacts.clear();
    m.attachments.clear(*m.cloth);
    m.contacts.bodies.clear();
    m.inWorld = false;
}

bool BulletCloth::inWorld() const {
    return impl_->live();
}

void BulletCloth::attach(Index particle, const btCollisionObject* body, const Vec3& localPoint) {
    Impl& m = *impl_;
    require(m.live(), ErrorCode::InvalidArgument,
            "attach: the cloth has been removed from its world (or the world destroyed)");
    require(particle < m.cloth->particleCount(), ErrorCode::IndexOutOfRange,
            "attach: particle " + std::to_string(particle) + " does not exist (the cloth has " +
                std::to_string(m.cloth->particleCount()) + " particles)");
    require(body != nullptr, ErrorCode::InvalidArgument,
            "attach: the body for particle " + std::to_string(particle) + " is null");
    require(localPoint.allFinite(), ErrorCode::NonFinite,
            "attach: the local point for particle " + std::to_string(particle) + " is not finite");
    const btCollisionObjectArray& objects = m.world->getCollisionObjectArray();
    require(objects.findLinearSearch(const_cast<btCollisionObject*>(body)) < objects.size(),
            ErrorCode::InvalidArgument,
            "attach: the body for particle " + std::to_string(particle) +
                " is not in the cloth's world (add it to the world first)");
    const int type = body->getInternalType();
    require(type == btCollisionObject::CO_RIGID_BODY ||
                type == btCollisionObject::CO_COLLISION_OBJECT,
            ErrorCode::InvalidArgument,
            "attach: the body for particle " + std::to_string(particle) +
                " is not a rigid body or collision object (a ghost object such as a cloth's "
                "proxy, a soft body or a multibody link): particles attach to rigid bodies and "
                "collision objects only");
    m.attachments.attach(*m.cloth, Attachment{particle, body, localPoint});
}

void BulletCloth::attachHere(Index particle, const btCollisionObject* body) {
    require(body != nullptr, ErrorCode::InvalidArgument,
            "attachHere: the body for particle " + std::to_string(particle) + " is null");
    require(particle < impl_->cloth->particleCount(), ErrorCode::IndexOutOfRange,
            "attachHere: particle " + std::to_string(particle) + " does not exist (the cloth has " +
                std::to_string(impl_->cloth->particleCount()) + " particles)");
    const detail::Pose pose = detail::toPose(body->getWorldTransform());
    attach(particle, body, pose.toLocal(impl_->cloth->positions()[particle]));
}

void BulletCloth::detach(Index particle) {
    impl_->attachments.detach(*impl_->cloth, particle);
}

const std::vector<Attachment>& BulletCloth::attachments() const {
    return impl_->attachments.list();
}
Cloth& BulletCloth::cloth() {
    return *impl_->cloth;
}
const Cloth& BulletCloth::cloth() const {
    return *impl_->cloth;
}
const std::shared_ptr<Cloth>& BulletCloth::clothPtr() const {
    return impl_->cloth;
}
const BulletClothSettings& BulletCloth::settings() const {
    return impl_->settings;
}
void BulletCloth::setTimeStep(std::optional<double> dt) {
    BulletClothSettings s = impl_->settings;
    s.timeStep = dt;
    detail::validate(s);
    impl_->settings.timeStep = dt;
}
const btCollisionObject* BulletCloth::proxyObject() const {
    return impl_->proxy.object();
}
const ContactStats& BulletCloth::lastStats() const {
    return impl_->last;
}
const ContactStats& BulletCloth::totalStats() const {
    return impl_->total;
}
void BulletCloth::debugDraw(btIDebugDraw* drawer) const {
    impl_->draw(drawer);
}

void BulletCloth::stepInWorld(double dt) {
    require(std::isfinite(dt) && dt > 0.0, ErrorCode::InvalidArgument,
            "stepInWorld: dt must be positive and finite, got " + num(dt));
    require(impl_->live(), ErrorCode::InvalidArgument,
            "stepInWorld: the cloth has been removed from its world (or the world destroyed)");
    Impl& m = *impl_; // (a stage may destroy this handle: `this` is not used after the step)
    const std::shared_ptr<Impl::Stepper> keep = m.stepper;
    const std::vector<Impl*> list{&m};
    const Impl::Stepper::Stepping during(*keep, list);
    m.step(dt);
}

BulletClothSettings BulletClothSettings::inUnits(double unitsPerMetre) {
    BulletClothSettings s;
    s.unitsPerMetre = unitsPerMetre;
    detail::validateUnitsPerMetre(unitsPerMetre, "BulletClothSettings::inUnits: ");
    s.contact.thickness *= unitsPerMetre;
    s.contact.depenetrationSpeed *= unitsPerMetre;
    s.teleportSpeed *= unitsPerMetre;
    s.selfCollision.thickness *= unitsPerMetre;
    s.clothCollision.thickness *= unitsPerMetre;
    return s;
}

std::unique_ptr<BulletCloth> addCloth(btDynamicsWorld* world, std::shared_ptr<Cloth> cloth,
                                      const BulletClothSettings& settings) {
    return std::make_unique<BulletCloth>(world, std::move(cloth), settings);
}

void removeCloth(BulletCloth& cloth) {
    cloth.remove();
}

} // namespace drape::bullet
