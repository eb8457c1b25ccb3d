// drape/bullet/bullet_cloth.hpp: a drape::Cloth living in a Bullet dynamics world.
//
//   auto cloth = std::make_shared<drape::Cloth>(topology, clothSettings);
//   auto handle = drape::bullet::addCloth(world, cloth);       // one call in
//   world->stepSimulation(dt, maxSubSteps, fixedTimeStep);      // steps bodies and cloth
//   drape::bullet::removeCloth(*handle);                        // one call out
//
// How it fits into Bullet (see src/bullet_cloth.cpp and the files it lists for the details):
//  - The cloth is a btActionInterface, so btDiscreteDynamicsWorld steps it in every internal
//    sub-step, right after the rigid bodies have been integrated.
//  - It owns a broadphase proxy (a btGhostObject whose AABB is the cloth's bounding box plus a
//    margin). The rigid bodies a cloth may touch are the ghost's broadphase overlaps, and the
//    bodies fast enough to cross its box within a sub-step: the world's kinematic and moving
//    bodies, listed in one pass over the world's objects per Bullet sub-step shared by all
//    the world's cloths (as Bullet's own step passes over them). The ghost never takes part in
//    narrow-phase, ray tests or contact generation of the world; it is in the broadphase, so
//    a game's own ghost objects and triggers list it among their overlaps. Its user pointer
//    is the BulletCloth handle (not a game entity; its shape's getName() is
//    "DrapeClothBounds"): give the cloth its own BulletClothSettings::collisionGroup and leave
//    it out of the trigger's mask, or skip objects that are a handle's proxyObject().
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
//    Cloth::isAsleep() describes and then costs a broadphase-overlap scan and a look at the
//    world's moving bodies per sub-step. It
//    wakes before it steps when a candidate body (a broadphase overlap of its proxy) is new,
//    has left, moves faster than v = sleep.distance / sleep.time (1 cm/s by default) or
//    has moved or turned by more than v times the step since the last sub-step, or has another
//    shape, a shape grown or shrunk by that much (setLocalScaling) or a compound shape whose
//    children were added, removed or moved (at any depth); when an attachment's body
//    moves; when the world's gravity changes. It stays awake while it pushes an
//    active dynamic body (a body resting on a sleeping cloth would lose its support).
//    A shape edited in place, which Bullet keeps no count of (a heightfield's height data, a
//    triangle mesh's vertices), is not seen: call Cloth::wake() after such an edit.
//
// Units are the world's (metres, kilograms, seconds when the scene is in SI). Bullet is
// single precision; drape is double precision; values are converted at this boundary.
#pragma once

#include "drape/bullet/settings.hpp"
#include "drape/cloth.hpp"

#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

class btCollisionObject;
class btDynamicsWorld;
class btIDebugDraw;

namespace drape::bullet {

/// A cloth added to a Bullet world. Created by addCloth; removed from the world by
/// removeCloth or by its destructor. Stepping the cloth directly (Cloth::step) while it is in
/// a world runs no contacts: the world steps it. Wrong uses that are caught:
/// - the world destroyed before the handle: inWorld() turns false, the handle's destructor
///   and remove() leave the (gone) world alone, and attach/stepInWorld throw drape::Error;
/// - a body removed from the world (or deleted) while particles are attached to it: the next
///   world step detaches those particles and throws drape::Error naming them (detach first;
///   a new body created at the freed body's address and added to the world is not told apart);
/// - the same cloth added to a second world (or twice): addCloth throws drape::Error;
/// - attaching to a body that is not in the cloth's world: attach throws drape::Error;
/// - the handle removed or destroyed inside its world's step (by a cloth's stage, a callback,
///   on the world's thread: not while the world steps its cloths in parallel,
///   BulletClothSettings::threads > 1): it leaves the world at once, the rest of the step
///   passes over it and its state is freed when the step ends (a cloth's own step finishes
///   the sub-step it was in); when it was the world's last cloth, the world's next action
///   misses that one sub-step;
/// - the proxy (proxyObject()) taken out of the world by the program: the next world step
///   throws drape::Error saying so, inWorld() turns false, later world steps pass over the
///   cloth (the rest of the world steps on), and remove() (with the world alive) takes the
///   cloth out; removing the handle before such a step, or after the world is destroyed, is
///   not safe.
class BulletCloth {
  public:
    /// Prefer addCloth(). Throws drape::Error on a null world or cloth or bad settings.
    BulletCloth(btDynamicsWorld* world, std::shared_ptr<Cloth> cloth,
                const BulletClothSettings& settings);
    ~BulletCloth();
    BulletCloth(const BulletCloth&) = delete;
    BulletCloth& operator=(const BulletCloth&) = delete;

    /// Takes the cloth out of the world (its proxy, its action, its stage). Idempotent. Its
    /// attachments go with it: the attached particles are free again (a cloth added again
    /// is attached again by the program).
    void remove();
    /// True between construction and remove(), while the world lives.
    bool inWorld() const;

    // --- attachments ------------------------------------------------------------------------
    /// Fixes particle i to `body` at `localPoint` (body frame) [m]. The particle follows the
    /// body; for a dynamic body the cloth's force on the particle is applied to the body, and
    /// the cloth holds the body within the particle's reach of the nearest particle held
    /// elsewhere (pinned, or attached to another body): (1 + maxStrain) times their rest
    /// path, as a rope (integration/README.md). Keep a dynamic body's effective mass at the
    /// attached points (its inertia through their lever arms counts) at least about 10 times
    /// the cloth's at a 60 Hz world step: lighter ones may swing about.
    /// A static or kinematic body that the program moves between attaching and the cloth's
    /// next step faster than a fifth of BulletClothSettings::teleportSpeed (10 m/s by default:
    /// a game that creates an NPC, attaches its cape, then sets it where it spawns) is placed:
    /// the cloth is carried there with its shape (ContactStats::teleports), not dragged as
    /// motion. Slower, and after that step, its motion is motion (teleportSpeed, teleportTurn).
    /// Throws drape::Error on an index out of range, a null body, a non-finite point, a body not
    /// in the cloth's world, or an object that is not a rigid body or collision object (a
    /// ghost object such as a cloth's proxyObject(), a soft body).
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
    /// Changes BulletClothSettings::timeStep (the exact double a matching Bullet sub-step is
    /// taken as), for a caller that steps the world with another dt. Throws drape::Error on a
    /// non-positive or non-finite value.
    void setTimeStep(std::optional<double> dt);
    /// The broadphase proxy's owner (a ghost object with no contact response).
    const btCollisionObject* proxyObject() const;
    /// Counts of the last Bullet sub-step.
    const ContactStats& lastStats() const;
    /// Counts summed since the cloth was added.
    const ContactStats& totalStats() const;
    /// Draws the cloth's springs (its triangles' edges) as lines, as Bullet draws a body: only
    /// when the drawer's debug mode has btIDebugDraw::DBG_DrawWireframe. The world's
    /// debugDrawWorld() draws every cloth so.
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
/// By default the cloth takes as many sub-steps per Bullet sub-step as its stability limit
/// asks (BulletClothSettings::substeps not given; a given count is sub-stepped further by
/// the cloth's own automatic sub-steps if it is not enough). A cloth step that fails (its
/// state stops being finite, a check of ClothSettings::failure, or a step that would need
/// more than substeps.maxSubsteps) throws its drape::Error out of stepSimulation; the cloth
/// keeps its state from before that step. The rigid bodies have moved in that Bullet
/// sub-step already (Bullet integrates them before it steps its actions), so the world is a
/// sub-step ahead of the cloth: catch the error to stop, or fix the cause (a smaller world
/// step, stiffer limits on substeps) and step on.
std::unique_ptr<BulletCloth> addCloth(btDynamicsWorld* world, std::shared_ptr<Cloth> cloth,
                                      const BulletClothSettings& settings = {});

/// Removes the cloth from its world: one call. The handle stays valid (the cloth keeps its
/// state, its attachments detached: BulletCloth::remove) and can be destroyed later.
void removeCloth(BulletCloth& cloth);

} // namespace drape::bullet
