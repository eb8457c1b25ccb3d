// The contact force term and eq. (7)'s penalty (see drape/contacts.hpp).
#include "drape/contacts.hpp"

namespace drape {

namespace {
constexpr double kE = 2.718281828459045;
}

double limitPenalty(double mass, double band, double dt, double& cp) {
    if (!(cp > 0.0)) return 0.0;
    // Keep the penalty spring (stiffness cp e / ((e - 1) w)) and its damping inside the
    // explicit stability limits of this step: k dt^2 / m <= 1, c dt / m <= 1/2.
    const double kMax = mass / (dt * dt);
    const double k = cp * kE / ((kE - 1.0) * band);
    if (k > kMax) cp *= kMax / k;
    return std::min(2.0 * std::sqrt(std::min(k, kMax) * mass), 0.5 * mass / dt);
}

double penaltyShape(double gap, double band) {
    if (gap >= band) return 0.0;
    const double g = std::max(gap, 0.0);
    return (std::exp(1.0 - g / band) - 1.0) / (kE - 1.0);
}

// For each record, the normal force N and the friction force T on its particle, added to f
// after every other term (so f holds the particle's other forces). With Velocity-Verlet this
// force acts in the closing half kick of the step that made the record and the opening half
// kick of the next one, that is, over one whole step dt between two collision stages. With v
// the half-step velocity the stage left, for a static or kinematic body:
//   N = min(eq. (7), hold),  hold = max(0, -f.n - m v_n / dt)
//       hold is the force that brings the normal relative velocity to zero within that step
//       (it cancels the push into the body and stops an approach; a particle leaving slowly
//       gets less than its load, so it comes back, and one leaving fast gets nothing);
//       eq. (7) (C_p phi(gap) - c v_n) bounds N in the band above the thickness, a touching
//       particle gets hold. N never exceeds hold: a contact holds its particle and stops its
//       approach, but never launches it (no rest is disturbed, no bounce: inelastic like the
//       projection).
//   T = the force that stops the tangential slip within that step, -(f_t + m v_t / dt), if
//       |T| <= mu N (static: the particle then stays exactly where it is, at any dt), else
//       that force scaled to mu N (kinetic, against the slip).
// (Symplectic Euler applies f(t + dt) in one kick of dt: the same. The other integrators
// apply it less directly, RK4 at its stages, so there the terms in v act as a damping of
// rate 1 / dt: the same contact in the limit dt -> 0, first order like every contact.)
// For a dynamic body (which gets -N n - T) the terms in v would feed back: many particles
// each stopping their slip against a light body move it by (their mass / its mass) times that
// slip, the wrong way (a 0.05 kg box under 1 kg of cloth tips over). There (impulses) N is
// eq. (7) as the paper has it (it also carries a body lying on the cloth), plus the inward
// part of f for a touching particle; T cancels f_t up to mu N; the rest of the friction cone,
// (mu N - |T|) dt, is the collision stage's to give as an impulse in the next step.
void addContactForces(ContactSet& set, const Vec3List& x, const Vec3List& v, Vec3List& f) {
    const double invDt = 1.0 / set.dt;
    for (auto& pc : set.contacts) {
        const Vec3& n = pc.normal;
        Vec3& fi = f[pc.particle];
        const Vec3 rel = v[pc.particle] - pc.bodyVelocity;
        const double vn = rel.dot(n);
        const double fn = fi.dot(n);
        const double gap = (x[pc.particle] - pc.point).dot(n) - set.thickness;
        const bool touching = gap <= kTouching * set.thickness;
        const double penalty =
            pc.cp > 0.0 ? std::max(0.0, pc.cp * penaltyShape(gap, set.band) - pc.damping * vn)
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

} // namespace drape
