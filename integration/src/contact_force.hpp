// contact_force.hpp (private to drape::bullet): the contact force term, one of the cloth's
// force terms (Cloth::addExternalForce, named "contact_force"). It reads the contact records
// the contact stage made and adds, for each, a normal force that holds the particle (bounded
// by the paper's eq. (7) in a band above the thickness) and Coulomb friction. Plain Eigen
// data; no Bullet types.
#pragma once

#include "drape/forces.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <vector>

namespace drape::bullet::detail {

constexpr double kE = 2.718281828459045;
/// A particle within this fraction of the thickness above it rests on the body: it is held
/// there, not floated by eq. (7). Covers the float noise of the projection onto P + h n and
/// the drift of a dynamic body's pose, which Bullet's solver moves by ~1e-9 m a step (with
/// 1e-6 of the thickness a sheet on a resting dynamic slab lost its support every few steps).
constexpr double kTouching = 1e-3;

/// One particle touching a body or inside eq. (7)'s band above it: the contact force term
/// reads these (see ContactForce).
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
    /// an impulse (see ContactForce).
    bool impulses = false;
    double force = 0.0;           ///< normal force at the last force evaluation [N]
    Vec3 friction = Vec3::Zero(); ///< friction force at the last evaluation [N]
};

/// Shared between the contact stage, the force term the cloth owns, and the handle.
struct ContactState {
    std::vector<ContactRecord> contacts;
    double thickness = 0.0;
    double band = 1.0;
    double dt = 1.0; ///< the step the records were made in [s]
};

/// Keeps eq. (7)'s penalty spring for a particle of mass `mass` [kg] in a step dt [s] inside
/// the explicit stability limits of the step: scales C_p (`cp`, > 0 when the penalty is on)
/// down if needed and returns the normal damping [N s/m] (0 with the penalty off).
inline double limitPenalty(double mass, double band, double dt, double& cp) {
    if (!(cp > 0.0)) return 0.0;
    // Keep the penalty spring (stiffness cp e / ((e - 1) w)) and its damping inside the
    // explicit stability limits of this step: k dt^2 / m <= 1, c dt / m <= 1/2.
    const double kMax = mass / (dt * dt);
    const double k = cp * kE / ((kE - 1.0) * band);
    if (k > kMax) cp *= kMax / k;
    return std::min(2.0 * std::sqrt(std::min(k, kMax) * mass), 0.5 * mass / dt);
}

/// Eq. (7) regularised. The paper's C_p exp(1 / |PP0|) grows without bound as the particle
/// reaches the surface and is dimensionally inconsistent; we keep its shape (an exponential
/// barrier along N_P0, zero without contact) on a band of width w above the thickness h:
///   phi(g) = (exp(1 - g / w) - 1) / (e - 1),  g = d - h in [0, w),  phi(0) = 1, phi(w) = 0,
///   F = max(0, C_p phi(g) - c (v_rel . n)),
/// continuous at the band's edge, bounded by C_p at the thickness (the projection takes over
/// below it), with a normal damping c that keeps resting particles from oscillating in the band.
double penaltyShape(double gap, double band);

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
///
/// The term is a ForceModel::ExternalForce: the cloth owns a copy, which shares the records
/// with the handle (they are cleared when the handle is removed, so a cloth that outlives it
/// gets no contact force).
class ContactForce {
  public:
    explicit ContactForce(std::shared_ptr<ContactState> state) : state_(std::move(state)) {}
    void operator()(const Vec3List& x, const Vec3List& v, Vec3List& f) const;

  private:
    std::shared_ptr<ContactState> state_;
};

} // namespace drape::bullet::detail
