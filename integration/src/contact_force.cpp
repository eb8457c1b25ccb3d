// The contact force term (see contact_force.hpp).
#include "contact_force.hpp"

namespace drape::bullet::detail {

double penaltyShape(double gap, double band) {
    if (gap >= band) return 0.0;
    const double g = std::max(gap, 0.0);
    return (std::exp(1.0 - g / band) - 1.0) / (kE - 1.0);
}

void ContactForce::operator()(const Vec3List& x, const Vec3List& v, Vec3List& f) const {
    ContactState& state = *state_;
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

} // namespace drape::bullet::detail
