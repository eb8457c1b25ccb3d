// Triangle-body contacts (contact.triangles): the cloth's triangles kept the thickness away
// from convex bodies and the convex children of compounds, so that a feature thinner than the
// particle spacing cannot pass between particles (see contacts.hpp).
#include "contacts.hpp"

#include <btBulletCollisionCommon.h>

namespace drape::bullet::detail {

void ContactSolver::collideTriangles(Cloth& c, double dt, QueryCounters& counters) {
    const auto& tris = c.topology().triangles();
    const auto& w = c.inverseMasses();
    const Vec3List& x = c.positions();
    triangleHits_.clear();
    for (std::uint32_t bi = 0; bi < bodies.size(); ++bi) {
        const BodySnapshot& b = bodies[bi];
        // Planes have no feature to slip between particles; concave meshes are not queried.
        const btCollisionShape* shape = b.object->getCollisionShape();
        if (b.plane || !(shape->isConvex() || shape->getShapeType() == COMPOUND_SHAPE_PROXYTYPE))
            continue;
        for (std::size_t t = 0; t < tris.size(); ++t) {
            const Triangle& tri = tris[t];
            if (w[tri[0]] == 0.0 && w[tri[1]] == 0.0 && w[tri[2]] == 0.0) continue;
            const Vec3 lo = x[tri[0]].cwiseMin(x[tri[1]]).cwiseMin(x[tri[2]]);
            const Vec3 hi = x[tri[0]].cwiseMax(x[tri[1]]).cwiseMax(x[tri[2]]);
            if ((hi.array() < b.aabbMin.array()).any() || (lo.array() > b.aabbMax.array()).any())
                continue;
            if (collideTriangle(c, bi, t, dt, counters) >= 0.0) triangleHits_.emplace_back(bi, t);
        }
    }
    // Moving one triangle's particles turns its neighbours (which share them) and can press
    // them back in: a few more sweeps over the triangles that touched (Gauss-Seidel).
    for (int sweep = 0; sweep < kTriangleSweeps && !triangleHits_.empty(); ++sweep) {
        double deepest = 0.0;
        for (const auto& [bi, t] : triangleHits_)
            deepest = std::max(deepest, collideTriangle(c, bi, t, dt, counters));
        if (deepest <= 1e-9 * contact_.thickness) break; // (rounding)
    }
}

double ContactSolver::collideTriangle(Cloth& c, std::uint32_t bi, std::size_t t, double dt,
                                      QueryCounters& counters) {
    const BodySnapshot& b = bodies[bi];
    const Triangle& tri = c.topology().triangles()[t];
    const Vec3List& x = c.positions();
    const double h = contact_.thickness;
    const TriangleHit hit = closestToTriangle(b.object->getCollisionShape(), toBtTransform(b.pose),
                                              x[tri[0]], x[tri[1]], x[tri[2]], h, counters);
    if (!hit.valid || !(hit.distance < h)) return -1.0;
    const double depth = h - hit.distance;
    return pushTriangle(c, bi, tri, hit.normal, hit.bodyPoint, hit.barycentric, depth, false, dt)
               ? depth
               : -1.0;
}

bool ContactSolver::pushTriangle(Cloth& c, std::uint32_t bi, const Triangle& tri, const Vec3& n,
                                 const Vec3& point, const Vec3& beta, double depth, bool swept,
                                 double dt) {
    BodySnapshot& b = bodies[bi];
    Vec3List& x = c.mutablePositions();
    Vec3List& v = c.mutableVelocities();
    const auto& w = c.inverseMasses();
    // The triangle's nearest point moves out by the depth along n: particle k by
    // beta_k w_k / W of it, W = sum beta_k^2 w_k (the least-mass-weighted change that moves the
    // point by exactly that), and its approach stops with the impulse lambda shared the same
    // way: the point's inverse mass along n is W.
    // A point at (or near) a fixed corner is held there: moving the free corners by
    // beta_k w_k depth / W would take them far (by depth / beta_k) for nothing.
    double weight = 0.0, free = 0.0;
    for (int k = 0; k < 3; ++k) {
        weight += beta[k] * beta[k] * w[tri[k]];
        free += w[tri[k]] > 0.0 ? beta[k] : 0.0;
    }
    if (!(weight > 0.0) || free < kFreeShare) return false;
    // A dynamic body pressing the triangle into a static or kinematic body that holds one of
    // its corners (a cup rolling over a cloth on the floor) moves nothing, as for a spring
    // (collideSpringWithBox) and a particle (collideParticle): moved, the corner went into the
    // floor, where it came out only at contact.depenetrationSpeed and stayed 1 cm inside.
    if (b.dynamicBody)
        for (int k = 0; k < 3; ++k)
            if (beta[k] != 0.0 && heldAgainst(x, tri[k], n)) return false;
    stats.maxDepth = std::max(stats.maxDepth, depth);
    // A body smaller than the triangle that swept into it (small_: it fits between the
    // corners, which its own tangent plane through each of them would let slide around it)
    // gets the triangle's plane in the walk instead (keepsTrianglePlanes).
    const bool trianglePlane = swept && keepsTrianglePlanes(bi);
    if (trianglePlane) addTrianglePlane(bi, tri, beta, n, point);
    // The push along n is a position change: without friction a triangle resting on a curved
    // body slid down it by g sin(theta) dt^2 each step (a towel draped over a clothesline crept
    // off it). Coulomb friction on the push (its normal part is `depth`): the point's slide
    // along the surface since the step's start, relative to the body, is taken back up to
    // mu depth, before the walk (pushFriction_).
    Vec3 taken = Vec3::Zero();
    if (!swept && pushFriction_ && b.friction > 0.0) {
        Vec3 slide = -dt * b.velocityAt(point);
        for (int k = 0; k < 3; ++k)
            slide += beta[k] * (x[tri[k]] - stepStart()[tri[k]]);
        slide -= slide.dot(n) * n;
        const double most = b.friction * depth, len = slide.norm();
        taken = len <= most ? slide : (most / len) * slide;
    }
    for (int k = 0; k < 3; ++k) {
        const Index i = tri[k];
        if (w[i] == 0.0 || beta[k] == 0.0) continue;
        x[i] += (beta[k] * w[i] * depth / weight) * n;
        if (taken != Vec3::Zero()) x[i] -= (beta[k] * w[i] / weight) * taken;
        touching_[i] = 1;
        projected_.push_back(i);
        boxes_.update(i, x[i], stepStart()[i], false);
        if (trianglePlane) continue;
        // The limiter's walk keeps the particle from going back along n, so the strain bound
        // and the triangle's contact hold together, as for particle contacts: against a static
        // or kinematic body (its own contact's plane, if it has one, comes first); after a
        // sweep also against the dynamic bodies a particle contact keeps planes with (a plane
        // of another body stays).
        const std::int32_t was = records->planes.of[i];
        const bool plane = swept ? (was < 0 || planeBody_[std::size_t(was)] == bi) &&
                                       (!b.dynamicBody || !b.supported ||
                                        b.inverseMassAlong(point, n) * clothMass_ <= 1.0)
                                 : !b.dynamicBody && (was < 0 || trianglePlane_[i]);
        if (plane) keepPlane(c, bi, i, n, n.dot(x[i]), point, !swept, dt);
    }
    ++(swept ? stats.sweptTriangles : stats.triangleContacts);
    const Vec3 rel =
        beta[0] * v[tri[0]] + beta[1] * v[tri[1]] + beta[2] * v[tri[2]] - b.velocityAt(point);
    if (b.dynamicBody) b.contactSpeed = std::max(b.contactSpeed, rel.norm());
    const double vn = rel.dot(n);
    if (vn >= 0.0) return true;
    auto share = [&](const Vec3& j) { // an impulse j at the point: the particles' shares, the
                                      // body's opposite
        for (int k = 0; k < 3; ++k)
            v[tri[k]] += (beta[k] * w[tri[k]]) * j;
        exchange(b, j, point);
    };
    const double lambda = -vn / (weight + b.inverseMassAlong(point, n));
    share(lambda * n);
    // Its Coulomb friction, against the slip before the normal impulse.
    Vec3 j;
    if (coulombImpulse(rel, n, weight, b, point, b.friction * lambda, j)) share(j);
    return true;
}

bool ContactSolver::keepsTrianglePlanes(std::uint32_t bi) const {
    const BodySnapshot& b = bodies[bi];
    return small_[bi] && (!b.dynamicBody || moverOf_[bi] >= 0);
}

void ContactSolver::addTrianglePlane(std::uint32_t bi, const Triangle& tri, const Vec3& beta,
                                     const Vec3& n, const Vec3& point) {
    const std::size_t t =
        records->planes.addTriangle(tri, beta, n, n.dot(point) + contact_.thickness);
    if (const std::int32_t m = moverOf_[bi]; m >= 0)
        records->planes.triangleMoveWith(t, m, point - bodies[bi].com);
    triangleBody_.push_back(bi);
    trianglePoint_.push_back(point);
}

void ContactSolver::sweepBodies(Cloth& c, double dt, QueryCounters& counters) {
    const double h = contact_.thickness;
    const auto& tris = c.topology().triangles();
    const auto& w = c.inverseMasses();
    const Vec3List& x = c.positions();
    for (std::uint32_t bi = 0; bi < bodies.size(); ++bi) {
        const BodySnapshot& b = bodies[bi];
        if (b.plane || !b.sweeps()) continue;
        const btCollisionShape* shape = b.object->getCollisionShape();
        if (!(shape->isConvex() || shape->getShapeType() == COMPOUND_SHAPE_PROXYTYPE)) continue;
        btVector3 centre;
        btScalar r;
        shape->getBoundingSphere(centre, r);
        const double radius = toVec(centre).norm() + double(r);
        const Pose& from = b.previous;
        const Pose& to = b.pose;
        const PosePath path(from, to);
        // A body that moved less than the thickness in the step and is not thin (thin_): the
        // particles' own queries (closest points, swept rays) meet it.
        if (!thin_[bi] && path.shift.norm() + path.turn.angle() * radius <= h) continue;
        btVector3 mn0, mx0, mn1, mx1;
        shapeAabb(shape, toBtTransform(from), mn0, mx0);
        shapeAabb(shape, toBtTransform(to), mn1, mx1);
        // A small body (small_) that does not stay put keeps the planes of the triangles
        // within a spring's length of where it ends (addTrianglePlane), not only of those it
        // reached: the walk after this stage can pull a triangle its springs hold back onto
        // it from there.
        const bool planes = keepsTrianglePlanes(bi);
        const double reach = planes ? h + longestSpring(c) : h;
        const Vec3 lo = toVec(mn0).cwiseMin(toVec(mn1)).array() - reach;
        const Vec3 hi = toVec(mx0).cwiseMax(toVec(mx1)).array() + reach;
        // A triangle the cloth holds on this body (a held corner on it: a flag's row on its
        // pole) turns with it: no sweep (a thin pole turning slowly on its hinge swept the
        // triangles along it in every cloth step, 8 times the cost of a static pole).
        const Vec3 onLo = toVec(mn1).array() - h, onHi = toVec(mx1).array() + h;
        auto heldOnBody = [&](Index i) {
            return w[i] == 0.0 && (x[i].array() >= onLo.array()).all() &&
                   (x[i].array() <= onHi.array()).all();
        };
        for (const Triangle& tri : tris) {
            if (w[tri[0]] == 0.0 && w[tri[1]] == 0.0 && w[tri[2]] == 0.0) continue;
            if (b.attached && (heldOnBody(tri[0]) || heldOnBody(tri[1]) || heldOnBody(tri[2])))
                continue;
            Vec3 start[3], end[3];
            Vec3 tlo = Vec3::Constant(std::numeric_limits<double>::infinity()), thi = -tlo;
            for (int k = 0; k < 3; ++k) {
                start[k] = stepStart()[tri[k]];
                end[k] = x[tri[k]];
                tlo = tlo.cwiseMin(start[k]).cwiseMin(end[k]);
                thi = thi.cwiseMax(start[k]).cwiseMax(end[k]);
            }
            if ((thi.array() < lo.array()).any() || (tlo.array() > hi.array()).any()) continue;
            const SweptTriangleHit hit =
                sweepToTriangle(shape, radius, path, start, end, h, 0.05 * h, counters);
            if (!hit.valid) {
                if (!planes) continue;
                const TriangleHit near = closestToTriangle(shape, toBtTransform(to), end[0], end[1],
                                                           end[2], reach, counters);
                if (near.valid && near.distance < reach)
                    addTrianglePlane(bi, tri, near.barycentric, near.normal, near.bodyPoint);
                continue;
            }
            // The body's point that reached the triangle and its normal there, carried to where
            // the body ends the step.
            const Vec3 point = to.toWorld(hit.pose.toLocal(hit.near.bodyPoint));
            const Vec3 n = (to.R * hit.pose.R.transpose() * hit.near.normal).normalized();
            // Only a body that came on toward the triangle carries it (not one that leaves it
            // or slides along it).
            const Vec3& beta = hit.near.barycentric;
            Vec3 triangleMove = Vec3::Zero();
            for (int k = 0; k < 3; ++k)
                triangleMove += beta[k] * (1.0 - hit.s) * (end[k] - start[k]);
            const bool coming =
                (point - hit.near.bodyPoint - triangleMove).dot(hit.near.normal) > 0.0;
            // The triangle's point there ends ahead of the body's tangent plane, the thickness
            // away, and stops coming toward it: the response of a triangle contact.
            Vec3 at = Vec3::Zero();
            for (int k = 0; k < 3; ++k)
                at += beta[k] * x[tri[k]];
            const double depth = n.dot(point) + h - n.dot(at);
            if (coming && depth > 0.0)
                pushTriangle(c, bi, tri, n, point, beta, depth, true, dt);
            else if (planes) // (moving with it, or away: the walk may pull it back)
                addTrianglePlane(bi, tri, beta, n, point);
        }
    }
}

} // namespace drape::bullet::detail
