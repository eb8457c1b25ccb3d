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
    BodySnapshot& b = bodies[bi];
    const Triangle& tri = c.topology().triangles()[t];
    Vec3List& x = c.mutablePositions();
    Vec3List& v = c.mutableVelocities();
    const auto& w = c.inverseMasses();
    const double h = contact_.thickness;
    const TriangleHit hit = closestToTriangle(b.object->getCollisionShape(), toBtTransform(b.pose),
                                              x[tri[0]], x[tri[1]], x[tri[2]], h, counters);
    if (!hit.valid || !(hit.distance < h)) return -1.0;
    // The triangle's nearest point moves out by the depth along n: particle k by
    // beta_k w_k / W of it, W = sum beta_k^2 w_k (the least-mass-weighted change that moves the
    // point by exactly that), and its approach stops with the impulse lambda shared the same
    // way: the point's inverse mass along n is W.
    const Vec3& beta = hit.barycentric;
    double weight = 0.0;
    for (int k = 0; k < 3; ++k)
        weight += beta[k] * beta[k] * w[tri[k]];
    if (!(weight > 0.0)) return -1.0;
    const Vec3& n = hit.normal;
    const double depth = h - hit.distance;
    stats.maxDepth = std::max(stats.maxDepth, depth);
    for (int k = 0; k < 3; ++k) {
        const Index i = tri[k];
        if (w[i] == 0.0 || beta[k] == 0.0) continue;
        x[i] += (beta[k] * w[i] * depth / weight) * n;
        touching_[i] = 1;
        projected_.push_back(i);
        boxes_.update(i, x[i], stepStart()[i], false);
        // Against a static or kinematic body the limiter's walk keeps the particle from going
        // back along n (its own contact's plane, if it has one, comes first), so the strain
        // bound and the triangle's contact hold together, as for particle contacts.
        if (!b.dynamicBody && (records->planes.of[i] < 0 || trianglePlane_[i]))
            keepPlane(c, bi, i, n, n.dot(x[i]), hit.bodyPoint, true, dt);
    }
    ++stats.triangleContacts;
    const Vec3 rel = beta[0] * v[tri[0]] + beta[1] * v[tri[1]] + beta[2] * v[tri[2]] -
                     b.velocityAt(hit.bodyPoint);
    if (b.dynamicBody) b.contactSpeed = std::max(b.contactSpeed, rel.norm());
    const double vn = rel.dot(n);
    if (vn >= 0.0) return depth;
    auto share = [&](const Vec3& j) { // an impulse j at the point: the particles' shares, the
                                      // body's opposite
        for (int k = 0; k < 3; ++k)
            v[tri[k]] += (beta[k] * w[tri[k]]) * j;
        exchange(b, j, hit.bodyPoint);
    };
    const double lambda = -vn / (weight + b.inverseMassAlong(hit.bodyPoint, n));
    share(lambda * n);
    // Its Coulomb friction, against the slip before the normal impulse.
    Vec3 j;
    if (coulombImpulse(rel, n, weight, b, hit.bodyPoint, b.friction * lambda, j)) share(j);
    return depth;
}

} // namespace drape::bullet::detail
