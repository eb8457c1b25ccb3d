// Attachments as kinematic targets set before every Bullet sub-step (see attachments.hpp).
#include "attachments.hpp"

#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <cstdint>

namespace drape::bullet::detail {

namespace {
/// The snapshot of body `o` among `bodies`, or null (a body outside the proxy).
BodySnapshot* snapshotOf(std::vector<BodySnapshot>& bodies, const btCollisionObject* o) {
    const auto it = std::find_if(bodies.begin(), bodies.end(),
                                 [&](const BodySnapshot& b) { return b.object == o; });
    return it == bodies.end() ? nullptr : &*it;
}
} // namespace

Vec3 attachmentPoint(const Attachment& a) {
    return toPose(a.body->getWorldTransform()).toWorld(a.localPoint);
}

void Attachments::attach(Cloth& c, const Attachment& a) {
    detach(c, a.particle);
    list_.push_back(a);
    tethersValid_ = false;
    c.setKinematicTarget(a.particle, attachmentPoint(a), c.time()); // there now
}

void Attachments::detach(Cloth& c, Index particle) {
    for (std::size_t k = 0; k < list_.size(); ++k) {
        if (list_[k].particle != particle) continue;
        c.unpin(particle);
        list_.erase(list_.begin() + static_cast<std::ptrdiff_t>(k));
        tethersValid_ = false;
        return;
    }
}

void Attachments::clear(Cloth& c) {
    for (const auto& a : list_)
        c.unpin(a.particle);
    list_.clear();
    tethersValid_ = false;
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
        if (BodySnapshot* snap = snapshotOf(bodies, a.body)) {
            snap->applyImpulse(j, at);
        } else {
            // The body is outside the proxy (possible with a long attachment).
            outside.push_back(OutsideImpulse{const_cast<btRigidBody*>(rb), j, at});
        }
    }
}

void Attachments::holdTethers(const Cloth& c, double dt, std::vector<BodySnapshot>& bodies) {
    if (list_.size() < 2 || !(dt > 0.0)) return;
    if (!tethersValid_) {
        tethers_.clear();
        std::vector<std::int64_t> of(c.particleCount(), -1);
        for (std::size_t k = 0; k < list_.size(); ++k)
            if (list_[k].particle < of.size()) of[list_[k].particle] = std::int64_t(k);
        const auto& springs = c.topology().springs();
        for (std::size_t s = 0; s < springs.size(); ++s) {
            const std::int64_t ka = of[springs[s].a], kb = of[springs[s].b];
            if (ka < 0 || kb < 0) continue;
            const Attachment &A = list_[std::size_t(ka)], &B = list_[std::size_t(kb)];
            if (A.body == B.body) continue; // (whether either is dynamic is asked each step)
            tethers_.push_back(Tether{Index(s), std::size_t(ka), std::size_t(kb)});
        }
        tethersValid_ = true;
    }
    if (tethers_.empty()) return;
    const auto& springs = c.topology().springs();
    const Vec3List& x = c.positions();
    const double limit = 1.0 + c.settings().limiter.maxStrain;
    for (const Tether& t : tethers_) {
        BodySnapshot* A = snapshotOf(bodies, list_[t.a].body);
        BodySnapshot* B = snapshotOf(bodies, list_[t.b].body);
        if (!A || !B) continue; // a body outside the proxy: left to the free particles' pulls
        const Spring& sp = springs[t.spring];
        const Vec3 pa = x[list_[t.a].particle], pb = x[list_[t.b].particle];
        const Vec3 d = pb - pa;
        const double l = d.norm(), beyond = l - limit * sp.restLength;
        if (!(beyond > 0.0)) continue;
        const Vec3 u = d / l;
        // Its ends' separation speed, plus the stretch beyond the limit taken back in one step
        // (at most kTetherCatchUp of the rest length per step: a post teleported away is
        // pulled back over many steps, not thrown).
        const double catchUp = std::min(beyond, kTetherCatchUp * sp.restLength) / dt;
        const double apart = (B->velocityAt(pb) - A->velocityAt(pa)).dot(u) + catchUp;
        const double k = A->inverseMassAlong(pa, u) + B->inverseMassAlong(pb, u);
        if (!(apart > 0.0) || !(k > 0.0)) continue;
        const Vec3 j = (apart / k) * u;
        A->applyImpulse(j, pa);
        B->applyImpulse(-j, pb);
    }
}

} // namespace drape::bullet::detail
