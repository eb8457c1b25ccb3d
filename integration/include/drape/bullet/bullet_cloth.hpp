// drape/bullet/bullet_cloth.hpp: a drape::Cloth living in a Bullet dynamics world.
//
//   auto cloth = std::make_shared<drape::Cloth>(topology, clothSettings);
//   auto handle = drape::bullet::addCloth(world, cloth);       // one call in
//   world->stepSimulation(dt, maxSubSteps, fixedTimeStep);      // steps bodies and cloth
//   drape::bullet::removeCloth(*handle);                        // one call out
//
// How it fits into Bullet (see bullet_cloth.cpp for the details):
//  - The cloth is a btActionInterface, so btDiscreteDynamicsWorld steps it in every internal
//    sub-step, right after the rigid bodies have been integrated.
//  - It owns a broadphase proxy (a btGhostObject whose AABB is the cloth's bounding box plus a
//    margin). The rigid bodies a cloth may touch are the ghost's broadphase overlaps; nothing
//    ever loops over the world's bodies. The ghost never takes part in narrow-phase, ray tests
//    or contact generation of the world.
//  - Contacts (particle against body, with a cloth thickness) are resolved in a drape::ClothStage
//    after integration and strain limiting: a position projection out of the body and an
//    inelastic normal velocity response, and a contact force term (an external force of the
//    cloth) that holds resting particles, bounded by eq. (7)'s penalty in the band above the
//    thickness, with Coulomb friction (the body's friction coefficient): static friction holds
//    exactly, kinetic friction is mu times the normal force. Contacts with dynamic bodies
//    exchange equal and opposite impulses with them (two-way coupling).
//  - Bodies are snapshotted (transform, velocities, inverse mass and inertia) before the cloth
//    step; the impulses the cloth gave them are applied after it.
//  - Sleeping (BulletClothSettings::sleep, on by default): a cloth at rest falls asleep as
//    Cloth::isAsleep() describes and then costs a broadphase-overlap scan per sub-step. It
//    wakes before it steps when a candidate body (a broadphase overlap of its proxy) is new,
//    has left, moves faster than v = sleep.distance / sleep.time (1 mm/s by default) or
//    has moved or turned by more than v times the step since the last sub-step; when an
//    attachment's body moves; when the world's gravity changes. It stays awake while it pushes an
//    active dynamic body (a body resting on a sleeping cloth would lose its support).
//
// Units are the world's (metres, kilograms, seconds when the scene is in SI). Bullet is
// single precision; drape is double precision; values are converted at this boundary.
#pragma once

#include "drape/cloth.hpp"

#include <cstdint>
#include <memory>
#include <vector>

class btCollisionObject;
class btDynamicsWorld;
class btIDebugDraw;

namespace drape::bullet {

/// Contacts between cloth particles and rigid bodies.
struct ContactSettings {
    /// Distance a particle keeps from every body surface [m]. Particles nearer than this are
    /// projected out to it; it is the cloth's collision thickness. Must be > 0.
    double thickness = 0.01;
    /// Width of the band above `thickness` in which eq. (7)'s penalty force acts [m].
    /// Negative means "equal to thickness".
    double penaltyBand = -1.0;
    /// C_p of eq. (7): the most the penalty pushes a particle at the bottom of the band [N].
    /// It slows particles coming down into the band and holds them where it can carry their
    /// load (a cloth landing on a body rests inside the band), but against static and kinematic
    /// bodies it never pushes more than stops the particle: a cloth placed at the thickness
    /// stays there. Negative means "twice the particle's weight under the cloth's gravity"; 0
    /// turns the penalty off (particles then rest at the thickness).
    double penaltyForce = -1.0;
    /// Multiplies the body's btCollisionObject friction coefficient (Coulomb mu) [-].
    double frictionScale = 1.0;
    /// Ray-test the path of particles that moved more than `thickness` in a step, so that a
    /// fast particle does not pass through a thin body between two steps.
    bool continuous = true;
    /// Also keep the cloth's triangles (their edges and interiors) `thickness` away from
    /// convex bodies and the convex children of compounds, so that a feature thinner than the
    /// particle spacing (a rod, a box's edge) cannot pass between particles. The response is
    /// shared among the triangle's particles by their barycentric weights, two-way with dynamic
    /// bodies. Off by default: it costs a box test per triangle and body near the cloth, and
    /// a GJK query per triangle within reach of a body that not all its particles touch.
    bool triangles = false;
    /// Margin added around the cloth's bounding box for its broadphase proxy [m]. Negative
    /// means "the cloth's mean spring rest length plus four thicknesses".
    double broadphaseMargin = -1.0;
};

/// Collision of the cloth's particles with its own triangles (the paper's particle-triangle
/// collision of the fabric with itself). Off unless `enabled`; costs nothing when off.
struct SelfCollisionSettings {
    bool enabled = false;    ///< run the self-collision pass
    double thickness = 0.01; ///< distance a particle keeps from the cloth's other triangles [m]
    int iterations = 2;      ///< passes over all particle-triangle pairs per step (>= 1)
    double friction = 0.2;   ///< Coulomb mu between layers of the cloth [-]
};

/// How a cloth joins a world.
struct BulletClothSettings {
    ContactSettings contact;             ///< particle-body contacts
    SelfCollisionSettings selfCollision; ///< particle-triangle self-collision
    /// Cloth steps per internal Bullet sub-step (>= 1): a stiff cloth can run at
    /// fixedTimeStep / substeps while the rigid bodies keep the world's step.
    int substeps = 1;
    /// Use the world's gravity for the cloth (copied when it is added and whenever the world's
    /// changes). drape's default gravity is -9.81 m/s^2 along y, Bullet's is -10.
    bool useWorldGravity = true;
    /// Broadphase filter group and mask of the cloth's proxy (Bullet's collision filtering).
    int collisionGroup = 1; ///< btBroadphaseProxy::DefaultFilter
    int collisionMask = -1; ///< btBroadphaseProxy::AllFilter
    /// Turn the cloth's sleeping on when it is added (with the thresholds of its
    /// ClothSettings::sleep); false leaves the cloth's own setting.
    bool sleep = true;
};

/// Work done in the last Bullet sub-step (all cloth sub-steps summed). Counts, not times, so
/// tests can check that the broadphase is used.
struct ContactStats {
    std::size_t candidateBodies = 0;    ///< bodies among the proxy's broadphase overlaps
    std::size_t particleBoxTests = 0;   ///< particle against body-AABB rejection tests
    std::size_t narrowphaseQueries = 0; ///< closest-point queries against body shapes
    std::size_t rayQueries = 0;         ///< continuous (swept) ray tests
    std::size_t triangleQueries = 0;    ///< triangle-body GJK queries (contact.triangles)
    std::size_t triangleContacts = 0;   ///< triangle-body contacts that moved a triangle
    /// Particle-body contacts: particles touching a body (projected, or resting at the
    /// thickness) or, with eq. (7) on, inside its band; once per particle and body per cloth
    /// step, summed over the sub-steps.
    std::size_t contacts = 0;
    std::size_t projections = 0;   ///< contacts that moved a particle out of a body
    std::size_t selfContacts = 0;  ///< particle-triangle self contacts resolved
    std::size_t selfPairTests = 0; ///< particle-triangle pairs tested by self-collision
    /// Total linear impulse the cloth gave dynamic bodies, through contacts and through
    /// attachments [N s].
    Vec3 impulseOnBodies = Vec3::Zero();
    /// Total linear impulse bodies (static, kinematic and dynamic) gave the cloth through
    /// contacts: velocity response, friction and contact forces over the step [N s]. With only
    /// dynamic bodies and no attachments it is exactly -impulseOnBodies.
    Vec3 impulseOnCloth = Vec3::Zero();
    std::uint64_t steps = 0; ///< cloth steps taken by this handle since it was added
    /// Sub-steps in which the cloth would have swept out of its proxy, so the proxy was moved
    /// and the broadphase queried directly (btBroadphaseInterface::aabbTest).
    std::size_t proxyRefreshes = 0;
};

/// A particle held at a point fixed in a body's frame.
struct Attachment {
    Index particle = 0;                      ///< cloth particle
    const btCollisionObject* body = nullptr; ///< the body it is fixed to
    Vec3 localPoint = Vec3::Zero();          ///< point in the body's frame [m]
};

/// A cloth added to a Bullet world. Created by addCloth; removed from the world by
/// removeCloth or by its destructor. Remove it (or destroy it) before the world, and detach
/// particles from a body before removing that body from the world. Stepping the cloth
/// directly (Cloth::step) while it is in a world runs no contacts: the world steps it.
class BulletCloth {
  public:
    /// Prefer addCloth(). Throws drape::Error on a null world or cloth or bad settings.
    BulletCloth(btDynamicsWorld* world, std::shared_ptr<Cloth> cloth,
                const BulletClothSettings& settings);
    ~BulletCloth();
    BulletCloth(const BulletCloth&) = delete;
    BulletCloth& operator=(const BulletCloth&) = delete;

    /// Takes the cloth out of the world (its proxy, its action, its stage). Idempotent.
    void remove();
    /// True between construction and remove().
    bool inWorld() const;

    // --- attachments ------------------------------------------------------------------------
    /// Fixes particle i to `body` at `localPoint` (body frame) [m]. The particle follows the
    /// body; for a dynamic body the cloth's force on the particle is applied to the body.
    /// Throws drape::Error on an index out of range, a null body or a non-finite point.
    void attach(Index particle, const btCollisionObject* body, const Vec3& localPoint);
    /// Fixes particle i to `body` where both are now.
    void attachHere(Index particle, const btCollisionObject* body);
    /// Frees particle i (it keeps its position and velocity). No-op if it is not attached.
    void detach(Index particle);
    const std::vector<Attachment>& attachments() const;

    // --- access -----------------------------------------------------------------------------
    Cloth& cloth();
    const Cloth& cloth() const;
    const std::shared_ptr<Cloth>& clothPtr() const;
    const BulletClothSettings& settings() const;
    /// The broadphase proxy's owner (a ghost object with no contact response).
    const btCollisionObject* proxyObject() const;
    /// Counts of the last Bullet sub-step.
    const ContactStats& lastStats() const;
    /// Counts summed since the cloth was added.
    const ContactStats& totalStats() const;
    /// Draws the cloth's triangles with the world's debug drawer conventions.
    void debugDraw(btIDebugDraw* drawer) const;

    /// Steps the cloth once by dt [s] as the world would in a sub-step (snapshot bodies, step
    /// the cloth `substeps` times, apply impulses, move the proxy). Called by the world;
    /// public for tests and for worlds that want to drive the cloth themselves.
    void stepInWorld(double dt);

    struct Impl;

  private:
    std::unique_ptr<Impl> impl_;
};

/// Adds `cloth` to `world`: one call. The world then steps it in every internal sub-step of
/// stepSimulation. Throws drape::Error (InvalidArgument) on a null world or cloth, and on
/// invalid settings (non-positive thickness, substeps < 1 ...).
///
/// A cloth step that fails (for example a fixedTimeStep / substeps beyond the cloth's
/// stability limit, see Cloth::stableTimeStep) throws its drape::Error out of
/// stepSimulation; the cloth keeps its state from before that step. Choose substeps so that
/// fixedTimeStep / substeps <= cloth.stableTimeStep().
std::unique_ptr<BulletCloth> addCloth(btDynamicsWorld* world, std::shared_ptr<Cloth> cloth,
                                      const BulletClothSettings& settings = {});

/// Removes the cloth from its world: one call. The handle stays valid (the cloth keeps its
/// state) and can be destroyed later.
void removeCloth(BulletCloth& cloth);

} // namespace drape::bullet
