// contacts.hpp (private to drape::bullet): the contact stage, which runs inside every cloth
// step before the strain limiter (detect) and after it and the cloth's own self-collision
// (finish): particle-body contacts
// (contacts.cpp: the pass over bodies and particles, culled by particle_boxes.hpp, the re-limiting;
// particle_contacts.cpp: one particle against one body, with its friction), triangle-body
// contacts (triangle_contacts.cpp), and the reaction of the contact force term on the bodies.
//
// Contact of particle i (inverse mass w_i, mass m_i) with a body at surface point P, outward
// normal n, signed distance d, thickness h, penalty band w:
//   d < h      (touching):  x_i is projected to P + h n; if the relative normal velocity
//              v_n = (v_i - v_body(P)) . n is negative, an impulse lambda n with
//              lambda = -v_n / (w_i + w_body(n)) stops the approach (inelastic: cloth does not
//              bounce), w_body(n) = 1/M + (r x n)^T I^-1 (r x n) for dynamic bodies and 0 for
//              static and kinematic ones, with a Coulomb impulse of at most mu lambda against
//              the tangential slip.
//   d < h (1 + 1e-6) or, with eq. (7) on, d < h + w: a contact record, which the contact
//              force term (drape/contacts.hpp, addContactForces) turns into a normal force N and a
//              friction force T in f(t + dt): N holds the particle (it cancels what presses it
//              in and stops its normal motion within the step, and never more: nothing is
//              launched, nothing bounces), bounded by eq. (7) in the band; T stops the slip
//              within the step while |T| <= mu N (static friction: no creep at any dt), else is
//              mu N against it (kinetic). A resting particle's state then stays exactly as it
//              is, and its end-of-step velocity is zero.
//   Each normal force gets its friction once: lambda and the limiter planes' pushes (below)
//              as impulses in the stage, N as T in the force term. The Coulomb impulse of
//              every impulse of the stage is one function (coulombImpulse).
// Dynamic bodies get the opposite of every impulse and of every contact force times the step
// at P; their snapshot velocities are updated contact by contact (sequential impulses), so
// many particles hitting a light body do not each see it at rest. Against them the force term
// has no terms in the velocity (they would feed back into a light body): N is eq. (7) plus the
// inward part of f, T cancels the tangential force up to mu N, and the rest of the cone is an
// impulse in the next stage (see addContactForces).
//
// Triangles (contact.triangles, off by default): each cloth triangle near a convex or compound
// body is kept h away from it too (collideTriangle: GJK/EPA, the depth and the approach
// impulse shared by barycentric weights), so a feature thinner than the particle spacing
// cannot pass between particles.
//
// Fast particles and fast bodies: a particle that moved more than h in a step relative to the
// body (its path from where it started, seen from where the body was then, to where it is now,
// seen from where the body is now) is also ray-tested along that path
// (btCollisionWorld::rayTestSingle; a box that does not move exactly, drape::segmentEntersBox),
// so neither passes through the other. A convex body that
// moved more than h in the step, or is thinner across than the longest spring, is also swept
// against the triangles on its way (sweepBodies, shape_queries.hpp's sweepToTriangle): a
// triangle it reached is moved ahead of it as a triangle contact (pushTriangle), so that it
// does not pass between the particles. A spring whose ends have planes of one thin body on
// opposite sides, which the strain bound cannot both hold (the body wedged between them),
// passes the body on the side the normals share (straddledSprings).
// A particle lying on the limiter plane of a static or kinematic body (a rug on the floor)
// that a dynamic body presses into it (a crate landing on the rug) is held: it is not moved
// out of the dynamic body (that would move it into the other one), the dynamic body's
// approach is stopped there as on the body behind (all such contacts of a pass together,
// solveHeld), and the body is moved back out to the thickness.
// A dynamic body takes a plane's push only up to what stops its approach (flushPlane).
// Every particle within reach of a static or kinematic body keeps that contact's tangent plane
// in the limiter's one walk of the step, which runs after detect (ContactSet::planes: the
// limiter slides it along the plane, so the strain bound and the contact hold together; the
// plane's push reaches the body as an impulse, flushPlane). What the walk moved is projected
// again in finish (curved bodies, other bodies, dynamic bodies, which get no plane); where
// that moves particles, the walk runs again from them (Cloth::relimit), until nothing moves or
// kRelimitPasses rounds have run.
#pragma once

#include "body_snapshot.hpp"
#include "particle_boxes.hpp"
#include "shape_queries.hpp"

#include "drape/bullet/settings.hpp"
#include "drape/cloth.hpp"
#include "drape/contacts.hpp"
#include "drape/strain_limit.hpp"

#include <algorithm>
#include <cstdint>
#include <limits>
#include <memory>
#include <utility>
#include <vector>

namespace drape::bullet::detail {

/// Sets a flag while it lives (ContactSolver::inStep, the re-projection pass).
struct ScopedFlag {
    bool& flag;
    explicit ScopedFlag(bool& f) : flag(f) { flag = true; }
    ~ScopedFlag() { flag = false; }
    ScopedFlag(const ScopedFlag&) = delete;
    ScopedFlag& operator=(const ScopedFlag&) = delete;
};

/// Follow-up walks and re-projections after the limiter's walk, at most.
constexpr int kRelimitPasses = 8;
/// A projection shorter than this share of the thickness is rounding, not a move: the
/// particle stays where it is (nothing for the limiter to walk again from).
constexpr double kNoMove = 1e-9;
/// Whether a contact moved a particle from `before` to `after` by more than rounding (kNoMove
/// of the thickness h).
inline bool movedBy(const Vec3& before, const Vec3& after, double h) {
    const double least = kNoMove * h;
    return (after - before).squaredNorm() > least * least;
}
/// A triangle contact whose point lies within this share of its fixed corners (barycentric
/// weight of the free ones below it) moves nothing: the fixed corners hold it.
constexpr double kFreeShare = 0.25;
/// Extra sweeps over the triangles in contact after a triangle pass.
constexpr int kTriangleSweeps = 4;
/// Sequential-impulse iterations over the held contacts of a pass (solveHeld).
constexpr int kHeldIterations = 8;
/// A particle this share of the thickness or less above the limiter plane of a static or
/// kinematic body lies on it, held (heldBehind); one higher, in eq. (7)'s band, can still give.
constexpr double kHeldGap = 0.01;

/// Coulomb friction of a normal impulse against body b at p (drape::coulombImpulse), particle
/// and triangle contacts alike.
inline bool coulombImpulse(const Vec3& rel, const Vec3& normal, double w, const BodySnapshot& b,
                           const Vec3& p, double budget, Vec3& j) {
    return drape::coulombImpulse(
        rel, normal, w, [&](const Vec3& d) { return b.inverseMassAlong(p, d); }, budget, j);
}

class ContactSolver {
  public:
    /// `band` is eq. (7)'s band width [m].
    ContactSolver(const BulletClothSettings& settings, double band);

    /// The contact stage, before the cloth's strain limiter (ClothStage::beforeLimit):
    /// particle-body contacts (projection, velocity response, friction, contact records) and
    /// each contact's tangent plane in the ContactSet, which the limiter's walk keeps.
    void detect(Cloth& c, double dt);
    /// After the limiter (ClothStage::run): what its walk moved is projected again (curved
    /// bodies, bodies without a plane), and what the planes pushed goes to the bodies.
    void finish(Cloth& c, double dt);
    /// The contact force (normal and friction) the particles got at the end of a cloth step
    /// of h [s] acts for h: dynamic bodies get the opposite, and what the friction cone left
    /// becomes next step's frictionLeft.
    void applyContactForces(const Cloth& c, double h);
    /// What the stage carries from one step to the next (the friction left per particle), as
    /// bytes for the cloth's snapshot, and back (empty: none). loadState throws drape::Error
    /// on bytes that are not n finite, non-negative values for the cloth's n particles.
    std::vector<unsigned char> saveState() const;
    void loadState(std::size_t particles, const std::vector<unsigned char>& bytes);
    /// The cloth's longest spring rest length [m], its spacing (found once: the topology never
    /// changes).
    double longestSpring(const Cloth& c) {
        if (maxRest_ < 0.0)
            for (const Spring& sp : c.topology().springs())
                maxRest_ = std::max(maxRest_, sp.restLength);
        return maxRest_;
    }

    /// The bodies of this Bullet sub-step (snapshotted by the handle), whose accumulated
    /// impulses the handle applies after the cloth's steps.
    std::vector<BodySnapshot> bodies;
    /// The work counts of the current Bullet sub-step (the handle's lastStats: the stage does
    /// most of the counting, the handle and the attachments add theirs).
    ContactStats stats;
    /// The contact records: the cloth's contact force term reads them (Cloth::setContacts).
    std::shared_ptr<ContactSet> records;
    /// The cloth's attachments (the handle's): a carrier body (BodySnapshot::carrier) carries
    /// its attached particles in the walk (ContactPlanes::carry).
    const std::vector<Attachment>* attached = nullptr;
    /// Inside a Bullet sub-step: the bodies are a fresh snapshot. Outside (the cloth stepped
    /// on its own) the stage collides with nothing.
    bool inStep = false;
    /// Timer slot in the cloth's PhaseTimers of the limiter calls inside the stage (nested in
    /// its "bullet_contacts" phase).
    std::size_t limiterSlot = 0;

  private:
    /// The positions the step started from (Cloth::stepStartPositions), set by run(): each
    /// particle is swept from here. Nothing of it outlives the step.
    const Vec3List* from_ = nullptr;
    const Vec3List& stepStart() const { return *from_; }
    using Block = ParticleBoxes::Block;
    static constexpr std::size_t kBlock = ParticleBoxes::kBlock;
    /// Moved particles of one block, moved[begin, end), for the re-projection.
    struct MovedGroup {
        std::size_t begin = 0, end = 0;
        Block box;
    };

    // --- the pass (contacts.cpp) ---------------------------------------------------------
    /// Every particle against every body whose box its block's box meets.
    void collideParticles(Cloth& c, double dt, QueryCounters& counters);
    /// The particles the limiter moved (`moved`), against every body again.
    void collideMoved(Cloth& c, double dt, const std::vector<Index>& moved,
                      QueryCounters& counters);

    // --- one particle (particle_contacts.cpp) ----------------------------------------------
    /// Contact of particle i with body bi (projection, velocity response, friction, and its
    /// contact record). Returns whether it is within the contact reach.
    bool collideParticle(Cloth& c, std::uint32_t bi, std::size_t i, double dt,
                         QueryCounters& counters);
    /// The limiter plane of a static or kinematic body that particle i lies on (at most
    /// kHeldGap thicknesses above it), or -1.
    std::int64_t heldBehind(const Vec3List& x, std::size_t i) const;
    /// Whether particle i is held from behind (heldBehind) against a push along n: the plane
    /// holding it faces the push. A dynamic body's push of a spring or triangle with such a
    /// corner (a crate on a rug on the floor, a cup on a cloth on the floor) moves nothing.
    bool heldAgainst(const Vec3List& x, std::size_t i, const Vec3& n) const {
        const std::int64_t k = heldBehind(x, i);
        return k >= 0 && records->planes.normal[std::size_t(k)].dot(n) < 0.0;
    }
    /// A dynamic body pressing a particle into a static or kinematic body that holds it
    /// (heldBehind): the body's approach to the one behind, at the contact, is stopped as if
    /// it touched it; the particle is not moved (moved out of the body it would be moved into
    /// the one behind, and the projection back would launch it).
    struct HeldContact {
        std::uint32_t body = 0;
        std::size_t particle = 0;
        Vec3 point = Vec3::Zero();          ///< on the dynamic body's surface [m]
        Vec3 normal = Vec3::UnitY();        ///< the dynamic body's outward normal there
        Vec3 behindVelocity = Vec3::Zero(); ///< of the body behind, at the particle [m/s]
        double give = 0.0;                  ///< the body's inverse mass along normal [1/kg]
        double depth = 0.0;  ///< how far inside the thickness the body came, at most h [m]
        double lambda = 0.0; ///< accumulated normal impulse [N s]
    };
    std::vector<HeldContact> held_;
    std::vector<const HeldContact*> deepestHeld_; ///< per body, in solveHeld
    /// The held contacts of the last pass over particles, solved together (solveHeld).
    void solveHeld(Cloth& c);
    /// Where the particle's path since the last step entered body b (a ray test, for fast
    /// particles): false if it did not.
    bool pathHit(const BodySnapshot& b, const Vec3& from, const Vec3& xi, SurfaceHit& hit);
    /// The contact record the force term reads, one per particle and body (a second visit,
    /// after re-limiting, updates it).
    void recordContact(const Cloth& c, std::uint32_t bi, std::size_t i, const SurfaceHit& hit,
                       double cp, double damping);
    /// Gives particle i the limiter plane n . x >= offset of its contact with body bi at
    /// `point` (a plane of another body it had first gives that body what it held).
    void keepPlane(Cloth& c, std::uint32_t bi, std::size_t i, const Vec3& n, double offset,
                   const Vec3& point, bool fromTriangle, double dt);
    /// Gives the body of contact plane k the opposite of what the plane pushed its particle
    /// by in the limiter's walk (m push / dt), with the Coulomb friction that normal impulse
    /// allows, and clears the push.
    void flushPlane(Cloth& c, std::size_t k, double dt);
    /// What the pins behind the particle of mover plane k pushed its body with in the walk
    /// (ContactPlanes::held) reaches the body as an impulse, at most what stops its approach
    /// to the particle (inelastic: the walk moved the body out by all of it, and a net holding
    /// a body does not throw it back).
    void flushHeld(std::size_t k, double dt);
    /// Springs whose two ends have planes of one body on opposite sides that the bound cannot
    /// both hold (a body thinner than the gap with the thickness around it): both ends get
    /// the plane on the side the two normals share.
    void straddledSprings(Cloth& c, double dt);
    /// After a limiter walk: the bodies that gave way in it (ContactPlanes::Mover) take the
    /// impulses of their planes and move where the walk pushed them.
    void settleMovers(Cloth& c, double dt);
    /// Coulomb friction of a normal impulse on particle i (coulombImpulse); the body gets the
    /// opposite.
    void frictionImpulse(Cloth& c, std::size_t i, BodySnapshot& b, const Vec3& p,
                         const Vec3& normal, double budget);
    /// The cloth gets impulse j at p, body b the opposite (if dynamic); both are counted.
    void exchange(BodySnapshot& b, const Vec3& j, const Vec3& p) {
        b.applyImpulse(-j, p);
        stats.impulseOnCloth += j;
        if (b.dynamicBody) stats.impulseOnBodies -= j;
    }

    // --- triangles (triangle_contacts.cpp) -------------------------------------------------
    /// Triangle-body contacts (contact.triangles): every triangle whose box overlaps the
    /// (reach-grown) box of a convex or compound body.
    void collideTriangles(Cloth& c, double dt, QueryCounters& counters);
    /// Contact of triangle t with body bi; returns the depth it moved the triangle out by
    /// [m], or -1 without contact.
    double collideTriangle(Cloth& c, std::uint32_t bi, std::size_t t, double dt,
                           QueryCounters& counters);

    /// Moves triangle `tri` out of body bi by `depth` [m] along n at its point of barycentric
    /// weights `beta` (body's surface point `point`), stops its approach with Coulomb
    /// friction, two-way, and gives its particles limiter planes (`swept`: after a body's
    /// sweep, sweepBodies). False if its particles are all fixed there.
    bool pushTriangle(Cloth& c, std::uint32_t bi, const Triangle& tri, const Vec3& n,
                      const Vec3& point, const Vec3& beta, double depth, bool swept, double dt);
    /// Bodies faster than the thickness per cloth step against the triangles in their way
    /// (contact.continuous): a triangle the body's path reached (sweepToTriangle) is moved
    /// ahead of it, so that no body passes between particles (a thin rod, a small ball).
    void sweepBodies(Cloth& c, double dt, QueryCounters& counters);

    // --- springs against boxes (edge_contacts.cpp) -----------------------------------------
    /// Springs with an end touching a box, kept the thickness away from it along their length
    /// (contact.boxEdges).
    void collideEdges(Cloth& c);
    /// Spring si against box bi: moved out at its deepest point if nearer than the thickness.
    void collideSpringWithBox(Cloth& c, std::size_t si, std::uint32_t bi);
    /// After the walk: the springs the detection moved off the edge of a static or kinematic
    /// box stop approaching it (inelastic; a kinematic box takes the opposite impulse as every
    /// body does). The edge push has no plane in the walk, so the walk pulls such a spring back
    /// towards the edge, and its corrections become velocity: the next step carried the spring
    /// into the edge again, to be pushed out again. A cloth draped over a box on the floor did
    /// that at the box's edges in every cloth step for as long as it ran, moved more than the
    /// sleep distance, and never fell asleep (3.9 ms a 60 Hz frame, forever).
    void stopEdgeApproach(Cloth& c);
    /// The point at t along spring si stops approaching body b along n at `point` (its ends
    /// share the impulse by their weights), with Coulomb friction if `friction`.
    void stopApproach(Cloth& c, std::size_t si, BodySnapshot& b, double t, const Vec3& n,
                      const Vec3& point, bool friction);

    // Copies of the handle's settings (they never change), read in the per-particle loops.
    const ContactSettings contact_;
    const double band_;
    /// The cloth's free mass this step [kg]: a dynamic body gets limiter planes when it is at
    /// least this heavy along the contact normal.
    double clothMass_ = 0.0;
    /// The cloth's weight over a step, as a move of unit mass: |g| M dt^2 [kg m]. A plane
    /// that carries all of it pushes its particle (mass m) by weightPush_ / m in a walk; a
    /// push beyond that and beyond the longest spring is a fight (pushLimit).
    double weightPush_ = 0.0;

    /// State carried to the next step (in the cloth's snapshots: saveState): per particle, the
    /// friction its contact forces with dynamic bodies had left in the last step, mu N - |T|
    /// [N] (see addContactForces); the next stage gives it as an impulse.
    std::vector<double> frictionLeft_;
    /// Per particle: whether it was on a slow exit from a body (contact.depenetrationSpeed) in
    /// the last cloth step (exitLast_) and in this one (exitNow_). Its exit goes on at that
    /// speed until it is at the thickness: moved the rest of the way at once, from inside the
    /// thickness, it dragged its neighbours up to a thickness in one sub-step through the walk
    /// (a static box moved 4 cm up under a resting cloth threw it 2 m high at 10-16 m/s).
    std::vector<unsigned char> exitLast_, exitNow_;
    bool exiting(Index i) const { return i < exitNow_.size() && exitNow_[i] != 0; }
    // Scratch of the stage, reused every step.
    std::vector<unsigned char> touching_; ///< particle touched a body this step
    /// Triangle pushes take back the slide along the body (Coulomb friction on the push) in the
    /// pass before the limiter's walk only: after it, the walk's moves along the body are its
    /// spring corrections, and taking them back stretched springs past the bound (a rod swept
    /// through a curtain: 0.102).
    bool pushFriction_ = false;
    bool anyTouching_ = false;           ///< some particle did (detect)
    std::vector<std::int64_t> recordOf_; ///< per particle: its latest ContactRecord, or -1
    std::vector<Index> projected_;       ///< particles the last contact pass moved
    /// The tangent plane of each particle's contact this step (n . x >= n . P + h), which the
    /// limiter's walk keeps, with the body and the point it belongs to.
    std::vector<std::uint32_t> planeBody_;
    /// Per body: its ContactPlanes::Mover this step (a free dynamic body), or -1.
    std::vector<std::int32_t> moverOf_;
    /// Per body: the ContactPlanes::Mover that carries its attached particles (a carrier), or
    /// -1. Its planes do not give way with it: pressed on particles whose neighbours hang from
    /// it (a bar landing on the curtain it carries), it would push itself, walk after walk.
    std::vector<std::int32_t> carrierOf_;
    std::vector<Index> carried_;        ///< detect's scratch: a carrier's particles,
    std::vector<Vec3> carriedLevers_;   ///< their levers
    std::vector<double> carriedMasses_; ///< and masses
    /// Per body: thinner across than the longest spring, so that it fits between two
    /// particles (detect): swept against the triangles at any speed (sweepBodies), and the
    /// springs across it pass it on one side (straddledSprings).
    std::vector<unsigned char> thin_;
    std::vector<unsigned char> small_;
    std::vector<Vec3> planePoint_;
    /// Per triangle plane (ContactPlanes::triangles): its body and the body's point.
    std::vector<std::uint32_t> triangleBody_;
    std::vector<Vec3> trianglePoint_;
    /// What triangle plane t pushed goes to its body (the triangle got push / dt).
    void flushTriangle(std::size_t t, double dt);
    /// Body bi's contacts with triangles are triangle planes in the walk
    /// (ContactPlanes::TrianglePlane): a small body (small_) that does not stay put (static,
    /// kinematic, or a mover).
    bool keepsTrianglePlanes(std::uint32_t bi) const;
    /// Gives the walk the plane of triangle `tri`'s point `beta` ahead of body bi's tangent
    /// plane (normal n, through its surface point `point`) by the thickness.
    void addTrianglePlane(std::uint32_t bi, const Triangle& tri, const Vec3& beta, const Vec3& n,
                          const Vec3& point);
    /// Per particle: its contact plane this step comes from a triangle contact (a particle
    /// contact's plane replaces it; a later triangle contact may update it). Sized only when
    /// contact.triangles is on.
    std::vector<unsigned char> trianglePlane_;
    std::vector<std::pair<std::uint32_t, std::size_t>>
        triangleHits_;    ///< (body, triangle) that touched
    ParticleBoxes boxes_; ///< the cheap tests before a particle's contact query
    std::vector<Block> blocks_;
    std::vector<std::size_t> moved_;
    std::vector<Index> everyParticle_; ///< the free particles (after a comparison limiter)
    /// eq. (7)'s C_p and normal damping for the last particle mass and step seen (a cloth's
    /// particles mostly share one mass: limitPenalty's roots and divisions once per step).
    struct Penalty {
        double mass = -1.0, dt = -1.0, gravity = -1.0, cp = 0.0, damping = 0.0;
    } penalty_;
    std::vector<MovedGroup> movedGroups_;
    /// The springs collideEdges moved off a static or kinematic box this cloth step: the
    /// spring, the box, where along the spring (the second end's weight), and the box's
    /// outward normal and surface point there (stopEdgeApproach).
    struct EdgeHit {
        std::size_t spring = 0;
        std::uint32_t body = 0;
        double t = 0.0;
        Vec3 normal = Vec3::Zero(), point = Vec3::Zero();
    };
    std::vector<EdgeHit> edgeHits_;
    std::vector<std::int32_t> edgeBody_; ///< per particle: the box of its contact, or -1
    std::vector<int> edgeRegion_;        ///< per particle: its region around that box
    std::vector<Block> edgeBlocks_;      ///< per block of particles: their positions' box
    /// Per particle near a box: its place in the box's frame, signed distance and gradient,
    /// valid while edgeCached_ is set (collideSpringWithBox; cleared when a spring moves it).
    std::vector<unsigned char> edgeCached_;
    std::vector<Vec3> edgeLocal_, edgeGradient_;
    std::vector<double> edgeDistance_;
    /// Per spring: a box that does not move it was last found clear of, by `room` beyond the
    /// thickness, its ends at a and b then. The box's signed distance is 1-Lipschitz, so while
    /// the box keeps its pose and neither end has moved `room` since, no point of the spring
    /// can have come within the thickness: the spring is not tested against it again (a cloth
    /// lying on a desk tests only the springs that move).
    struct EdgeClearance {
        /// The box and its pose: versions are never reused (boxVersion_), 0 for none.
        std::uint64_t version = 0;
        Vec3 a = Vec3::Zero(), b = Vec3::Zero();
        double room = 0.0;
    };
    std::vector<EdgeClearance> edgeClear_;
    /// The boxes that do not move (static, or kinematic at rest), as collideEdges last saw
    /// them; a box's version changes whenever its pose or size does.
    struct StillBox {
        const btCollisionObject* body = nullptr;
        Pose pose;
        Vec3 half = Vec3::Zero();
        std::uint64_t version = 0;
    };
    std::vector<StillBox> stillBoxes_, stillBoxesNext_;
    std::vector<std::uint64_t> boxVersion_; ///< per body this pass: its version, 0 if it moves
    std::uint64_t lastBoxVersion_ = 0;
    /// In collideMoved: what the limiter moved is projected again (a particle coming out of a
    /// body slowly, collideParticle, is left where the limiter put it).
    bool reprojecting_ = false;
    double maxRest_ = -1.0;   ///< the longest spring's rest length (once) [m]
    double totalMass_ = -1.0; ///< the cloth's mass (once: masses never change) [kg]
    double totalMass(const Cloth& c) {
        if (totalMass_ < 0.0) totalMass_ = c.totalMass();
        return totalMass_;
    }
};

// Defined here, inline: they run per contact in the stage's loops.

inline void ContactSolver::keepPlane(Cloth& c, std::uint32_t bi, std::size_t i, const Vec3& n,
                                     double offset, const Vec3& point, bool fromTriangle,
                                     double dt) {
    if (const std::int32_t was = records->planes.of[i];
        was >= 0 && planeBody_[std::size_t(was)] != bi)
        flushPlane(c, std::size_t(was), dt);
    const auto plane = std::size_t(records->planes.set(static_cast<Index>(i), n, offset));
    // A body that does not give way and is not free lets the plane go in a fight.
    if (const BodySnapshot& b = bodies[bi]; !b.dynamicBody || b.attached)
        records->planes.pushLimit[plane] = std::max(longestSpring(c), weightPush_ / c.masses()[i]);
    if (const std::int32_t m = moverOf_[bi]; m >= 0)
        records->planes.moveWith(plane, m, point - bodies[bi].com);
    if (!trianglePlane_.empty()) trianglePlane_[i] = fromTriangle ? 1 : 0;
    if (plane == planeBody_.size()) {
        planeBody_.push_back(bi);
        planePoint_.push_back(point);
    } else {
        planeBody_[plane] = bi;
        planePoint_[plane] = point;
    }
}

inline void ContactSolver::flushPlane(Cloth& c, std::size_t k, double dt) {
    if (records->planes.mover[k] >= 0) flushHeld(k, dt);
    Vec3 push = records->planes.push[k];
    if (push == Vec3::Zero()) return;
    // A plane the walk let go of (ContactPlanes::pushLimit) pushed one move past the limit:
    // what it exchanges is cut to it.
    if (const double most = records->planes.pushLimit[k]; push.squaredNorm() > most * most)
        push *= most / push.norm();
    const std::size_t i = records->planes.particle(k);
    const Vec3 j = (c.masses()[i] / dt) * push;
    BodySnapshot& b = bodies[planeBody_[k]];
    const Vec3& n = records->planes.normal[k];
    const Vec3& p = planePoint_[k];
    records->planes.push[k] = Vec3::Zero();
    if (records->planes.mover[k] >= 0) {
        // A body that gave way in the walk took its share there, along n: the same impulse,
        // opposite. No friction from it: the particle's velocity then holds the walk's spring
        // corrections along the surface (internal to the cloth), and a friction impulse
        // against them spun thin rods up without bound (measured: 5 mm capsules at 30 m/s
        // reached 2.6e5 rad/s). The contact's own friction acts where it is found.
        exchange(b, j, p);
        return;
    }
    if (!b.dynamicBody) {
        exchange(b, j, p);
        frictionImpulse(c, i, b, p, n, b.friction * j.norm());
        return;
    }
    // A dynamic body takes what the plane held only up to what stops its approach to the
    // particle (an inelastic exchange, at the particle's velocity without the push): never
    // more, so the limiter cannot throw a body back (a net holding a ball stops it, and the
    // ball does not take the net's whole pull on a particle it pushed). The particle keeps its
    // position and gets the impulse that was exchanged instead of m push / dt.
    Vec3& vi = c.mutableVelocities()[i];
    const Vec3 without = vi - push / dt;
    const double wi = c.inverseMasses()[i];
    const double approach = (b.velocityAt(p) - without).dot(n);
    const double lambda = std::min(std::max(0.0, j.dot(n)),
                                   std::max(0.0, approach) / (wi + b.inverseMassAlong(p, n)));
    vi = without + (wi * lambda) * n;
    exchange(b, lambda * n, p);
    frictionImpulse(c, i, b, p, n, b.friction * lambda);
}

inline void ContactSolver::flushHeld(std::size_t k, double dt) {
    Vec3& held = records->planes.held[k];
    if (held == Vec3::Zero()) return;
    const Vec3& n = records->planes.normal[k];
    const Vec3& p = planePoint_[k];
    BodySnapshot& b = bodies[planeBody_[k]];
    // The pins do not move: the body's approach is its own velocity into the particle.
    const double approach = b.velocityAt(p).dot(n);
    const double give = b.inverseMassAlong(p, n);
    const double lambda =
        give > 0.0 ? std::min(held.norm() / dt, std::max(0.0, approach) / give) : 0.0;
    held = Vec3::Zero();
    exchange(b, lambda * n, p);
}

} // namespace drape::bullet::detail
