// body_snapshot.hpp (private to drape::bullet): a rigid body as the cloth sees it during one
// Bullet sub-step, in double precision: pose, velocities, inverse mass and inertia, friction,
// and the impulses the cloth gives it, applied to the Bullet body after the cloth's steps.
#pragma once

#include "pose.hpp"

#include <utility>
#include <vector>

class btCollisionObject;
class btRigidBody;

namespace drape::bullet::detail {

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
    Vec3 linearImpulse = Vec3::Zero();  ///< accumulated for the body [N s]
    Vec3 angularImpulse = Vec3::Zero(); ///< about the centre of mass [N m s]

    Vec3 velocityAt(const Vec3& p) const { return still ? v : Vec3(v + w.cross(p - com)); }
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
        still = false;
    }
    /// Gives the Bullet body the impulses accumulated on it. A sleeping body is woken only by
    /// an impulse that changes its velocity by its linear sleeping threshold, or by a cloth
    /// that moves against it at that speed (contactSpeed); a cloth settling on it does not. Returns
    /// whether the cloth pushed an active body (the cloth then must not sleep: a body resting on it
    /// would lose its support).
    bool applyAccumulatedImpulses();
};

/// Snapshots `object` if the cloth collides with it (rigid bodies and collision objects with
/// contact response; not ghosts, such as other cloths' proxies and triggers, soft bodies or
/// multibodies): its AABB grown by `reach` [m], its friction times `frictionScale`. Throws
/// drape::Error when its friction is negative or not finite.
bool snapshotBody(const btCollisionObject* object, double reach, double frictionScale,
                  BodySnapshot& out);

/// The candidate bodies and their poses at the previous sub-step, for waking a sleeping cloth.
class BodyPoses {
  public:
    /// Whether a body is new or gone since the last record, or moves: farther or faster than
    /// the speed `tol` [m/s] carries a point within dt (turning measured at its extent).
    bool changed(const std::vector<BodySnapshot>& bodies, double tol, double dt) const;
    void record(const std::vector<BodySnapshot>& bodies);

  private:
    std::vector<std::pair<const btCollisionObject*, Pose>> last_;
};

} // namespace drape::bullet::detail
