// BulletCloth: a drape::Cloth stepped by a Bullet dynamics world (see bullet_cloth.hpp).
//
// One Bullet sub-step (btDiscreteDynamicsWorld::internalSingleStepSimulation) runs: rigid
// bodies predicted, broadphase and narrow-phase, constraints solved, transforms integrated,
// then the actions -- our updateAction. So when the cloth steps, the bodies are already at the
// end of the sub-step, and the cloth ends the sub-step at the same instant. The impulses the
// cloth gives dynamic bodies change their velocities for the next sub-step (the same one-step
// lag as every Bullet action, e.g. the character controller and the raycast vehicle).
//
// Per sub-step:
//   1. bodies:  the ghost's broadphase overlaps, filtered (no ghosts, soft bodies, triggers),
//               snapshotted in double precision (pose, velocities, inverse mass and inertia);
//   2. attach:  attached particles get the body's new attachment point as a kinematic target;
//   3. step:    cloth.step(dt / substeps), `substeps` times; our ContactStage runs inside it
//               after strain limiting (self-collision, then particle-body contacts), and the
//               eq. (7) penalty is one of the cloth's force terms;
//   4. impulses: the impulses accumulated on dynamic bodies are applied;
//   5. proxy:   the ghost's AABB becomes the cloth's bounding box plus margin.
// A sleeping cloth (Cloth::isAsleep) is first woken if a candidate body is new, gone or
// moving (wakeForBodies); if it stays asleep, step 3 only advances its clock and steps 4 and
// 5 have nothing to do. After an awake sub-step in which it pushed an active dynamic body,
// its quiet time restarts.
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
//              force term (contactForces) turns into a normal force N and a friction force T
//              in f(t + dt): N holds the particle (it cancels what presses it in and stops its
//              normal motion within the step, and never more: nothing is launched, nothing
//              bounces), bounded by eq. (7) in the band; T stops the slip within the step while
//              |T| <= mu N (static friction: no creep at any dt), else is mu N against it
//              (kinetic). A resting particle's state then stays exactly as it is, and its
//              end-of-step velocity is zero.
//   Each normal force gets its friction once: lambda and the limiter planes' pushes (below)
//              as impulses in the stage, N as T in the force term.
// Dynamic bodies get the opposite of every impulse and of every contact force times the step
// at P; their snapshot velocities are updated contact by contact (sequential impulses), so
// many particles hitting a light body do not each see it at rest. Against them the force term
// has no terms in the velocity (they would feed back into a light body): N is eq. (7) plus the
// inward part of f, T cancels the tangential force up to mu N, and the rest of the cone is an
// impulse in the next stage (see contactForces).
//
// Triangles (contact.triangles, off by default): each cloth triangle near a convex or compound
// body is kept h away from it too (collideTriangle: GJK/EPA, the depth and the approach
// impulse shared by barycentric weights), so a feature thinner than the particle spacing
// cannot pass between particles.
//
// Fast particles: a particle that moved more than h in a step is also ray-tested along its
// path (btCollisionWorld::rayTestSingle), so it cannot pass through a thin body.
// After the projection, the particles it moved go into the limiter's worklist
// (Cloth::relimit), and every particle within reach of a static or kinematic body keeps that
// contact's tangent plane in the walk (ContactPlanes: the limiter slides it along the plane,
// so the strain bound and the contact hold together; the plane's push reaches the body as an
// impulse). What the limiter then moves is projected again (curved bodies, other bodies,
// dynamic bodies, which get no plane), until nothing moves or kRelimitPasses rounds have run.
#include "drape/bullet/bullet_cloth.hpp"

#include "self_collision.hpp"
#include "shape_queries.hpp"

#include "drape/error.hpp"
#include "drape/strain_limit.hpp"

#include <BulletCollision/CollisionDispatch/btGhostObject.h>
#include <BulletCollision/CollisionShapes/btEmptyShape.h>
#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <string>

namespace drape::bullet {
namespace {

using detail::Pose;

Vec3 toVec(const btVector3& v) {
    return Vec3(double(v.x()), double(v.y()), double(v.z()));
}
btVector3 toBt(const Vec3& v) {
    return btVector3(btScalar(v.x()), btScalar(v.y()), btScalar(v.z()));
}
Eigen::Matrix3d toMat(const btMatrix3x3& m) {
    Eigen::Matrix3d r;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            r(i, j) = double(m[i][j]);
    return r;
}
Pose toPose(const btTransform& t) {
    return Pose{toMat(t.getBasis()), toVec(t.getOrigin())};
}

std::string num(double v) {
    std::ostringstream s;
    s.precision(6);
    s << v;
    return s.str();
}

void require(bool ok, ErrorCode code, const std::string& message) {
    if (!ok) throw Error(code, message);
}

void validate(const BulletClothSettings& s) {
    const auto& c = s.contact;
    require(std::isfinite(c.thickness) && c.thickness > 0.0, ErrorCode::InvalidArgument,
            "contact.thickness must be positive and finite, got " + num(c.thickness));
    require(std::isfinite(c.penaltyBand), ErrorCode::NonFinite,
            "contact.penaltyBand is not finite");
    require(std::isfinite(c.penaltyForce), ErrorCode::NonFinite,
            "contact.penaltyForce is not finite");
    require(std::isfinite(c.frictionScale) && c.frictionScale >= 0.0, ErrorCode::InvalidArgument,
            "contact.frictionScale must be >= 0 and finite, got " + num(c.frictionScale));
    require(std::isfinite(c.broadphaseMargin), ErrorCode::NonFinite,
            "contact.broadphaseMargin is not finite");
    require(s.substeps >= 1, ErrorCode::InvalidArgument,
            "substeps must be >= 1, got " + std::to_string(s.substeps));
    const auto& sc = s.selfCollision;
    if (sc.enabled) {
        require(std::isfinite(sc.thickness) && sc.thickness > 0.0, ErrorCode::InvalidArgument,
                "selfCollision.thickness must be positive and finite, got " + num(sc.thickness));
        require(sc.iterations >= 1, ErrorCode::InvalidArgument,
                "selfCollision.iterations must be >= 1, got " + std::to_string(sc.iterations));
        require(std::isfinite(sc.friction) && sc.friction >= 0.0, ErrorCode::InvalidArgument,
                "selfCollision.friction must be >= 0 and finite, got " + num(sc.friction));
    }
}

/// The proxy's shape: no geometry (Bullet's ray tests and contact queries find nothing in
/// it), only an AABB that we set.
class BoundsShape final : public btEmptyShape {
  public:
    BT_DECLARE_ALIGNED_ALLOCATOR();
    void getAabb(const btTransform&, btVector3& aabbMin, btVector3& aabbMax) const override {
        aabbMin = min_;
        aabbMax = max_;
    }
    const char* getName() const override { return "DrapeClothBounds"; }
    void set(const Vec3& lo, const Vec3& hi) {
        min_ = toBt(lo);
        max_ = toBt(hi);
    }

  private:
    btVector3 min_{0, 0, 0};
    btVector3 max_{0, 0, 0};
};

/// The proxy: a ghost object whose broadphase overlaps are the cloth's candidate bodies. It
/// refuses narrow-phase with everything (checkCollideWith), so Bullet's dispatcher never
/// computes contacts for its pairs.
class ProxyGhost final : public btGhostObject {
  public:
    BT_DECLARE_ALIGNED_ALLOCATOR();
    ProxyGhost() { m_checkCollideWith = 1; }
    bool checkCollideWithOverride(const btCollisionObject*) const override { return false; }
};

/// The ghost pair callback that keeps btGhostObject overlap lists. Stateless, so one instance
/// serves every world; a world that already uses a btGhostPairCallback behaves the same with it.
btGhostPairCallback& ghostPairCallback() {
    static btGhostPairCallback callback;
    return callback;
}

/// A rigid body as the cloth sees it during one Bullet sub-step.
struct BodySnapshot {
    const btCollisionObject* object = nullptr;
    btRigidBody* dynamicBody = nullptr; ///< non-null when the cloth pushes the body back
    Pose pose;
    Vec3 aabbMin = Vec3::Zero(), aabbMax = Vec3::Zero(); ///< world AABB grown by the reach
    Vec3 com = Vec3::Zero();
    Vec3 v = Vec3::Zero(), w = Vec3::Zero(); ///< velocities, updated by the cloth's impulses
    double invMass = 0.0;
    Eigen::Matrix3d invInertia = Eigen::Matrix3d::Zero(); ///< world frame
    double friction = 0.0;
    /// A static plane (btStaticPlaneShape): its world normal and offset, nW . x - offset being
    /// the signed distance, for the cheap rejection of particles far above it (its AABB is
    /// infinite, so the box test passes every particle).
    bool plane = false;
    Vec3 planeNormal = Vec3::UnitY();
    double planeOffset = 0.0;
    double planeScale = 0.0; ///< |offset| + |t|: the size of the numbers in the distance [m]
    Vec3 linearImpulse = Vec3::Zero();  ///< accumulated for the body [N s]
    Vec3 angularImpulse = Vec3::Zero(); ///< about the centre of mass [N m s]

    Vec3 velocityAt(const Vec3& p) const { return v + w.cross(p - com); }
    /// Inverse effective mass of the body at p along unit direction d.
    double inverseMassAlong(const Vec3& p, const Vec3& d) const {
        if (!dynamicBody) return 0.0;
        const Vec3 rxd = (p - com).cross(d);
        return invMass + rxd.dot(invInertia * rxd);
    }
    void applyImpulse(const Vec3& j, const Vec3& p) {
        if (!dynamicBody) return;
        const Vec3 torque = (p - com).cross(j);
        linearImpulse += j;
        angularImpulse += torque;
        v += invMass * j;
        w += invInertia * torque;
    }
};

/// One particle touching a body or inside eq. (7)'s band above it: the contact force term
/// reads these (see contactForces).
struct ContactRecord {
    Index particle = 0;
    std::uint32_t body = 0;
    Vec3 point = Vec3::Zero();        ///< surface point [m]
    Vec3 normal = Vec3::UnitY();      ///< outward unit normal
    Vec3 bodyVelocity = Vec3::Zero(); ///< at the point [m/s]
    double mass = 0.0;                ///< the particle's mass [kg]
    double cp = 0.0;                  ///< C_p for this particle [N] (0: penalty off)
    double damping = 0.0;             ///< normal damping of the penalty [N s/m]
    double mu = 0.0;                  ///< Coulomb coefficient [-]
    /// The body is dynamic: no velocity terms in the force, the rest of the friction cone as
    /// an impulse (see contactForces).
    bool impulses = false;
    double force = 0.0;           ///< normal force at the last force evaluation [N]
    Vec3 friction = Vec3::Zero(); ///< friction force at the last evaluation [N]
};

/// Shared between the stage, the force term the cloth owns, and the handle.
struct ContactState {
    std::vector<ContactRecord> contacts;
    double thickness = 0.0;
    double band = 1.0;
    double dt = 1.0; ///< the step the records were made in [s]
};

constexpr double kE = 2.718281828459045;
/// A particle within this fraction of the thickness above it rests on the body: it is held
/// there, not floated by eq. (7). Covers the float noise of the projection onto P + h n and
/// the drift of a dynamic body's pose, which Bullet's solver moves by ~1e-9 m a step (with
/// 1e-6 of the thickness a sheet on a resting dynamic slab lost its support every few steps).
constexpr double kTouching = 1e-3;
/// Limiter and re-projection passes after the contact projection.
constexpr int kRelimitPasses = 8;
/// Extra sweeps over the triangles in contact after a triangle pass.
constexpr int kTriangleSweeps = 4;

/// Eq. (7) regularised. The paper's C_p exp(1 / |PP0|) grows without bound as the particle
/// reaches the surface and is dimensionally inconsistent; we keep its shape (an exponential
/// barrier along N_P0, zero without contact) on a band of width w above the thickness h:
///   phi(g) = (exp(1 - g / w) - 1) / (e - 1),  g = d - h in [0, w),  phi(0) = 1, phi(w) = 0,
///   F = max(0, C_p phi(g) - c (v_rel . n)),
/// continuous at the band's edge, bounded by C_p at the thickness (the projection takes over
/// below it), with a normal damping c that keeps resting particles from oscillating in the band.
double penaltyShape(double gap, double band) {
    if (gap >= band) return 0.0;
    const double g = std::max(gap, 0.0);
    return (std::exp(1.0 - g / band) - 1.0) / (kE - 1.0);
}

/// The contact force term: for each record, the normal force N and the friction force T on
/// its particle, added to f after every other term (so f holds the particle's other forces).
/// With Velocity-Verlet this force acts in the closing half kick of the step that made the
/// record and the opening half kick of the next one, that is, over one whole step dt between
/// two contact stages. With v the half-step velocity the stage left, for a static or
/// kinematic body:
///   N = min(eq. (7), hold),  hold = max(0, -f.n - m v_n / dt)
///       hold is the force that brings the normal relative velocity to zero within that step
///       (it cancels the push into the body and stops an approach; a particle leaving slowly
///       gets less than its load, so it comes back, and one leaving fast gets nothing);
///       eq. (7) (C_p phi(gap) - c v_n) bounds N in the band above the thickness, a touching
///       particle gets hold. N never exceeds hold: a contact holds its particle and stops its
///       approach, but never launches it (no rest is disturbed, no bounce: inelastic like the
///       projection).
///   T = the force that stops the tangential slip within that step, -(f_t + m v_t / dt), if
///       |T| <= mu N (static: the particle then stays exactly where it is, at any dt), else
///       that force scaled to mu N (kinetic, against the slip).
/// (Symplectic Euler applies f(t + dt) in one kick of dt: the same. The other integrators
/// apply it less directly, RK4 at its stages, so there the terms in v act as a damping of
/// rate 1 / dt: the same contact in the limit dt -> 0, first order like every contact.)
/// For a dynamic body (which gets -N n - T) the terms in v would feed back: many particles
/// each stopping their slip against a light body move it by (their mass / its mass) times that
/// slip, the wrong way (a 0.05 kg box under 1 kg of cloth tips over). There (pc.impulses) N is
/// eq. (7) as the paper has it (it also carries a body lying on the cloth), plus the inward
/// part of f for a touching particle; T cancels f_t up to mu N; the rest of the friction cone,
/// (mu N - |T|) dt, is given as an impulse against the slip by the next contact stage, which
/// updates the body's velocity contact by contact (frictionLeft).
/// Each normal force counts once: the stage gives friction only for the impulses it applies
/// itself (stopping an approach, the limiter's contact planes) and for that rest.
void contactForces(ContactState& state, const Vec3List& x, const Vec3List& v, Vec3List& f) {
    const double invDt = 1.0 / state.dt;
    for (auto& pc : state.contacts) {
        const Vec3& n = pc.normal;
        Vec3& fi = f[pc.particle];
        const Vec3 rel = v[pc.particle] - pc.bodyVelocity;
        const double vn = rel.dot(n);
        const double fn = fi.dot(n);
        const double gap = (x[pc.particle] - pc.point).dot(n) - state.thickness;
        const bool touching = gap <= kTouching * state.thickness;
        const double penalty =
            pc.cp > 0.0 ? std::max(0.0, pc.cp * penaltyShape(gap, state.band) - pc.damping * vn)
                        : 0.0;
        double force = 0.0;
        if (!pc.impulses) {
            force = std::max(0.0, -fn - pc.mass * vn * invDt);
            if (!touching) force = std::min(force, penalty);
        } else {
            force = std::max(penalty, touching ? -fn : 0.0);
        }
        pc.force = force;
        pc.friction = Vec3::Zero();
        if (force <= 0.0) continue;
        fi += force * n;
        if (pc.mu <= 0.0) continue;
        Vec3 stop = -(fi - fi.dot(n) * n);
        if (!pc.impulses) stop -= (pc.mass * invDt) * (rel - vn * n);
        const double need = stop.norm(), limit = pc.mu * force;
        pc.friction = need <= limit ? stop : Vec3(stop * (limit / need));
        fi += pc.friction;
    }
}

} // namespace

// --------------------------------------------------------------------------------------------

struct BulletCloth::Impl {
    class Action;
    class Stage;

    btDynamicsWorld* world = nullptr;
    std::shared_ptr<Cloth> cloth;
    BulletClothSettings settings;
    bool inWorld = false;
    bool inStep = false; ///< inside step(): the stage has a fresh body snapshot

    std::unique_ptr<BoundsShape> boundsShape;
    std::unique_ptr<ProxyGhost> ghost;
    std::unique_ptr<Action> action;
    std::shared_ptr<Stage> stage;
    std::shared_ptr<ContactState> penalty;

    std::vector<BodySnapshot> bodies;
    std::vector<Attachment> attachments;
    /// Per attachment: the attachment point at the start and end of the current sub-step.
    struct Target {
        Vec3 from = Vec3::Zero(), to = Vec3::Zero();
    };
    std::shared_ptr<std::vector<Target>> targets = std::make_shared<std::vector<Target>>();
    std::shared_ptr<std::pair<double, double>> window =
        std::make_shared<std::pair<double, double>>(0.0, 1.0);

    Vec3List prevX; ///< positions at the end of the previous step (after contacts)
    detail::SelfCollider selfCollider;
    ContactStats last, total;
    double margin = 0.0; ///< broadphase margin [m]
    double band = 0.0;   ///< eq. (7) band width [m]
    std::vector<const btCollisionObject*> candidates;
    Vec3 proxyMin = Vec3::Zero(), proxyMax = Vec3::Zero(); ///< the proxy's AABB [m]
    /// The candidate bodies and their poses at the previous sub-step (for waking).
    std::vector<std::pair<const btCollisionObject*, Pose>> lastPoses;

    // Scratch of the contact stage, reused every step.
    std::vector<unsigned char> touching; ///< particle touched a body this step
    std::vector<std::int64_t> recordOf;  ///< per particle: its latest ContactRecord, or -1
    /// Per particle: the friction its contact forces with dynamic bodies had left in the last
    /// step, mu N - |T| [N] (see contactForces); the stage gives it as an impulse.
    std::vector<double> frictionLeft;
    std::vector<Index> projected; ///< particles the last contact pass moved
    /// The tangent plane of each particle's contact this step (n . x >= n . P + h), which the
    /// limiter's walk keeps, with the body and the point it belongs to.
    ContactPlanes planes;
    std::vector<std::uint32_t> planeBody;
    std::vector<Vec3> planePoint;
    std::vector<std::size_t> moved;
    /// Timer slots in the cloth's PhaseTimers: the limiter calls inside the contact stage
    /// (nested in its "bullet_contacts" phase), and the handle's work around the cloth's
    /// steps (body snapshot, proxy, impulses on bodies).
    std::size_t slotStageLimiter = 0, slotBodies = 0;

    /// One Bullet sub-step of dt [s] (the action's updateAction).
    void step(double dt);
    /// Snapshots the bodies among the proxy's overlaps (and the broadphase's answer for a
    /// larger box when the cloth would sweep out of the proxy in this step).
    void gatherBodies(double dt);
    /// Wakes a sleeping cloth when a candidate body is new, gone or moving; records the poses.
    void wakeForBodies(double dt);
    /// The cloth's box swept over dt at its current velocities, grown by the contact reach.
    void sweptBounds(double dt, Vec3& lo, Vec3& hi) const;
    void setProxyBounds(const Vec3& lo, const Vec3& hi);
    void updateBounds(double dt);
    /// The contact stage: self-collision, particle-body contacts, re-limiting, friction.
    void resolveContacts(Cloth& c, double dt);
    /// Gives the body of contact plane k the opposite of what the plane pushed its particle
    /// by in the limiter's walk (m push / dt), with the Coulomb friction that normal impulse
    /// allows, and clears the push.
    void flushPlane(Cloth& c, std::size_t k, double dt) {
        const Vec3 push = planes.push[k];
        if (push == Vec3::Zero()) return;
        const std::size_t i = planes.particle(k);
        const Vec3 j = (c.masses()[i] / dt) * push;
        BodySnapshot& b = bodies[planeBody[k]];
        b.applyImpulse(-j, planePoint[k]);
        last.impulseOnCloth += j;
        if (b.dynamicBody) last.impulseOnBodies -= j;
        frictionImpulse(c, i, b, planePoint[k], planes.normal[k], b.friction * j.norm());
        planes.push[k] = Vec3::Zero();
    }
    /// Coulomb friction of a normal impulse: a tangential impulse of at most `budget` [N s]
    /// against particle i's velocity relative to body b at point p (tangent to `normal`); the
    /// body gets the opposite.
    void frictionImpulse(Cloth& c, std::size_t i, BodySnapshot& b, const Vec3& p,
                         const Vec3& normal, double budget) {
        if (!(budget > 0.0)) return;
        Vec3& vi = c.mutableVelocities()[i];
        const Vec3 rel = vi - b.velocityAt(p);
        const Vec3 vt = rel - rel.dot(normal) * normal;
        const double vtLen = vt.norm();
        if (vtLen <= 0.0) return;
        const Vec3 tdir = vt / vtLen;
        const double wi = c.inverseMasses()[i];
        const double jt = std::min(vtLen / (wi + b.inverseMassAlong(p, tdir)), budget);
        const Vec3 j = -jt * tdir;
        vi += wi * j;
        b.applyImpulse(-j, p);
        last.impulseOnCloth += j;
        if (b.dynamicBody) last.impulseOnBodies -= j;
    }
    /// Contact of particle i with body bi (projection, velocity response, friction, and its
    /// eq. (7) record). Returns whether it is within the contact reach.
    bool collideParticle(Cloth& c, std::uint32_t bi, std::size_t i, double dt,
                         detail::QueryCounters& counters);
    /// Triangle-body contacts (contact.triangles): every triangle whose box overlaps the
    /// (reach-grown) box of a convex or compound body.
    void collideTriangles(Cloth& c, double dt, detail::QueryCounters& counters);
    /// Contact of triangle t with body bi; returns the depth it moved the triangle out by
    /// [m], or -1 without contact.
    double collideTriangle(Cloth& c, std::uint32_t bi, std::size_t t, double dt,
                           detail::QueryCounters& counters);
    /// Per particle: its contact plane this step comes from a triangle contact (a particle
    /// contact's plane replaces it; a later triangle contact may update it). Sized only when
    /// contact.triangles is on.
    std::vector<unsigned char> trianglePlane;
    std::vector<std::pair<std::uint32_t, std::size_t>>
        triangleHits; ///< (body, triangle) that touched
    /// Per particle: the box collideParticle tests against a body's AABB (the particle, or
    /// its path since the previous step when that is longer than the thickness). Empty for
    /// particles that never collide (zero inverse mass). Kept up to date as contacts move
    /// particles, so every body sees the box of the particle as it is when it is tested.
    struct ParticleBox {
        double lo[3], hi[3];
    };
    std::vector<ParticleBox> boxes;
    /// The union of the boxes of kBlock consecutive particles, and how many of them collide.
    struct Block {
        Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity());
        Vec3 hi = Vec3::Constant(-std::numeric_limits<double>::infinity());
        std::size_t free = 0;
        void grow(const ParticleBox& b) {
            lo = lo.cwiseMin(Vec3(b.lo[0], b.lo[1], b.lo[2]));
            hi = hi.cwiseMax(Vec3(b.hi[0], b.hi[1], b.hi[2]));
        }
    };
    static constexpr std::size_t kBlock = 16;
    std::vector<Block> blocks;
    /// Moved particles of one block, moved[begin, end), for the re-projection.
    struct MovedGroup {
        std::size_t begin = 0, end = 0;
        Block box;
    };
    std::vector<MovedGroup> movedGroups;
    /// No particle whose box is inside bl can be within the reach of body b.
    bool blockMisses(const BodySnapshot& b, const Block& bl) const {
        return (bl.hi.array() < b.aabbMin.array()).any() ||
               (bl.lo.array() > b.aabbMax.array()).any() ||
               (b.plane && aboveReach(b, bl.lo, bl.hi));
    }
    void updateBox(std::size_t i, const Vec3& xi, const Vec3& from, bool fixed);
    /// The cheap test before collideParticle: false when particle i cannot be within the
    /// contact reach of body b in this step, so that collideParticle would return false
    /// without doing anything. Counts a box test.
    bool mayTouch(const BodySnapshot& b, std::size_t i, const Vec3& xi, const Vec3& from);
    bool aboveReach(const BodySnapshot& b, const Vec3& lo, const Vec3& hi) const;
    Vec3 attachmentPoint(const Attachment& a) const {
        return toPose(a.body->getWorldTransform()).toWorld(a.localPoint);
    }
};

class BulletCloth::Impl::Action final : public btActionInterface {
  public:
    explicit Action(Impl& impl) : impl_(impl) {}
    void updateAction(btCollisionWorld*, btScalar dt) override { impl_.step(double(dt)); }
    void debugDraw(btIDebugDraw* drawer) override {
        if (!drawer) return;
        const Cloth& c = *impl_.cloth;
        const btVector3 colour(0.8f, 0.5f, 0.2f);
        for (const auto& s : c.topology().springs()) {
            drawer->drawLine(toBt(c.positions()[s.a]), toBt(c.positions()[s.b]), colour);
        }
    }

  private:
    Impl& impl_;
};

class BulletCloth::Impl::Stage final : public ClothStage {
  public:
    explicit Stage(Impl& impl) : impl_(impl) {}
    std::string name() const override { return "bullet_contacts"; }
    void run(Cloth& c, double dt) override { impl_.resolveContacts(c, dt); }

  private:
    Impl& impl_;
};

namespace {
/// Collects the objects of the broadphase proxies overlapping a box.
struct CollectObjects final : btBroadphaseAabbCallback {
    std::vector<const btCollisionObject*>* out = nullptr;
    bool process(const btBroadphaseProxy* proxy) override {
        out->push_back(static_cast<const btCollisionObject*>(proxy->m_clientObject));
        return true;
    }
};
} // namespace

void BulletCloth::Impl::gatherBodies(double dt) {
    bodies.clear();
    candidates.clear();
    const auto& overlaps = ghost->getOverlappingPairs();
    for (int k = 0; k < overlaps.size(); ++k)
        candidates.push_back(overlaps[k]);
    // The proxy's box was set at the end of the previous step for the motion expected then.
    // If the cloth will sweep beyond it in this step (a first step, velocities set by the user,
    // a longer step), move the proxy now and ask the broadphase directly (a tree query, not
    // a loop over bodies) for what the larger box overlaps.
    // A sleeping cloth does not move: its proxy still holds it (and the sweep is O(particles)).
    Vec3 lo = proxyMin, hi = proxyMax;
    if (!cloth->isAsleep()) sweptBounds(dt, lo, hi);
    if ((lo.array() < proxyMin.array()).any() || (hi.array() > proxyMax.array()).any()) {
        setProxyBounds(lo, hi);
        CollectObjects collect;
        collect.out = &candidates;
        world->getBroadphase()->aabbTest(toBt(proxyMin), toBt(proxyMax), collect);
        std::sort(candidates.begin(), candidates.end());
        candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
        ++last.proxyRefreshes;
    }
    const double reach = settings.contact.thickness + band;
    for (const btCollisionObject* obj : candidates) {
        if (!obj || obj == ghost.get()) continue;
        const int type = obj->getInternalType();
        if (type != btCollisionObject::CO_RIGID_BODY &&
            type != btCollisionObject::CO_COLLISION_OBJECT) {
            continue; // ghosts (other cloths' proxies, triggers), soft bodies, multibodies
        }
        if (!obj->hasContactResponse() || !obj->getCollisionShape()) continue;
        BodySnapshot b;
        b.object = obj;
        b.pose = toPose(obj->getWorldTransform());
        b.com = b.pose.t;
        const double mu = double(obj->getFriction());
        if (!(std::isfinite(mu) && mu >= 0.0)) { // (the message is built only then: every step)
            throw Error(ErrorCode::InvalidArgument,
                        std::string("a body the cloth may touch (") +
                            obj->getCollisionShape()->getName() + ") has friction " + num(mu) +
                            ": Coulomb's coefficient (btCollisionObject::setFriction) must be >= 0 "
                            "and finite");
        }
        b.friction = mu * settings.contact.frictionScale;
        btVector3 mn, mx;
        obj->getCollisionShape()->getAabb(obj->getWorldTransform(), mn, mx);
        b.aabbMin = toVec(mn).array() - reach;
        b.aabbMax = toVec(mx).array() + reach;
        if (obj->getCollisionShape()->getShapeType() == STATIC_PLANE_PROXYTYPE) {
            const auto* ps = static_cast<const btStaticPlaneShape*>(obj->getCollisionShape());
            const Vec3 nLocal = toVec(ps->getPlaneNormal()).normalized(); // as shape_queries does
            b.plane = true;
            b.planeNormal = b.pose.R * nLocal;
            b.planeOffset = b.planeNormal.dot(b.pose.t) + double(ps->getPlaneConstant());
            b.planeScale = std::abs(b.planeOffset) + b.pose.t.cwiseAbs().sum();
        }
        if (const btRigidBody* rb = btRigidBody::upcast(obj)) {
            b.v = toVec(rb->getLinearVelocity());
            b.w = toVec(rb->getAngularVelocity());
            if (!rb->isStaticOrKinematicObject() && rb->getInvMass() > 0.0f) {
                b.dynamicBody = const_cast<btRigidBody*>(rb); // impulses are applied after the step
                b.invMass = double(rb->getInvMass());
                b.invInertia = toMat(rb->getInvInertiaTensorWorld());
            }
        }
        bodies.push_back(b);
    }
    last.candidateBodies = bodies.size();
}

void BulletCloth::Impl::wakeForBodies(double dt) {
    Cloth& c = *cloth;
    // Body motion that wakes the cloth: what would carry a point farther than sleep.distance
    // within the quiet time (a mean speed of distance / time).
    const auto& sl = c.settings().sleep;
    const double tol = sl.distance / std::max(sl.time, dt);
    bool wakeUp = c.isAsleep() && bodies.size() != lastPoses.size();
    for (std::size_t k = 0; k < bodies.size() && c.isAsleep() && !wakeUp; ++k) {
        const BodySnapshot& b = bodies[k];
        const auto was = std::find_if(lastPoses.begin(), lastPoses.end(),
                                      [&](const auto& p) { return p.first == b.object; });
        if (was == lastPoses.end()) {
            wakeUp = true; // a new candidate
            continue;      // (the loop ends on wakeUp)
        }
        const Pose& pose = was->second;
        // Turning is measured at the body's extent (its AABB's half diagonal; an infinite
        // plane turns only when its pose changes at all).
        const double radius = 0.5 * (b.aabbMax - b.aabbMin).norm();
        const double turn = (b.pose.R - pose.R).cwiseAbs().maxCoeff();
        wakeUp = (b.pose.t - pose.t).norm() > tol * dt ||
                 (turn > 0.0 && !(turn * radius <= tol * dt)) || b.v.norm() > tol ||
                 (b.w.norm() > 0.0 && !(b.w.norm() * radius <= tol));
    }
    if (wakeUp) c.wake();
    lastPoses.resize(bodies.size());
    for (std::size_t k = 0; k < bodies.size(); ++k)
        lastPoses[k] = {bodies[k].object, bodies[k].pose};
}

inline void BulletCloth::Impl::updateBox(std::size_t i, const Vec3& xi, const Vec3& from,
                                         bool fixed) {
    ParticleBox& box = boxes[i];
    if (fixed) { // never collides: a box no AABB overlaps
        for (int k = 0; k < 3; ++k) {
            box.lo[k] = std::numeric_limits<double>::infinity();
            box.hi[k] = -std::numeric_limits<double>::infinity();
        }
        return;
    }
    const double h = settings.contact.thickness;
    const bool sweep = settings.contact.continuous && (xi - from).squaredNorm() > h * h;
    for (int k = 0; k < 3; ++k) {
        box.lo[k] = sweep ? std::min(xi[k], from[k]) : xi[k];
        box.hi[k] = sweep ? std::max(xi[k], from[k]) : xi[k];
    }
}

/// Whether the box lo..hi lies entirely above plane b, farther than the contact reach, with
/// the margin mayTouch uses for swept particles: then no particle whose box is inside it
/// (both its ends when swept) can touch the plane.
bool BulletCloth::Impl::aboveReach(const BodySnapshot& b, const Vec3& lo, const Vec3& hi) const {
    Vec3 corner; // the box's corner deepest along -normal
    for (int k = 0; k < 3; ++k)
        corner[k] = b.planeNormal[k] >= 0.0 ? lo[k] : hi[k];
    if (!corner.allFinite()) return false;
    const double reach = settings.contact.thickness + band;
    const double size = b.planeScale + std::max(lo.cwiseAbs().maxCoeff(), hi.cwiseAbs().maxCoeff());
    return b.planeNormal.dot(corner) - b.planeOffset > reach + 1e-5 * size;
}

inline bool BulletCloth::Impl::mayTouch(const BodySnapshot& b, std::size_t i, const Vec3& xi,
                                        const Vec3& from) {
    ++last.particleBoxTests;
    // The particle's box against the body's AABB grown by the reach: the comparisons
    // collideParticle made before.
    const ParticleBox& box = boxes[i];
    if ((box.hi[0] < b.aabbMin[0]) | (box.hi[1] < b.aabbMin[1]) | (box.hi[2] < b.aabbMin[2]) |
        (box.lo[0] > b.aabbMax[0]) | (box.lo[1] > b.aabbMax[1]) | (box.lo[2] > b.aabbMax[2])) {
        return false;
    }
    if (!b.plane) return true;
    // A plane's AABB is infinite: reject particles clearly above it. The margin covers the
    // rounding of this distance against the query's (1e-9 relative), and for a swept particle
    // that of Bullet's single-precision ray test (1e-5 relative): only particles that the
    // query and the ray test would certainly reject are skipped, so nothing changes.
    const double h = settings.contact.thickness;
    const double reach = h + band;
    const bool sweep = settings.contact.continuous && (xi - from).squaredNorm() > h * h;
    const double dist = b.planeNormal.dot(xi) - b.planeOffset;
    const double size = b.planeScale + xi.cwiseAbs().maxCoeff();
    if (!sweep) return !(dist > reach + 1e-9 * size);
    const double distFrom = b.planeNormal.dot(from) - b.planeOffset;
    const double sizeFrom = std::max(size, b.planeScale + from.cwiseAbs().maxCoeff());
    return !(dist > reach + 1e-5 * sizeFrom && distFrom > reach + 1e-5 * sizeFrom);
}

bool BulletCloth::Impl::collideParticle(Cloth& c, std::uint32_t bi, std::size_t i, double dt,
                                        detail::QueryCounters& counters) {
    BodySnapshot& b = bodies[bi];
    Vec3List& x = c.mutablePositions();
    Vec3List& v = c.mutableVelocities();
    const double wi = c.inverseMasses()[i];
    const auto& cs = settings.contact;
    const double h = cs.thickness;
    const Vec3 xi = x[i];
    const Vec3 from = prevX[i];
    const bool sweep = cs.continuous && (xi - from).squaredNorm() > h * h;

    detail::SurfaceHit hit;
    bool crossed = false;
    if (sweep) {
        // Did the particle's path since the last step enter the body?
        ++last.rayQueries;
        btTransform t0, t1;
        t0.setIdentity();
        t1.setIdentity();
        t0.setOrigin(toBt(from));
        t1.setOrigin(toBt(xi));
        btCollisionWorld::ClosestRayResultCallback ray(t0.getOrigin(), t1.getOrigin());
        btCollisionWorld::rayTestSingle(t0, t1, const_cast<btCollisionObject*>(b.object),
                                        b.object->getCollisionShape(),
                                        b.object->getWorldTransform(), ray);
        if (ray.hasHit()) {
            Vec3 nrm = toVec(ray.m_hitNormalWorld);
            const double len = nrm.norm();
            if (len > 0.0) {
                nrm /= len;
                if (nrm.dot(from - xi) < 0.0) nrm = -nrm; // face where the particle came from
                crossed = true;
                hit.valid = true;
                hit.point = toVec(ray.m_hitPointWorld);
                hit.normal = nrm;
                hit.distance = std::min((xi - hit.point).dot(nrm), 0.0);
            }
        }
    }
    if (!crossed) {
        hit = detail::closestSurface(b.object->getCollisionShape(), b.pose, xi, from, h + band,
                                     counters);
        if (!hit.valid || hit.distance >= h + band) return false;
    }
    // The limiter's walk keeps the particle above the tangent plane of a contact with a static
    // or kinematic body. (Against a dynamic body the plane's push, applied after the walk as
    // an impulse, feeds back into the body's motion: a body much lighter than the cloth on it
    // goes unstable. There the projection and the walk alternate instead.) A plane of another
    // body this particle had gives that body what it held first.
    if (!b.dynamicBody) {
        if (const std::int32_t was = planes.of[i]; was >= 0 && planeBody[std::size_t(was)] != bi)
            flushPlane(c, std::size_t(was), dt);
        const std::size_t plane = std::size_t(
            planes.set(static_cast<Index>(i), hit.normal, hit.normal.dot(hit.point) + h));
        if (!trianglePlane.empty()) trianglePlane[i] = 0;
        if (plane == planeBody.size()) {
            planeBody.push_back(bi);
            planePoint.push_back(hit.point);
        } else {
            planeBody[plane] = bi;
            planePoint[plane] = hit.point;
        }
    }

    // The contact record the force term reads (contactForces): for every particle touching
    // the body (below the thickness, or resting at it), and with eq. (7) on for every particle
    // in the band above it (also for particles below the thickness: they end at its bottom
    // after the projection).
    const bool touches = hit.distance < h * (1.0 + kTouching);
    const double mi = c.masses()[i];
    double cp = cs.penaltyForce < 0.0 ? 2.0 * mi * c.settings().gravity.norm() : cs.penaltyForce;
    if (cp > 0.0 || touches) {
        double damping = 0.0;
        if (cp > 0.0) {
            // Keep the penalty spring (stiffness cp e / ((e - 1) w)) and its damping inside the
            // explicit stability limits of this step: k dt^2 / m <= 1, c dt / m <= 1/2.
            const double kMax = mi / (dt * dt);
            const double k = cp * kE / ((kE - 1.0) * band);
            if (k > kMax) cp *= kMax / k;
            damping = std::min(2.0 * std::sqrt(std::min(k, kMax) * mi), 0.5 * mi / dt);
        }
        // One record per particle and body: a second visit (after re-limiting) updates it.
        ContactRecord* rec = nullptr;
        const std::int64_t existing = recordOf[i];
        if (existing >= 0 && penalty->contacts[std::size_t(existing)].body == bi) {
            rec = &penalty->contacts[std::size_t(existing)];
        } else {
            recordOf[i] = std::int64_t(penalty->contacts.size());
            rec = &penalty->contacts.emplace_back();
            ++last.contacts;
        }
        rec->particle = static_cast<Index>(i);
        rec->body = bi;
        rec->point = hit.point;
        rec->normal = hit.normal;
        rec->bodyVelocity = b.velocityAt(hit.point);
        rec->mass = mi;
        rec->cp = std::max(cp, 0.0);
        rec->damping = damping;
        rec->mu = b.friction;
        rec->impulses = b.dynamicBody != nullptr;
    }
    if (b.dynamicBody && i < frictionLeft.size() && frictionLeft[i] > 0.0) {
        // The rest of the last step's friction cone against a dynamic body, once per step.
        frictionImpulse(c, i, b, hit.point, hit.normal, frictionLeft[i] * dt);
        frictionLeft[i] = 0.0;
    }
    if (hit.distance >= h) return true; // in the band or resting on the body: no projection

    ++last.projections;
    touching[i] = 1;
    x[i] = xi + (h - hit.distance) * hit.normal;
    const Vec3 rel = v[i] - b.velocityAt(hit.point);
    const double vn = rel.dot(hit.normal);
    if (vn < 0.0) {
        // Inelastic: the approach stops, and the normal impulse lambda allows a tangential
        // (Coulomb) impulse of mu lambda. (A resting load is carried by the contact force of
        // contactForces, with its own friction: each normal force counts once.)
        const double lambda = -vn / (wi + b.inverseMassAlong(hit.point, hit.normal));
        const Vec3 j = lambda * hit.normal;
        v[i] += wi * j;
        b.applyImpulse(-j, hit.point);
        last.impulseOnCloth += j;
        if (b.dynamicBody) last.impulseOnBodies -= j;
        frictionImpulse(c, i, b, hit.point, hit.normal, b.friction * lambda);
    }
    return true;
}

double BulletCloth::Impl::collideTriangle(Cloth& c, std::uint32_t bi, std::size_t t, double dt,
                                          detail::QueryCounters& counters) {
    BodySnapshot& b = bodies[bi];
    const Triangle& tri = c.topology().triangles()[t];
    Vec3List& x = c.mutablePositions();
    Vec3List& v = c.mutableVelocities();
    const auto& w = c.inverseMasses();
    const double h = settings.contact.thickness;
    const detail::TriangleHit hit =
        detail::closestToTriangle(b.object->getCollisionShape(), b.object->getWorldTransform(),
                                  x[tri[0]], x[tri[1]], x[tri[2]], h, counters);
    if (!hit.valid || !(hit.distance < h)) return -1.0;
    // The triangle's nearest point moves out by the depth along n: particle k by
    // beta_k w_k / W of it, W = sum beta_k^2 w_k (the least-mass-weighted change that moves the
    // point by exactly that), and its approach stops with the impulse lambda shared the same
    // way: the point's inverse mass along n is W.
    const Vec3& beta = hit.barycentric;
    double weight = 0.0;
    for (int k = 0; k < 3; ++k)
        weight += beta[k] * beta[k] * w[tri[k]];
    if (!(weight > 0.0)) return -1.0;
    const Vec3& n = hit.normal;
    const double depth = h - hit.distance;
    for (int k = 0; k < 3; ++k) {
        const Index i = tri[k];
        if (w[i] == 0.0 || beta[k] == 0.0) continue;
        x[i] += (beta[k] * w[i] * depth / weight) * n;
        touching[i] = 1;
        projected.push_back(i);
        updateBox(i, x[i], prevX[i], false);
        // Against a static or kinematic body the limiter's walk keeps the particle from going
        // back along n (its own contact's plane, if it has one, comes first), so the strain
        // bound and the triangle's contact hold together, as for particle contacts.
        if (!b.dynamicBody && (planes.of[i] < 0 || trianglePlane[i])) {
            if (const std::int32_t was = planes.of[i];
                was >= 0 && planeBody[std::size_t(was)] != bi)
                flushPlane(c, std::size_t(was), dt);
            const auto plane = std::size_t(planes.set(i, n, n.dot(x[i])));
            if (plane == planeBody.size()) {
                planeBody.push_back(bi);
                planePoint.push_back(hit.bodyPoint);
            } else {
                planeBody[plane] = bi;
                planePoint[plane] = hit.bodyPoint;
            }
            trianglePlane[i] = 1;
        }
    }
    ++last.triangleContacts;
    const Vec3 rel = beta[0] * v[tri[0]] + beta[1] * v[tri[1]] + beta[2] * v[tri[2]] -
                     b.velocityAt(hit.bodyPoint);
    const double vn = rel.dot(n);
    if (vn >= 0.0) return depth;
    auto share = [&](const Vec3& j) { // an impulse j at the point: the particles' shares, the
                                      // body's opposite
        for (int k = 0; k < 3; ++k)
            v[tri[k]] += (beta[k] * w[tri[k]]) * j;
        b.applyImpulse(-j, hit.bodyPoint);
        last.impulseOnCloth += j;
        if (b.dynamicBody) last.impulseOnBodies -= j;
    };
    const double lambda = -vn / (weight + b.inverseMassAlong(hit.bodyPoint, n));
    share(lambda * n);
    const Vec3 vt = rel - vn * n;
    const double vtLen = vt.norm();
    if (vtLen > 0.0 && b.friction > 0.0) {
        const Vec3 tdir = vt / vtLen;
        const double jt = std::min(vtLen / (weight + b.inverseMassAlong(hit.bodyPoint, tdir)),
                                   b.friction * lambda);
        share(-jt * tdir);
    }
    return depth;
}

void BulletCloth::Impl::collideTriangles(Cloth& c, double dt, detail::QueryCounters& counters) {
    const auto& tris = c.topology().triangles();
    const auto& w = c.inverseMasses();
    const Vec3List& x = c.positions();
    triangleHits.clear();
    for (std::uint32_t bi = 0; bi < bodies.size(); ++bi) {
        const BodySnapshot& b = bodies[bi];
        // Planes have no feature to slip between particles; concave meshes are not queried.
        const btCollisionShape* shape = b.object->getCollisionShape();
        if (b.plane || !(shape->isConvex() || shape->getShapeType() == COMPOUND_SHAPE_PROXYTYPE))
            continue;
        for (std::size_t t = 0; t < tris.size(); ++t) {
            const Triangle& tri = tris[t];
            if (w[tri[0]] == 0.0 && w[tri[1]] == 0.0 && w[tri[2]] == 0.0) continue;
            const Vec3 lo = x[tri[0]].cwiseMin(x[tri[1]]).cwiseMin(x[tri[2]]);
            const Vec3 hi = x[tri[0]].cwiseMax(x[tri[1]]).cwiseMax(x[tri[2]]);
            if ((hi.array() < b.aabbMin.array()).any() || (lo.array() > b.aabbMax.array()).any())
                continue;
            if (collideTriangle(c, bi, t, dt, counters) >= 0.0) triangleHits.emplace_back(bi, t);
        }
    }
    // Moving one triangle's particles turns its neighbours (which share them) and can press
    // them back in: a few more sweeps over the triangles that touched (Gauss-Seidel).
    for (int sweep = 0; sweep < kTriangleSweeps && !triangleHits.empty(); ++sweep) {
        double deepest = 0.0;
        for (const auto& [bi, t] : triangleHits)
            deepest = std::max(deepest, collideTriangle(c, bi, t, dt, counters));
        if (deepest <= 1e-9 * settings.contact.thickness) break; // (rounding)
    }
}

void BulletCloth::Impl::resolveContacts(Cloth& c, double dt) {
    const std::size_t n = c.particleCount();
    planes.reset(n);
    if (settings.contact.triangles) trianglePlane.assign(n, 0);
    planeBody.clear();
    planePoint.clear();
    if (!inStep) { // the cloth was stepped outside the world: no snapshot to collide with
        prevX = c.positions();
        return;
    }
    if (prevX.size() != n) prevX = c.positions();
    penalty->contacts.clear();
    penalty->dt = dt;
    const bool self = settings.selfCollision.enabled;
    if (bodies.empty() && !self) {
        prevX = c.positions();
        return; // no rigid collider near the cloth: no collision work at all
    }
    Vec3List& x = c.mutablePositions();
    Vec3List& v = c.mutableVelocities();
    const auto& invMass = c.inverseMasses();

    if (self) {
        const auto& sc = settings.selfCollision;
        const auto counts = selfCollider.run(c.topology(), invMass, prevX, x, v, sc.thickness,
                                             sc.friction, sc.iterations);
        last.selfPairTests += counts.pairTests;
        last.selfContacts += counts.contacts;
    }

    detail::QueryCounters counters;
    touching.assign(n, 0);
    recordOf.assign(n, -1);
    projected.clear();
    bool anyTouching = false;
    // Pinned, kinematic and attached particles (zero inverse mass) get empty boxes. Blocks of
    // kBlock consecutive particles (neighbours in a sheet, so their boxes are close) get the
    // union of their boxes: a body a block's box misses is not tested against its particles
    // one by one. The cloth's box is the union of all of them. Both are grown as contacts move
    // particles, so they stay supersets of the boxes the particles have when they are tested.
    boxes.resize(n);
    Block whole;
    for (std::size_t i = 0; i < n; ++i) {
        const bool fixed = invMass[i] == 0.0;
        updateBox(i, x[i], prevX[i], fixed);
        whole.free += !fixed;
        whole.grow(boxes[i]);
    }
    // The blocks are built when a body is near the cloth at all (not while it falls free).
    const std::size_t nBlocks = (n + kBlock - 1) / kBlock;
    bool blocksBuilt = false;
    for (std::uint32_t bi = 0; bi < bodies.size(); ++bi) {
        const BodySnapshot& b = bodies[bi];
        auto misses = [&b, this](const Block& bl) { return blockMisses(b, bl); };
        // Every particle's box would fail the box test: skip them (and count the tests).
        if (misses(whole)) {
            last.particleBoxTests += whole.free;
            continue;
        }
        if (!blocksBuilt) { // before any projection of this step: from the boxes as they are
            blocks.assign(nBlocks, Block{});
            for (std::size_t i = 0; i < n; ++i) {
                Block& bl = blocks[i / kBlock];
                bl.free += invMass[i] != 0.0;
                bl.grow(boxes[i]);
            }
            blocksBuilt = true;
        }
        for (std::size_t k = 0; k < nBlocks; ++k) {
            Block& bl = blocks[k];
            if (misses(bl)) {
                last.particleBoxTests += bl.free;
                continue;
            }
            for (std::size_t i = k * kBlock, end = std::min(n, i + kBlock); i < end; ++i) {
                if (invMass[i] == 0.0 || !mayTouch(b, i, x[i], prevX[i])) continue;
                const Vec3 before = x[i];
                collideParticle(c, bi, i, dt, counters);
                if (x[i] != before) { // projected: the next bodies see where it is now
                    projected.push_back(static_cast<Index>(i));
                    updateBox(i, x[i], prevX[i], false);
                    bl.grow(boxes[i]);
                    whole.grow(boxes[i]);
                }
            }
        }
    }
    if (settings.contact.triangles) collideTriangles(c, dt, counters);
    for (unsigned char t : touching)
        anyTouching = anyTouching || t != 0;

    // The projection may have overstretched springs the limiter had just fixed (a cloth
    // pressed onto a sphere by its hanging sides: projecting along diverging normals lengthens
    // the springs between touching particles). The particles it moved go into the limiter's
    // worklist; what the limiter then moves is projected again, and so on. Holding the
    // touching particles fixed instead does not work: springs between two of them could
    // never be shortened.
    const auto& lim = c.settings().limiter;
    for (int pass = 0; anyTouching && lim.kind != LimiterKind::None && pass < kRelimitPasses;
         ++pass) {
        StrainLimitStats st;
        {
            ScopedPhase timeLimiter(c.timers(), slotStageLimiter);
            st = c.relimit(projected, dt, &planes);
        }
        if (st.corrections == 0) break;
        moved.assign(c.relimitMoved().begin(), c.relimitMoved().end());
        std::sort(moved.begin(), moved.end());
        projected.clear();
        // Re-project what the limiter moved, in index order per body as before; the moved
        // particles of one block are skipped together when their boxes' union misses a body.
        movedGroups.clear();
        for (std::size_t m = 0; m < moved.size(); ++m) {
            const std::size_t i = moved[m];
            updateBox(i, x[i], prevX[i], false);
            if (movedGroups.empty() || moved[movedGroups.back().begin] / kBlock != i / kBlock)
                movedGroups.push_back(MovedGroup{m, m, Block{}});
            MovedGroup& g = movedGroups.back();
            g.end = m + 1;
            ++g.box.free;
            g.box.grow(boxes[i]);
        }
        for (std::uint32_t bi = 0; bi < bodies.size(); ++bi) {
            const BodySnapshot& b = bodies[bi];
            for (MovedGroup& g : movedGroups) {
                if (blockMisses(b, g.box)) {
                    last.particleBoxTests += g.box.free;
                    continue;
                }
                for (std::size_t m = g.begin; m < g.end; ++m) {
                    const std::size_t i = moved[m];
                    if (!mayTouch(b, i, x[i], prevX[i])) continue;
                    const Vec3 before = x[i];
                    collideParticle(c, bi, i, dt, counters);
                    if (x[i] != before) {
                        projected.push_back(static_cast<Index>(i));
                        updateBox(i, x[i], prevX[i], false);
                        g.box.grow(boxes[i]);
                    }
                }
            }
        }
        if (settings.contact.triangles) collideTriangles(c, dt, counters);
    }

    // What the contact planes held in the limiter's walk: the particle got m push / dt (its
    // velocity follows its position), the body gets the opposite.
    for (std::size_t k = 0; k < planes.size(); ++k)
        flushPlane(c, k, dt);

    last.narrowphaseQueries += counters.queries;
    last.triangleQueries += counters.triangleQueries;
    prevX = x;
}

void BulletCloth::Impl::sweptBounds(double dt, Vec3& lo, Vec3& hi) const {
    const Cloth& c = *cloth;
    // x and y as one two-lane Eigen array (one SSE2 register), z on its own: the same values
    // as Vec3 arithmetic (min and max are exact, x + dt v is computed the same way per lane)
    // at half the instructions.
    using Pair = Eigen::Array2d;
    const double inf = std::numeric_limits<double>::infinity();
    Pair lo01 = Pair::Constant(inf), hi01 = Pair::Constant(-inf);
    double lo2 = inf, hi2 = -inf;
    const Vec3* xs = c.positions().data();
    const Vec3* vs = c.velocities().data();
    for (std::size_t i = 0, n = c.particleCount(); i < n; ++i) {
        const Pair x01 = Eigen::Map<const Pair>(xs[i].data());
        const Pair a01 = x01 + dt * Eigen::Map<const Pair>(vs[i].data());
        lo01 = lo01.min(x01).min(a01);
        hi01 = hi01.max(x01).max(a01);
        const double x2 = xs[i][2], a2 = x2 + dt * vs[i][2];
        lo2 = std::min(lo2, std::min(x2, a2));
        hi2 = std::max(hi2, std::max(x2, a2));
    }
    lo = Vec3(lo01[0], lo01[1], lo2);
    hi = Vec3(hi01[0], hi01[1], hi2);
    const double grow = settings.contact.thickness + band;
    lo.array() -= grow;
    hi.array() += grow;
}

void BulletCloth::Impl::setProxyBounds(const Vec3& lo, const Vec3& hi) {
    proxyMin = lo;
    proxyMax = hi;
    boundsShape->set(lo, hi);
    if (inWorld) world->updateSingleAabb(ghost.get());
}

void BulletCloth::Impl::updateBounds(double dt) {
    // Where the particles can get in the next step (at the speed they have now), plus the
    // contact reach, plus the margin for bodies moving toward the cloth.
    Vec3 lo, hi;
    sweptBounds(dt, lo, hi);
    setProxyBounds(lo.array() - margin, hi.array() + margin);
}

void BulletCloth::Impl::step(double dt) {
    using Clock = std::chrono::steady_clock;
    const auto start = Clock::now();
    last = ContactStats{};
    gatherBodies(dt);
    Cloth& c = *cloth;
    const double t0 = c.time();
    *window = {t0, t0 + dt};
    for (std::size_t a = 0; a < attachments.size(); ++a) {
        (*targets)[a].from = (*targets)[a].to;
        (*targets)[a].to = attachmentPoint(attachments[a]);
    }
    if (settings.useWorldGravity) { // follow the world's gravity if the user changes it
        const Vec3 g = toVec(world->getGravity());
        if (g != c.settings().gravity) c.setGravity(g); // wakes the cloth
    }
    wakeForBodies(dt); // a moving attachment body wakes it through its kinematic path
    const double h = dt / settings.substeps;
    struct InStep {
        bool& flag;
        explicit InStep(bool& f) : flag(f) { flag = true; }
        ~InStep() { flag = false; }
        InStep(const InStep&) = delete;
        InStep& operator=(const InStep&) = delete;
    } guard(inStep);
    double bodySeconds = std::chrono::duration<double>(Clock::now() - start).count();
    bool slept = true; // every sub-step was taken asleep
    for (int s = 0; s < settings.substeps; ++s) {
        const bool wasAsleep = c.isAsleep();
        c.step(h);
        ++last.steps;
        if (wasAsleep && c.isAsleep()) continue; // nothing moved, nothing to hand to bodies
        slept = false;
        const auto afterStep = Clock::now();
        // The contact force (normal and friction) the particles got at the end of this step
        // acts for h; the body gets the opposite.
        frictionLeft.assign(c.particleCount(), 0.0);
        for (const auto& pc : penalty->contacts) {
            if (pc.impulses)
                frictionLeft[pc.particle] += std::max(0.0, pc.mu * pc.force - pc.friction.norm());
        }
        for (const auto& pc : penalty->contacts) {
            if (pc.force == 0.0) continue;
            const Vec3 j = (pc.force * pc.normal + pc.friction) * h;
            last.impulseOnCloth += j;
            BodySnapshot& b = bodies[pc.body];
            if (b.dynamicBody) {
                b.applyImpulse(-j, pc.point);
                last.impulseOnBodies -= j;
            }
        }
        // Attachments to dynamic bodies: the body carries the force the cloth puts on the
        // attached particle (springs and the particle's own weight).
        for (const auto& a : attachments) {
            const btRigidBody* rb = btRigidBody::upcast(a.body);
            if (!rb || rb->isStaticOrKinematicObject() || rb->getInvMass() <= 0.0f) continue;
            const Vec3 j = c.forces()[a.particle] * h;
            const Vec3 at = c.positions()[a.particle];
            last.impulseOnBodies += j;
            auto snap = std::find_if(bodies.begin(), bodies.end(),
                                     [&](const BodySnapshot& b) { return b.object == a.body; });
            if (snap != bodies.end()) {
                snap->applyImpulse(j, at);
            } else {
                // The body is outside the proxy (possible with a long attachment): apply now.
                auto* body = const_cast<btRigidBody*>(rb);
                body->applyImpulse(toBt(j), toBt(at - toVec(body->getCenterOfMassPosition())));
                body->activate();
            }
        }
        bodySeconds += std::chrono::duration<double>(Clock::now() - afterStep).count();
    }
    const auto afterSteps = Clock::now();
    for (auto& b : bodies) {
        if (!b.dynamicBody) continue;
        if (b.linearImpulse.squaredNorm() == 0.0 && b.angularImpulse.squaredNorm() == 0.0) continue;
        btRigidBody* rb = b.dynamicBody;
        if (rb->isActive()) c.wake(); // it carries or pushes a body: no sleep (see the header)
        // A sleeping body is not woken by nudges below its sleeping threshold.
        const double dv = b.linearImpulse.norm() * b.invMass;
        if (!rb->isActive() && dv < double(rb->getLinearSleepingThreshold())) continue;
        rb->applyCentralImpulse(toBt(b.linearImpulse));
        rb->applyTorqueImpulse(toBt(b.angularImpulse));
        rb->activate();
    }
    if (!slept) updateBounds(dt);
    bodySeconds += std::chrono::duration<double>(Clock::now() - afterSteps).count();
    c.timers().add(slotBodies, bodySeconds);
    total.candidateBodies += last.candidateBodies;
    total.particleBoxTests += last.particleBoxTests;
    total.narrowphaseQueries += last.narrowphaseQueries;
    total.rayQueries += last.rayQueries;
    total.triangleQueries += last.triangleQueries;
    total.triangleContacts += last.triangleContacts;
    total.contacts += last.contacts;
    total.projections += last.projections;
    total.selfContacts += last.selfContacts;
    total.selfPairTests += last.selfPairTests;
    total.impulseOnBodies += last.impulseOnBodies;
    total.impulseOnCloth += last.impulseOnCloth;
    total.steps += last.steps;
    total.proxyRefreshes += last.proxyRefreshes;
}

// --------------------------------------------------------------------------------------------

BulletCloth::BulletCloth(btDynamicsWorld* world, std::shared_ptr<Cloth> cloth,
                         const BulletClothSettings& settings)
    : impl_(std::make_unique<Impl>()) {
    require(world != nullptr, ErrorCode::InvalidArgument, "addCloth: the Bullet world is null");
    require(cloth != nullptr, ErrorCode::InvalidArgument, "addCloth: the cloth is null");
    validate(settings);
    Impl& m = *impl_;
    m.world = world;
    m.cloth = std::move(cloth);
    m.settings = settings;
    const double h = settings.contact.thickness;
    m.band = settings.contact.penaltyBand < 0.0 ? h : settings.contact.penaltyBand;
    require(m.band > 0.0 || settings.contact.penaltyForce == 0.0, ErrorCode::InvalidArgument,
            "contact.penaltyBand must be positive when the penalty force is on");
    if (!(m.band > 0.0)) m.band = h;
    if (settings.contact.broadphaseMargin >= 0.0) {
        m.margin = settings.contact.broadphaseMargin;
    } else {
        double sum = 0.0;
        for (const auto& s : m.cloth->topology().springs())
            sum += s.restLength;
        const auto count = double(std::max<std::size_t>(1, m.cloth->topology().springCount()));
        m.margin = sum / count + 4.0 * h;
    }
    if (settings.useWorldGravity) m.cloth->setGravity(toVec(world->getGravity()));
    if (settings.sleep && !m.cloth->settings().sleep.enabled) {
        SleepSettings sleep = m.cloth->settings().sleep;
        sleep.enabled = true;
        m.cloth->setSleep(sleep);
    }

    m.slotStageLimiter = m.cloth->timers().slot("bullet_contacts/limiter");
    m.slotBodies = m.cloth->timers().slot("bullet_bodies");
    m.penalty = std::make_shared<ContactState>();
    m.penalty->thickness = h;
    m.penalty->band = m.band;
    // The force term lives as long as the cloth; it reads the contact list, which is empty
    // once this handle is removed.
    m.cloth->addExternalForce("contact_force",
                              [state = m.penalty](const Vec3List& x, const Vec3List& v,
                                                  Vec3List& f) { contactForces(*state, x, v, f); });
    m.stage = std::make_shared<Impl::Stage>(m);
    m.cloth->addStage(m.stage);
    m.prevX = m.cloth->positions();

    m.boundsShape = std::make_unique<BoundsShape>();
    m.ghost = std::make_unique<ProxyGhost>();
    m.ghost->setCollisionShape(m.boundsShape.get());
    m.ghost->setCollisionFlags(m.ghost->getCollisionFlags() |
                               btCollisionObject::CF_NO_CONTACT_RESPONSE);
    m.ghost->setActivationState(DISABLE_DEACTIVATION);
    m.ghost->setUserPointer(this);
    m.updateBounds(0.0);
    world->getPairCache()->setInternalGhostPairCallback(&ghostPairCallback());
    world->addCollisionObject(m.ghost.get(), settings.collisionGroup, settings.collisionMask);
    m.action = std::make_unique<Impl::Action>(m);
    world->addAction(m.action.get());
    m.inWorld = true;
}

BulletCloth::~BulletCloth() {
    remove();
}

void BulletCloth::remove() {
    Impl& m = *impl_;
    if (!m.inWorld) return;
    m.world->removeAction(m.action.get());
    m.world->removeCollisionObject(m.ghost.get());
    m.cloth->removeStage(m.stage.get());
    m.penalty->contacts.clear();
    for (const auto& a : m.attachments)
        m.cloth->unpin(a.particle);
    m.attachments.clear();
    m.targets->clear();
    m.bodies.clear();
    m.inWorld = false;
}

bool BulletCloth::inWorld() const {
    return impl_->inWorld;
}

void BulletCloth::attach(Index particle, const btCollisionObject* body, const Vec3& localPoint) {
    Impl& m = *impl_;
    require(m.inWorld, ErrorCode::InvalidArgument,
            "attach: the cloth has been removed from its world");
    require(particle < m.cloth->particleCount(), ErrorCode::IndexOutOfRange,
            "attach: particle " + std::to_string(particle) + " does not exist (the cloth has " +
                std::to_string(m.cloth->particleCount()) + " particles)");
    require(body != nullptr, ErrorCode::InvalidArgument,
            "attach: the body for particle " + std::to_string(particle) + " is null");
    require(localPoint.allFinite(), ErrorCode::NonFinite,
            "attach: the local point for particle " + std::to_string(particle) + " is not finite");
    detach(particle);
    Attachment a{particle, body, localPoint};
    const Vec3 p = m.attachmentPoint(a);
    m.attachments.push_back(a);
    m.targets->push_back(Impl::Target{p, p});
    const std::size_t slot = m.attachments.size() - 1;
    // The particle's path interpolates the attachment point across the current sub-step.
    m.cloth->setKinematic(particle, [targets = m.targets, window = m.window, slot](double t) {
        const auto& tg = (*targets)[slot];
        const double span = window->second - window->first;
        const double s = span > 0.0 ? std::clamp((t - window->first) / span, 0.0, 1.0) : 1.0;
        return Vec3(tg.from + s * (tg.to - tg.from));
    });
}

void BulletCloth::attachHere(Index particle, const btCollisionObject* body) {
    require(body != nullptr, ErrorCode::InvalidArgument,
            "attachHere: the body for particle " + std::to_string(particle) + " is null");
    require(particle < impl_->cloth->particleCount(), ErrorCode::IndexOutOfRange,
            "attachHere: particle " + std::to_string(particle) + " does not exist (the cloth has " +
                std::to_string(impl_->cloth->particleCount()) + " particles)");
    const Pose pose = toPose(body->getWorldTransform());
    attach(particle, body, pose.toLocal(impl_->cloth->positions()[particle]));
}

void BulletCloth::detach(Index particle) {
    Impl& m = *impl_;
    for (std::size_t k = 0; k < m.attachments.size(); ++k) {
        if (m.attachments[k].particle != particle) continue;
        m.cloth->unpin(particle);
        // Slots are captured by index: re-register the paths of the attachments that move.
        m.attachments.erase(m.attachments.begin() + static_cast<std::ptrdiff_t>(k));
        m.targets->erase(m.targets->begin() + static_cast<std::ptrdiff_t>(k));
        for (std::size_t r = k; r < m.attachments.size(); ++r) {
            const Index pr = m.attachments[r].particle;
            const Vec3 vr = m.cloth->velocities()[pr]; // setKinematic pins: it zeroes the velocity
            m.cloth->setKinematic(pr, [targets = m.targets, window = m.window, r](double t) {
                const auto& tg = (*targets)[r];
                const double span = window->second - window->first;
                const double s =
                    span > 0.0 ? std::clamp((t - window->first) / span, 0.0, 1.0) : 1.0;
                return Vec3(tg.from + s * (tg.to - tg.from));
            });
            m.cloth->mutableVelocities()[pr] = vr; // detached later, it leaves with it
        }
        return;
    }
}

const std::vector<Attachment>& BulletCloth::attachments() const {
    return impl_->attachments;
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
const btCollisionObject* BulletCloth::proxyObject() const {
    return impl_->ghost.get();
}
const ContactStats& BulletCloth::lastStats() const {
    return impl_->last;
}
const ContactStats& BulletCloth::totalStats() const {
    return impl_->total;
}
void BulletCloth::debugDraw(btIDebugDraw* drawer) const {
    impl_->action->debugDraw(drawer);
}

void BulletCloth::stepInWorld(double dt) {
    require(std::isfinite(dt) && dt > 0.0, ErrorCode::InvalidArgument,
            "stepInWorld: dt must be positive and finite, got " + num(dt));
    require(impl_->inWorld, ErrorCode::InvalidArgument,
            "stepInWorld: the cloth has been removed from its world");
    impl_->step(dt);
}

std::unique_ptr<BulletCloth> addCloth(btDynamicsWorld* world, std::shared_ptr<Cloth> cloth,
                                      const BulletClothSettings& settings) {
    return std::make_unique<BulletCloth>(world, std::move(cloth), settings);
}

void removeCloth(BulletCloth& cloth) {
    cloth.remove();
}

} // namespace drape::bullet
