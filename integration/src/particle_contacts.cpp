// One particle against one body: the closest point (or where a fast particle's path entered
// the body), its limiter plane, its contact record, the projection, the inelastic normal
// impulse and its Coulomb friction (see contacts.hpp).
#include "contacts.hpp"

#include "drape/geometry.hpp"

#include <btBulletDynamicsCommon.h>

#include <cmath>

namespace drape::bullet::detail {

namespace {
/// How far particle i at `at` may move along the unit n and stay within its long-range
/// attachment's reach of its anchor (StrainLimiter::anchorRoom): infinite without an anchor
/// (none reaches it, the attachments are off, or the anchors were found for another set of
/// held particles), 0 if it is beyond already. `anchor`: the anchor, when there is one.
double anchorRoom(const Cloth& c, std::size_t i, const Vec3& at, const Vec3& n, Index& anchor) {
    const auto& lim = c.settings().limiter;
    const AnchorField& field = c.limiter().anchors();
    if (lim.kind != LimiterKind::StressOrdered || !lim.longRangeAttachments ||
        field.anchor.size() != c.particleCount())
        return std::numeric_limits<double>::infinity();
    const Index a = field.anchor[i];
    if (a == kNoParticle || c.inverseMasses()[a] != 0.0)
        return std::numeric_limits<double>::infinity();
    anchor = a;
    return c.limiter().anchorRoom(Index(i), at, n, c.positions());
}
} // namespace

inline void ContactSolver::recordContact(const Cloth& c, std::uint32_t bi, std::size_t i,
                                         const SurfaceHit& hit, double cp, double damping) {
    const BodySnapshot& b = bodies[bi];
    ContactRecord* rec = nullptr;
    const std::int64_t existing = recordOf_[i];
    if (existing >= 0 && records->contacts[std::size_t(existing)].body == bi) {
        rec = &records->contacts[std::size_t(existing)];
    } else {
        recordOf_[i] = std::int64_t(records->contacts.size());
        rec = &records->contacts.emplace_back();
        ++stats.contacts;
    }
    rec->particle = static_cast<Index>(i);
    rec->body = bi;
    rec->point = hit.point;
    rec->normal = hit.normal;
    rec->bodyVelocity = b.velocityAt(hit.point);
    rec->mass = c.masses()[i];
    rec->cp = std::max(cp, 0.0);
    rec->damping = damping;
    rec->mu = b.friction;
    rec->impulses = b.dynamicBody != nullptr;
}

std::int64_t ContactSolver::heldBehind(const Vec3List& x, std::size_t i) const {
    const ContactPlanes& planes = records->planes;
    const std::int32_t k = planes.of[i];
    if (k < 0) return -1;
    const auto kk = std::size_t(k);
    if (bodies[planeBody_[kk]].dynamicBody) return -1;
    if (planes.normal[kk].dot(x[i]) - planes.offset[kk] > kHeldGap * contact_.thickness) return -1;
    return std::int64_t(kk);
}

void ContactSolver::solveHeld(Cloth& c) {
    if (held_.empty()) return;
    stats.heldBetween += held_.size();
    // Sequential impulses with accumulated, clamped normal impulses (as Bullet's own solver):
    // a long body landing on a row of held particles gets its approach stopped at every one
    // of them together, so an impulse at one end that turned it is taken back at the other,
    // instead of one pass in particle order that leaves it spinning (it threw a 1.1 m plank
    // back at 3.1 m/s after landing at 4.1).
    // The particle's side of each impulse goes to the body behind it: only b moves.
    auto toBody = [this](BodySnapshot& b, const Vec3& j, const Vec3& p) {
        b.applyImpulse(-j, p);
        stats.impulseOnBodies -= j;
    };
    for (int it = 0; it < kHeldIterations; ++it) {
        for (HeldContact& h : held_) {
            BodySnapshot& b = bodies[h.body];
            const double vn = (h.behindVelocity - b.velocityAt(h.point)).dot(h.normal);
            const double sum = std::max(0.0, h.lambda - vn / h.give);
            if (sum == h.lambda) continue;
            toBody(b, (sum - h.lambda) * h.normal, h.point);
            h.lambda = sum;
        }
    }
    // Then each contact's Coulomb friction against the particle's slip, within mu lambda.
    const Vec3List& v = c.velocities();
    for (const HeldContact& h : held_) {
        if (!(h.lambda > 0.0)) continue;
        BodySnapshot& b = bodies[h.body];
        const Vec3 rel = v[h.particle] - b.velocityAt(h.point);
        Vec3 j;
        if (coulombImpulse(rel, h.normal, 0.0, b, h.point, b.friction * h.lambda, j))
            toBody(b, j, h.point);
    }
    // And the body is moved back out to the thickness where it came nearer (a body resting on
    // the held cloth sinks by g dt^2 a world step: Bullet moves it before the cloth's impulse
    // stops it), as far as its deepest held contact needs: a move, not a velocity, so that
    // nothing is launched.
    deepestHeld_.assign(bodies.size(), nullptr);
    for (const HeldContact& h : held_) {
        const HeldContact*& d = deepestHeld_[h.body];
        if (h.depth > 0.0 && (!d || h.depth > d->depth)) d = &h;
    }
    for (std::size_t bi = 0; bi < bodies.size(); ++bi)
        if (const HeldContact* d = deepestHeld_[bi]) bodies[bi].liftOut(-d->depth * d->normal);
    held_.clear();
}

bool ContactSolver::collideParticle(Cloth& c, std::uint32_t bi, std::size_t i, double dt,
                                    QueryCounters& counters) {
    BodySnapshot& b = bodies[bi];
    Vec3List& x = c.mutablePositions();
    Vec3List& v = c.mutableVelocities();
    const double wi = c.inverseMasses()[i];
    const auto& cs = contact_;
    const double h = cs.thickness;
    const Vec3 xi = x[i];
    // Where the particle started the step, seen from the body: where it is now relative to
    // it (a moving body sweeps past particles as particles sweep past bodies).
    const Vec3 from =
        b.sweeps() ? b.pose.toWorld(b.previous.toLocal(stepStart()[i])) : stepStart()[i];
    const bool sweep = cs.continuous && (xi - from).squaredNorm() > h * h;

    SurfaceHit hit;
    // Where the contact holds the particle: `reach` above the surface (the thickness, or less
    // for a particle that started the step inside the body).
    double reach = h;
    if (!(sweep && pathHit(b, from, xi, hit))) {
        hit = b.box ? boxSurface(b.boxHalf, b.boxFaceNormal, b.pose, xi, counters)
                    : closestSurface(b.object->getCollisionShape(), b.pose, xi, from, h + band_,
                                     counters);
        if (!hit.valid || hit.distance >= h + band_) return false;
        // Inside the body now and at the step's start, seen from the body (placed or
        // teleported there, or the body moved, grew or was placed round it: not come in on its
        // way): out at contact.depenetrationSpeed only, all the way to the thickness (its
        // neighbours follow it through the limiter at the speed it moves). (Within the
        // thickness it was moved out at once: a particle near a box's edge then went out
        // through the side, and one that reached the surface was moved the last centimetre in
        // one sub-step; the walk dragged their neighbours along at 10-16 m/s.) A moving body's pose
        // at the step's start is reconstructed from its velocity at the end, so a fast body Bullet
        // stopped on the way looks as if it had been there already, and its particles come out
        // slowly too. Judged only for bodies that did not move, a dynamic body resting on the floor
        // (never exactly still in Bullet) had a cloth spawned through it projected out in one step
        // and thrown off at 15 km/s.
        if (i < exitLast_.size() && exitLast_[i] && hit.distance < h) {
            // On its way out slowly in the last step: on at that speed to the thickness.
            if (reprojecting_) return true;
            reach = std::min(h, hit.distance + cs.depenetrationSpeed * dt);
        } else if (hit.distance < 0.0) {
            const SurfaceHit start =
                b.box ? boxSurface(b.boxHalf, b.boxFaceNormal, b.pose, from, counters)
                      : closestSurface(b.object->getCollisionShape(), b.pose, from, from, h,
                                       counters);
            if (start.valid && start.distance < 0.0) {
                // Once a step, before the limiter: the limiter then keeps the bound over it
                // (projected again after it, particles pushed out through different faces
                // tore the cloth apart, and it flew off at 26 m/s when they came out).
                if (reprojecting_) return true;
                reach = std::min(h, start.distance + cs.depenetrationSpeed * dt);
            }
        }
        if (reach < h && i < exitNow_.size()) exitNow_[i] = 1;
    }
    // A particle whose anchor (a pinned or attached particle it hangs from) is inside the body
    // (a row attached to a cart that sank into the floor) comes out only as far as its
    // long-range attachment reaches: there the cloth follows its anchor into the body, at the
    // strain bound. Projected to the surface, it was pulled back in by the walk in every
    // step, and the fight launched the cloth (strain 4, 45 m/s, 0.3-0.9 s a frame).
    // Its anchor holds it there: no plane, no contact force or impulse against the pull that
    // holds it in (they pushed it out again, and the walk pulled it back).
    if (hit.distance < reach && moverOf_[bi] < 0) {
        Index a = kNoParticle;
        if (const double room = anchorRoom(c, i, xi, hit.normal, a); room < reach - hit.distance) {
            ++stats.projections;
            stats.maxDepth = std::max(stats.maxDepth, h - hit.distance);
            touching_[i] = 1;
            // Already at its reach (the walk left it on its attachment's sphere), the room is
            // rounding, 1e-16 m: not a move (it made the walk run again, in every cloth step
            // of a banner whose edge column lies along its posts' faces).
            if (room > kNoMove * h) x[i] = xi + room * hit.normal;
            // It moves into the body no faster than its anchor (the lift stops the rest, as
            // the walk's long-range attachment would).
            const double vn = (v[i] - v[a]).dot(hit.normal);
            if (vn < 0.0) v[i] -= vn * hit.normal;
            return true;
        }
    }
    // A particle that a static or kinematic body holds from behind (a rug on the floor) does
    // not give way to a dynamic body: one pressing it into that body (normals more than 120
    // degrees apart: a crate landing on the rug) is stopped there as by that body; one it lies
    // inside of, but not under (a resting crate's bottom edge, which Bullet lets sit on the
    // floor through the rug), leaves it where it is. Moved out, it would be moved into the body
    // behind it or pulled out from under the crate against its springs, and the projection
    // back would launch it (a 20 kg box then left the rug at 5.6 m/s after landing at 3.6).
    if (b.dynamicBody) {
        if (const std::int64_t k = heldBehind(x, i); k >= 0) {
            const double facing = records->planes.normal[std::size_t(k)].dot(hit.normal);
            if (facing < -0.5) {
                const double give = b.inverseMassAlong(hit.point, hit.normal);
                if (give > 0.0)
                    held_.push_back(HeldContact{bi, i, hit.point, hit.normal,
                                                bodies[planeBody_[std::size_t(k)]].velocityAt(x[i]),
                                                give, std::min(h, h - hit.distance), 0.0});
                return true;
            }
            if (hit.distance < 0.0 && facing < 0.5) return true;
        }
    }
    // The limiter's walk keeps the particle above the tangent plane of a contact with a static
    // or kinematic body, with a free dynamic body (nothing else holds it, see
    // BodySnapshot::supported), and with a supported one at least as heavy, along the normal
    // at the point, as the whole cloth. The plane's push reaches a dynamic body after the walk
    // as an impulse, at most what stops its approach (flushPlane). (On a supported body lighter
    // than the cloth, the plane's impulses and Bullet's contacts would feed on each other;
    // there the projection and the walk alternate instead.)
    // (Not for a particle coming out of a body slowly: the limiter keeps the bound over it.)
    if (reach == h && (!b.dynamicBody || !b.supported ||
                       b.inverseMassAlong(hit.point, hit.normal) * clothMass_ <= 1.0))
        keepPlane(c, bi, i, hit.normal, hit.normal.dot(hit.point) + h, hit.point, false, dt);

    // The contact record the force term reads (addContactForces, drape/contacts.hpp): for every
    // particle touching the body (below the thickness, or resting at it), and with eq. (7) on for
    // every particle in the band above it (also for particles below the thickness: they end at its
    // bottom after the projection).
    const bool touches = hit.distance < h * (1.0 + kTouching);
    const double mi = c.masses()[i];
    const double g = c.settings().gravity.squaredNorm();
    if (mi != penalty_.mass || dt != penalty_.dt || g != penalty_.gravity) {
        penalty_.mass = mi;
        penalty_.dt = dt;
        penalty_.gravity = g;
        penalty_.cp = cs.penaltyForce ? *cs.penaltyForce : 2.0 * mi * std::sqrt(g);
        penalty_.damping = limitPenalty(mi, band_, dt, penalty_.cp);
    }
    if (penalty_.cp > 0.0 || touches) recordContact(c, bi, i, hit, penalty_.cp, penalty_.damping);
    if (b.dynamicBody && i < frictionLeft_.size() && frictionLeft_[i] > 0.0) {
        // The rest of the last step's friction cone against a dynamic body, once per step.
        frictionImpulse(c, i, b, hit.point, hit.normal, frictionLeft_[i] * dt);
        frictionLeft_[i] = 0.0;
    }
    if (hit.distance >= h) return true; // in the band or resting on the body: no projection

    ++stats.projections;
    stats.maxDepth = std::max(stats.maxDepth, h - hit.distance);
    touching_[i] = 1;
    if (reach > hit.distance) x[i] = xi + (reach - hit.distance) * hit.normal;
    const Vec3 rel = v[i] - b.velocityAt(hit.point);
    const double vn = rel.dot(hit.normal);
    if (vn < 0.0) {
        // Inelastic: the approach stops, and the normal impulse lambda allows a tangential
        // (Coulomb) impulse of mu lambda. (A resting load is carried by the contact force of
        // addContactForces, with its own friction: each normal force counts once.)
        const double lambda = -vn / (wi + b.inverseMassAlong(hit.point, hit.normal));
        const Vec3 j = lambda * hit.normal;
        v[i] += wi * j;
        exchange(b, j, hit.point);
        frictionImpulse(c, i, b, hit.point, hit.normal, b.friction * lambda);
    }
    return true;
}

bool ContactSolver::pathHit(const BodySnapshot& b, const Vec3& from, const Vec3& xi,
                            SurfaceHit& hit) {
    // Did the particle's path since the last step enter the body?
    ++stats.rayQueries;
    if (b.box && !b.sweeps()) {
        // A box that does not move, exactly (segmentEntersBox): Bullet's ray cast stops within
        // the shape's margin, near a corner up to a centimetre outside the box with the
        // corner's normal, so a particle sliding past the corner in the thickness counted as
        // entering and was put on the corner. (A moving box keeps Bullet's ray: there the
        // margin also catches particles its corners sweep past, which holds a banner in front
        // of a box driven through it.)
        double t = 0.0;
        Vec3 n;
        const Vec3 o = b.pose.toLocal(from), e = b.pose.toLocal(xi);
        if (!segmentEntersBox(o, e, b.boxHalf, t, n)) return false;
        hit.valid = true;
        hit.point = b.pose.toWorld(o + t * (e - o));
        hit.normal = b.pose.R * n;
        hit.distance = std::min((xi - hit.point).dot(hit.normal), 0.0);
        return true;
    }
    btTransform t0, t1;
    t0.setIdentity();
    t1.setIdentity();
    t0.setOrigin(toBt(from));
    t1.setOrigin(toBt(xi));
    btCollisionWorld::ClosestRayResultCallback ray(t0.getOrigin(), t1.getOrigin());
    btCollisionWorld::rayTestSingle(t0, t1, const_cast<btCollisionObject*>(b.object),
                                    b.object->getCollisionShape(), toBtTransform(b.pose), ray);
    // A path that passes a sphere or capsule within the cloth's thickness touched it, as a
    // particle that ends there does (a thin rod between two rows of particles): where it meets
    // the body head on (within 60 degrees of the normal; one that grazes the body's side
    // passes it).
    if (!ray.hasHit()) {
        if (!inflatedPathHit(b.object->getCollisionShape(), b.pose, from, xi, contact_.thickness,
                             hit))
            return false;
        const Vec3 back = from - xi;
        if (hit.normal.dot(back) >= 0.5 * back.norm()) return true;
        hit = SurfaceHit{};
        return false;
    }
    Vec3 nrm = toVec(ray.m_hitNormalWorld);
    const double len = nrm.norm();
    if (!(len > 0.0)) return false;
    nrm /= len;
    if (nrm.dot(from - xi) < 0.0) nrm = -nrm; // face where the particle came from
    hit.valid = true;
    hit.point = toVec(ray.m_hitPointWorld);
    hit.normal = nrm;
    if (b.dynamicBody) {
        // Bullet's ray cast against a convex shape stops within its margin, with a normal
        // up to tens of degrees off: on a thin rod that is a lever about its axis, where it
        // has almost no inertia. A primitive's exact surface point and normal nearest to the
        // hit replace them (the body's answer to the walk's pushes depends on them).
        const int type = b.object->getCollisionShape()->getShapeType();
        if (type == SPHERE_SHAPE_PROXYTYPE || type == CAPSULE_SHAPE_PROXYTYPE ||
            type == CYLINDER_SHAPE_PROXYTYPE || type == BOX_SHAPE_PROXYTYPE ||
            type == CONE_SHAPE_PROXYTYPE) {
            QueryCounters local;
            const SurfaceHit q =
                closestSurface(b.object->getCollisionShape(), b.pose, hit.point, from, 0.0, local);
            if (q.valid && q.normal.dot(from - xi) >= 0.0) {
                hit.point = q.point;
                hit.normal = q.normal;
            }
        }
    }
    hit.distance = std::min((xi - hit.point).dot(hit.normal), 0.0);
    return true;
}

void ContactSolver::frictionImpulse(Cloth& c, std::size_t i, BodySnapshot& b, const Vec3& p,
                                    const Vec3& normal, double budget) {
    Vec3& vi = c.mutableVelocities()[i];
    const double wi = c.inverseMasses()[i];
    Vec3 j;
    if (!coulombImpulse(vi - b.velocityAt(p), normal, wi, b, p, budget, j)) return;
    vi += wi * j;
    exchange(b, j, p);
}

} // namespace drape::bullet::detail
