// drape/contacts.hpp: contacts with other bodies as data the step consumes. A collision
// stage (drape::bullet's) fills a ContactSet with the particles touching a body or inside
// eq. (7)'s band above it; the cloth's contact force term (Cloth::setContacts) reads the set
// and writes the force each record got back into it, for the caller to give the bodies.
// Plain Eigen data; the response formulas here are engine-neutral.
#pragma once

#include "drape/forces.hpp"
#include "drape/strain_limit.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace drape {

/// A particle within this fraction of the thickness above a surface rests on it: it is held
/// there, not floated by eq. (7). Covers the float noise of the projection onto P + h n and
/// the drift of a dynamic body's pose, which Bullet's solver moves by ~1e-9 m a step.
constexpr double kTouching = 1e-3;

/// One particle touching a body or inside eq. (7)'s band above it.
struct ContactRecord {
    // --- input: the collision stage fills these --------------------------------------------
    Index particle = 0;
    std::uint32_t body = 0;           ///< the caller's index of the body
    Vec3 point = Vec3::Zero();        ///< surface point [m]
    Vec3 normal = Vec3::UnitY();      ///< outward unit normal
    Vec3 bodyVelocity = Vec3::Zero(); ///< at the point [m/s]
    double mass = 0.0;                ///< the particle's mass [kg]
    double cp = 0.0;                  ///< C_p for this particle [N] (0: penalty off)
    double damping = 0.0;             ///< normal damping of the penalty [N s/m]
    double mu = 0.0;                  ///< Coulomb coefficient [-]
    /// The body is dynamic: no velocity terms in the force, the rest of the friction cone as
    /// an impulse (see addContactForces).
    bool impulses = false;
    // --- output: the force term writes these -----------------------------------------------
    double force = 0.0;           ///< normal force at the last force evaluation [N]
    Vec3 friction = Vec3::Zero(); ///< friction force at the last evaluation [N]
};

/// The contacts of one step: made by the collision stage, read by the force term, and read
/// again by the caller after the step (the forces its bodies get).
struct ContactSet {
    std::vector<ContactRecord> contacts;
    /// Contact planes a stage sets before the strain limiter (ClothStage::beforeLimit): the
    /// stress-ordered walk keeps each particle above its plane while it corrects the springs
    /// (one walk for the strain bound and the contacts), recording in `push` how far each
    /// plane pushed; the stage passes that on to the bodies after it.
    ContactPlanes planes;
    double thickness = 0.0; ///< h [m]
    double band = 1.0;      ///< eq. (7)'s band width w above the thickness [m]
    double dt = 1.0;        ///< the step the records were made in [s]
};

/// Keeps eq. (7)'s penalty spring for a particle of mass `mass` [kg] in a step dt [s] inside
/// the explicit stability limits of the step: scales C_p (`cp`, > 0 when the penalty is on)
/// down if needed and returns the normal damping [N s/m] (0 with the penalty off).
double limitPenalty(double mass, double band, double dt, double& cp);

/// Eq. (7) regularised. The paper's C_p exp(1 / |PP0|) grows without bound as the particle
/// reaches the surface and is dimensionally inconsistent; we keep its shape (an exponential
/// barrier along N_P0, zero without contact) on a band of width w above the thickness h:
///   phi(g) = (exp(1 - g / w) - 1) / (e - 1),  g = d - h in [0, w),  phi(0) = 1, phi(w) = 0,
///   F = max(0, C_p phi(g) - c (v_rel . n)),
/// continuous at the band's edge, bounded by C_p at the thickness (the projection takes over
/// below it), with a normal damping c that keeps resting particles from oscillating in the band.
double penaltyShape(double gap, double band);

/// The contact force term (Cloth::setContacts; derivation in contacts.cpp): for each record, a
/// normal force N that holds its particle (never launches it) and Coulomb friction T, added
/// to f after every other term; N and T are written to the record.
void addContactForces(ContactSet& set, const Vec3List& x, const Vec3List& v, Vec3List& f);

/// Coulomb friction of a normal impulse: the tangential impulse j, of at most `budget` [N s],
/// against the slip of a point of inverse mass w whose velocity relative to the body is
/// `rel`, tangent to `normal`: the impulse that stops the slip if the budget allows it.
/// `bodyInverseMass(d)` is the body's inverse mass along direction d at the point (0 for a
/// static body). Returns false when there is nothing to give (no budget, no slip).
template <class BodyInverseMass>
bool coulombImpulse(const Vec3& rel, const Vec3& normal, double w,
                    const BodyInverseMass& bodyInverseMass, double budget, Vec3& j) {
    if (!(budget > 0.0)) return false;
    const Vec3 vt = rel - rel.dot(normal) * normal;
    const double vtLen = vt.norm();
    if (vtLen <= 0.0) return false;
    const Vec3 tdir = vt / vtLen;
    const double jt = std::min(vtLen / (w + bodyInverseMass(tdir)), budget);
    j = -jt * tdir;
    return true;
}

} // namespace drape
