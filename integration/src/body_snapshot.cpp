// Body snapshots (see body_snapshot.hpp).
#include "body_snapshot.hpp"

#include "validate.hpp"

#include "drape/error.hpp"

#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <cmath>
#include <string>

namespace drape::bullet::detail {
bool snapshotBody(const btCollisionObject* obj, double reach, double frictionScale,
                  BodySnapshot& b) {
    const int type = obj->getInternalType();
    if (type != btCollisionObject::CO_RIGID_BODY && type != btCollisionObject::CO_COLLISION_OBJECT)
        return false; // ghosts (other cloths' proxies, triggers), soft bodies, multibodies
    if (!obj->hasContactResponse() || !obj->getCollisionShape()) return false;
    b = BodySnapshot{};
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
    b.friction = mu * frictionScale;
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
    if (obj->getCollisionShape()->getShapeType() == BOX_SHAPE_PROXYTYPE) {
        const auto* bs = static_cast<const btBoxShape*>(obj->getCollisionShape());
        b.box = true;
        b.boxHalf = toVec(bs->getHalfExtentsWithMargin());
        for (int k = 0; k < 3; ++k) {
            for (int side = 0; side < 2; ++side) {
                Vec3 n = Vec3::Zero();
                n[k] = side == 0 ? 1.0 : -1.0;
                b.boxFaceNormal[2 * k + side] = (b.pose.R * n).normalized();
            }
        }
    }
    if (const btRigidBody* rb = btRigidBody::upcast(obj)) {
        b.v = toVec(rb->getLinearVelocity());
        b.w = toVec(rb->getAngularVelocity());
        b.still = b.v == Vec3::Zero() && b.w == Vec3::Zero();
        if (!rb->isStaticOrKinematicObject() && rb->getInvMass() > 0.0f) {
            b.dynamicBody = const_cast<btRigidBody*>(rb); // impulses are applied after the step
            b.invMass = double(rb->getInvMass());
            b.invInertia = toMat(rb->getInvInertiaTensorWorld());
        }
    }
    return true;
}

bool BodySnapshot::applyAccumulatedImpulses() {
    if (!dynamicBody) return false;
    if (linearImpulse.squaredNorm() == 0.0 && angularImpulse.squaredNorm() == 0.0) return false;
    btRigidBody* rb = dynamicBody;
    const bool pushedActive = rb->isActive();
    // A sleeping body is not woken by nudges below its sleeping threshold.
    const double dv = linearImpulse.norm() * invMass;
    const double threshold = double(rb->getLinearSleepingThreshold());
    if (!rb->isActive() && dv < threshold && contactSpeed < threshold) return pushedActive;
    rb->applyCentralImpulse(toBt(linearImpulse));
    rb->applyTorqueImpulse(toBt(angularImpulse));
    // Only a sleeping body is woken: activate() on an awake one would restart its
    // deactivation time, and a body the cloth rests on could never fall asleep. An awake body
    // that the cloth's impulse leaves below its sleeping thresholds sleeps as Bullet decides.
    if (!pushedActive) rb->activate();
    return pushedActive;
}

bool BodyPoses::changed(const std::vector<BodySnapshot>& bodies, double tol, double dt) const {
    if (bodies.size() != last_.size()) return true;
    for (const BodySnapshot& b : bodies) {
        const auto was = std::find_if(last_.begin(), last_.end(),
                                      [&](const auto& p) { return p.first == b.object; });
        if (was == last_.end()) return true; // a new candidate
        const Pose& pose = was->second;
        // Turning is measured at the body's extent (its AABB's half diagonal; an infinite
        // plane turns only when its pose changes at all).
        const double radius = 0.5 * (b.aabbMax - b.aabbMin).norm();
        const double turn = (b.pose.R - pose.R).cwiseAbs().maxCoeff();
        if ((b.pose.t - pose.t).norm() > tol * dt || (turn > 0.0 && !(turn * radius <= tol * dt)) ||
            b.v.norm() > tol || (b.w.norm() > 0.0 && !(b.w.norm() * radius <= tol)))
            return true;
    }
    return false;
}

void BodyPoses::record(const std::vector<BodySnapshot>& bodies) {
    last_.resize(bodies.size());
    for (std::size_t k = 0; k < bodies.size(); ++k)
        last_[k] = {bodies[k].object, bodies[k].pose};
}

} // namespace drape::bullet::detail
