// body_snapshot.hpp (private to drape::bullet): a rigid body as the cloth sees it during one
// Bullet sub-step, in double precision: pose, velocities, inverse mass and inertia, friction,
// and the impulses the cloth gives it, applied to the Bullet body after the cloth's steps.
#pragma once

#include "pose.hpp"

#include "drape/strain_limit.hpp"

#include <cstdint>
#include <utility>
#include <vector>

class btCollisionObject;
class btCollisionShape;
class btRigidBody;
class btDispatcher;
class btDynamicsWorld;

namespace drape::bullet::detail {

/// No body leaves a contact with the cloth faster than twice the fastest thing in it: an elastic
/// bounce off an infinitely heavy wall (applyAccumulatedImpulses).
constexpr double kRefusedSpeedFactor = 2.0;
/// A supported body takes the cloth's weight on it and this much more (the cloth's sway) in
/// one Bullet sub-step (applyAccumulatedImpulses).
constexpr double kWeightShare = 1.25;

/// A rigid body as the cloth sees it during one Bullet sub-step.
struct BodySnapshot {
    const btCollisionObject* object = nullptr;
    btRigidBody* dynamicBody = nullptr; ///< non-null when the cloth pushes the body back
    Pose pose;
    Vec3 aabbMin = Vec3::Zero(), aabbMax = Vec3::Zero(); ///< world AABB grown by the reach
    Vec3 com = Vec3::Zero();
    Vec3 v = Vec3::Zero(), w = Vec3::Zero(); ///< velocities, updated by the cloth's impulses
    double invMass = 0.0;
    /// World frame; for a body that spins more easily than the cloth can resolve, the one
    /// limitSpin leaves (the same as Bullet's otherwise).
    Eigen::Matrix3d invInertia = Eigen::Matrix3d::Zero();
    /// What of a torque impulse the body takes (limitSpin: identity unless it limits the spin).
    Eigen::Matrix3d spinFilter = Eigen::Matrix3d::Identity();
    double friction = 0.0;
    /// A static plane (btStaticPlaneShape): its world normal and offset, nW . x - offset being
    /// the signed distance, for the cheap rejection of particles far above it (its AABB is
    /// infinite, so the box test passes every particle).
    bool plane = false;
    Vec3 planeNormal = Vec3::UnitY();
    double planeOffset = 0.0;
    double planeScale = 0.0; ///< |offset| + |t|: the size of the numbers in the distance [m]
    /// A box (btBoxShape): its half extents with the margin and the world normals of its faces,
    /// (R n).normalized() for the local face normals n = +e_k (index 2k) and -e_k (2k + 1),
    /// as the closest-point query would compute them for every particle (boxSurface).
    bool box = false;
    Vec3 boxHalf = Vec3::Zero();
    Vec3 boxFaceNormal[6];
    /// v and w are zero (a static body, a resting one): the velocity at every point is v.
    bool still = true;
    /// The fastest a cloth particle touching the body moved relative to it in the sub-step
    /// [m/s]: a sleeping body is woken when this reaches its linear sleeping threshold (a cloth
    /// pushed across it moves), not only by impulses that large.
    double contactSpeed = 0.0;
    /// A dynamic body that a chain of Bullet contacts (manifolds with points) through dynamic
    /// bodies joins to a static or kinematic body: Bullet's solver holds its position, so the
    /// cloth moves it only through impulses (a cloth pushing a box on the floor into the floor
    /// would make Bullet push it back out with energy). A free one (a projectile, a thrown
    /// ball, items resting only on each other on a net) ends the Bullet sub-step where its
    /// sweep through the cloth's steps took it.
    bool supported = false;
    /// Gravity's direction (unit; zero without gravity) and a supported body's speed along it
    /// as Bullet left it: the cloth's impulses do not take it down faster.
    Vec3 down = Vec3::Zero();
    double supportedDownSpeed = 0.0;
    /// How many times lighter the limiter's walks count it (ContactPlanes::Mover::lighten),
    /// kept from one cloth sub-step's walks to the next through the world step (a snapshot
    /// starts every world step at 1).
    double lighten = 1.0;
    /// Particles of the cloth are attached to it: it moves them as kinematic targets.
    bool attached = false;
    /// Attached, dynamic and not supported, with every joint it is in giving its rows
    /// (jointRows): it carries its attached particles in the limiter's walk
    /// (ContactPlanes::carry), moving only as its joints let it, and they follow its snapshot
    /// through the Bullet sub-step. Any other attachment body moves them along Bullet's path
    /// only and does not give way in the walk (a joint the walk did not know held the banner's
    /// posts back against what the walk moved).
    bool carrier = false;
    /// A carrier in joints: the rows its joints keep and how far their other bodies give
    /// (drape::JointRows), which restrict how it gives way in the walk and what it takes after
    /// it (constrainToJoints). Empty for a free one.
    JointRows joints;
    /// Of its weight, what Bullet gives the body alone as its joints let it (the share of
    /// constrainToJoints for the body without its particles: 1 - J^T (J W J^T)^+ J W).
    Eigen::Matrix<double, 6, 6> jointedWeight = Eigen::Matrix<double, 6, 6>::Identity();
    /// The pose at the end of the Bullet sub-step (Bullet's answer, at the velocities it had).
    Pose end;
    /// Where the body was at the start of the current cloth step (pose: at its end).
    Pose previous;
    /// The body moves through the Bullet sub-step while the cloth steps: startSweep puts it
    /// where it was dt [s] before `end`, and each cloth step of h [s] advances it at its
    /// velocities, which the cloth's impulses change on the way (a body the cloth stops, stops
    /// there). A free body the cloth gave impulses to ends where the sweep took it
    /// (applyAccumulatedImpulses).
    void startSweep(double dt);
    void advance(double h);
    /// Moves the body by `shift` [m] and turns it by `turn` [rad] about its centre of mass
    /// (where the limiter's walk pushed a body that gives way: ContactPlanes::Mover).
    void displace(const Vec3& shift, const Vec3& turn);
    /// displace() out of particles a static or kinematic body holds from behind (solveHeld):
    /// the body ends there even when it rests on something (supported), which would otherwise
    /// keep it where Bullet put it (a crate spawned standing on the floor through a rug).
    void liftOut(const Vec3& shift) {
        displace(shift, Vec3::Zero());
        liftedOut_ = dynamicBody != nullptr;
    }
    /// Whether the body moves through the cloth's steps (else pose == previous == end).
    bool sweeps() const { return sweeping_ || moved_; }
    Vec3 linearImpulse = Vec3::Zero();  ///< accumulated for the body [N s]
    Vec3 angularImpulse = Vec3::Zero(); ///< about the centre of mass [N m s]

    Vec3 velocityAt(const Vec3& p) const { return still ? v : Vec3(v + w.cross(p - com)); }
    /// Inverse effective mass of the body at p along unit direction d.
    double inverseMassAlong(const Vec3& p, const Vec3& d) const {
        if (!dynamicBody) return 0.0;
        const Vec3 rxd = (p - com).cross(d);
        return invMass + rxd.dot(invInertia * rxd);
    }
    /// A linear impulse [N s] and an angular one about its centre of mass [N m s]. A supported
    /// body does not go down under it faster than Bullet moved it (its supports hold it, which
    /// only Bullet's solver knows; they get the impulse after the cloth's steps). (Moved down
    /// by the impulses on the way, a light box under a heavy cloth sank away under the step's
    /// weight, its particles followed it into where Bullet held it, and the next step pushed
    /// them out: a 2 kg cloth on a 0.2 kg box sank 0.29 m into it and threw it 9 m up.)
    void applyImpulseAboutCentre(const Vec3& linear, const Vec3& angular) {
        if (!dynamicBody) return;
        linearImpulse += linear;
        angularImpulse += angular;
        v += invMass * linear;
        if (supported) v -= std::max(0.0, v.dot(down) - supportedDownSpeed) * down;
        w += invInertia * angular;
        still = false;
        moved_ = true;
    }
    /// An impulse j [N s] at point p.
    void applyImpulse(const Vec3& j, const Vec3& p) {
        applyImpulseAboutCentre(j, (p - com).cross(j));
    }
    /// Gives the Bullet body the impulses accumulated on it. A sleeping body is woken only by
    /// an impulse that changes its velocity by its linear sleeping threshold, or by a cloth
    /// that moves against it at that speed (contactSpeed); a cloth settling on it does not. Returns
    /// whether the cloth pushed an active body (the cloth then must not sleep: a body resting on it
    /// would lose its support). Refuses them (sets `refused`, gives nothing) when they would
    /// leave a point of the body moving more than kRefusedSpeedFactor times faster than
    /// anything in the contact: the body's fastest point before, `clothSpeed` (the cloth's
    /// fastest particle before the sub-step [m/s]) and `floorSpeed` (1 m/s, in the world's
    /// length unit: BulletClothSettings::unitsPerMetre). A cloth throws a body at most twice
    /// as fast as it moves itself (an elastic bounce off a heavy wall), or, caught and thrown
    /// back by the strain limiter, as fast as the body came; what goes beyond is the limiter's
    /// walk pushing a body wedged between particles out of the hole
    /// (ContactStats::refusedBodyImpulses).
    /// A supported body may also take kWeightShare times the cloth's whole weight over the
    /// Bullet sub-step (`clothWeight`: the cloth's mass times gravity times the sub-step
    /// [N s]): its supports carry it (a 20 kg cloth resting on a 0.2 kg box).
    bool applyAccumulatedImpulses(double clothSpeed, double floorSpeed, double clothWeight);
    bool refused = false;

  private:
    bool sweeping_ = false;  ///< startSweep found it moving
    bool moved_ = false;     ///< impulses or displacements changed its sweep
    bool liftedOut_ = false; ///< liftOut moved it
};

/// Snapshots `object` if the cloth collides with it (rigid bodies and collision objects with
/// contact response; not ghosts, such as other cloths' proxies and triggers, soft bodies or
/// multibodies): its AABB grown by `reach` [m] and by where it came from in the sub-step of
/// dt [s] (at its velocities), its friction times `frictionScale`. Throws drape::Error when its
/// friction is negative or not finite. `at`, when given, is the body's pose in place of its
/// world transform (a kinematic body followed through the frame's sub-steps, followKinematic).
bool snapshotBody(const btCollisionObject* object, double reach, double frictionScale,
                  BodySnapshot& out, double dt, const Pose* at = nullptr);

/// A character: a ghost object flagged btCollisionObject::CF_CHARACTER_OBJECT, as Bullet's
/// btKinematicCharacterController's is. The cloth collides with it as with a kinematic body
/// whose velocities are its move since the last sub-step (moveCharacter); other ghosts
/// (triggers, other cloths' proxies) it passes through.
bool isCharacter(const btCollisionObject* object);

/// A character's snapshot `b` (at its pose now) moved from `before` within the sub-step of dt
/// [s]: its velocities that move, and its box grown over the way.
void moveCharacter(BodySnapshot& b, const Pose& before, double dt);

/// A kinematic body (a snapshot of one, or of a character) whose fastest point moved faster than
/// `speed` [m/s], or that turned by more than `turn` [rad], in the sub-step of dt [s] is taken as
/// put where it is: no velocities, no way swept in the sub-step (its box `reach` [m] round where it
/// is). Bullet gives a kinematic body whose motion state the program set in one go the velocity of
/// that jump over the sub-step. Either limit 0: not tested. Returns whether it was taken so.
bool holdIfJumped(BodySnapshot& b, double dt, double speed, double turn, double reach);

/// An elongated dynamic body (4 times lighter about an axis than about its heaviest one) that is
/// lighter about that axis than a ring of radius `gyration` [m] of its mass (a
/// rod or bar thinner than the cloth's spacing, about its own axis) is treated as that ring
/// about that axis: its inverse inertia is capped at 1 / (m gyration^2) there, and the torque
/// impulses the cloth gives it are filtered to match (spinFilter). The cloth resolves levers
/// only down to its spacing: pushes a fraction of a millimetre off such a body's axis, added
/// up over a walk, spun it by more than half a turn (refused, and the body passed). The spin
/// about that axis the cloth would have given it is not given (angular momentum about it is
/// not conserved); everything else is unchanged.
void limitSpin(BodySnapshot& b, double gyration);

/// Sets BodySnapshot::supported of the dynamic bodies: joined to a static or kinematic body
/// by a chain of the dispatcher's contact manifolds with points, through dynamic bodies, all
/// with contact response.
void markSupported(btDispatcher& dispatcher, std::vector<BodySnapshot>& bodies);

/// What the enabled joints of `world` keep of `body`'s motion (Bullet's own Jacobian rows, from
/// getInfo1 and getInfo2 at the step dt [s]), and how far their other bodies give way along
/// them: a dynamic one as its own other joints let it, those held still. Rows a bounded impulse
/// drives (a motor, friction) are left out: they give way. Returns false when a joint of the
/// body gives no rows this way (an old-style constraint) or joins it to a body of `inWalk`
/// (sorted: the other bodies the cloth's walk moves, whose joint the walk would not keep).
bool jointRows(btDynamicsWorld& world, const btRigidBody& body, double dt,
               const std::vector<const btCollisionObject*>& inWalk, JointRows& out);

/// The candidate bodies and their poses at the previous sub-step, for waking a sleeping cloth.
class BodyPoses {
  public:
    /// Whether a body is new or gone since the last record, or moves: farther or faster than
    /// the speed `tol` [m/s] carries a point within dt (turning measured at its extent); or its
    /// shape changed (another shape, a compound's children added, removed or moved at any
    /// depth, or its extent grew or shrank that much: setLocalScaling),
    /// or its friction did (setFriction: a cloth at rest on a slope may slide). Only bodies
    /// whose box (grown by the contact reach, over its way in the sub-step), grown again by
    /// `spring` [m] (the cloth's longest spring: a thin body can touch a triangle or a spring
    /// between particles), holds a particle of `x`, now or at the last record, count: one that
    /// came, went or moved beside the cloth touched nothing and held nothing up.
    bool changed(const std::vector<BodySnapshot>& bodies, double tol, double dt,
                 const std::vector<Vec3>& x, double spring) const;
    void record(const std::vector<BodySnapshot>& bodies);

  private:
    struct Last {
        const btCollisionObject* object;
        const btCollisionShape* shape;
        std::uint64_t revision; ///< shapeRevision of the shape
        Pose pose;
        Vec3 extent;     ///< the world AABB's size
        double friction; ///< BodySnapshot::friction
        Vec3 lo, hi;     ///< BodySnapshot::aabbMin, aabbMax
    };
    std::vector<Last> last_;
};

} // namespace drape::bullet::detail
