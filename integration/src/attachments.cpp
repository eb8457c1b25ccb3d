// Attachments as kinematic targets set before every Bullet sub-step (see attachments.hpp).
#include "attachments.hpp"

#include <btBulletDynamicsCommon.h>

#include <algorithm>

namespace drape::bullet::detail {

Vec3 attachmentPoint(const Attachment& a) {
    return toPose(a.body->getWorldTransform()).toWorld(a.localPoint);
}

void Attachments::attach(Cloth& c, const Attachment& a) {
    detach(c, a.particle);
    list_.push_back(a);
    c.setKinematicTarget(a.particle, attachmentPoint(a), c.time()); // there now
}

void Attachments::detach(Cloth& c, Index particle) {
    for (std::size_t k = 0; k < list_.size(); ++k) {
        if (list_[k].particle != particle) continue;
        c.unpin(particle);
        list_.erase(list_.begin() + static_cast<std::ptrdiff_t>(k));
        return;
    }
}

void Attachments::clear(Cloth& c) {
    for (const auto& a : list_)
        c.unpin(a.particle);
    list_.clear();
}

void Attachments::advance(Cloth& c, double dt) const {
    const double arrival = c.time() + dt;
    for (const auto& a : list_)
        c.setKinematicTarget(a.particle, attachmentPoint(a), arrival);
}

void Attachments::pushBodies(const Cloth& c, double h, std::vector<BodySnapshot>& bodies,
                             ContactStats& stats, std::vector<OutsideImpulse>& outside) const {
    // The body carries the force the cloth puts on the attached particle (springs and the
    // particle's own weight) and the strain limiter's reaction on it (its corrections' pull).
    const Vec3List& held = c.constraintImpulses();
    for (const auto& a : list_) {
        const btRigidBody* rb = btRigidBody::upcast(a.body);
        if (!rb || rb->isStaticOrKinematicObject() || rb->getInvMass() <= 0.0f) continue;
        const Vec3 j = c.forces()[a.particle] * h +
                       (a.particle < held.size() ? held[a.particle] : Vec3::Zero());
        const Vec3 at = c.positions()[a.particle];
        stats.impulseOnBodies += j;
        auto snap = std::find_if(bodies.begin(), bodies.end(),
                                 [&](const BodySnapshot& b) { return b.object == a.body; });
        if (snap != bodies.end()) {
            snap->applyImpulse(j, at);
        } else {
            // The body is outside the proxy (possible with a long attachment).
            outside.push_back(OutsideImpulse{const_cast<btRigidBody*>(rb), j, at});
        }
    }
}

} // namespace drape::bullet::detail
