// Springs against box bodies (see contacts.hpp): a spring whose ends rest on two faces of a
// box wraps its edge, and the straight segment between the two particles cuts the corner,
// so the edge shows through the cloth between them. Each spring with an end touching a box is
// tested as a segment against the box (its deepest point by the signed distance, convex
// along the segment); a segment nearer than the thickness is moved out at that point, its
// ends sharing the move and the stopping impulse by their weights, as triangle contacts
// share theirs.
#include "contacts.hpp"
#include "shape_queries.hpp"

#include <btBulletCollisionCommon.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace drape::bullet::detail {

void ContactSolver::collideEdges(Cloth& c) {
    const auto& springs = c.topology().springs();
    const Vec3List& x = c.positions();
    const auto& w = c.inverseMasses();
    // Per particle with a contact on a box: the box and the region of space around it the
    // particle is in (a face's prism, an edge's wedge, a corner; boxRegion), once per pass.
    if (std::none_of(bodies.begin(), bodies.end(), [](const BodySnapshot& b) { return b.box; }))
        return;
    edgeBody_.assign(c.particleCount(), -1);
    edgeRegion_.resize(c.particleCount());
    edgeCached_.assign(c.particleCount(), 0);
    edgeLocal_.resize(c.particleCount());
    edgeGradient_.resize(c.particleCount());
    edgeDistance_.resize(c.particleCount());
    bool onBox = false;
    for (const ContactRecord& r : records->contacts) {
        const BodySnapshot& b = bodies[r.body];
        if (!b.box || edgeBody_[r.particle] >= 0) continue;
        edgeBody_[r.particle] = std::int32_t(r.body);
        onBox = true;
        edgeRegion_[r.particle] = boxRegion(b.boxHalf, b.pose.toLocal(x[r.particle]));
    }
    // And the free particles within a spring's length of a box that have no contact yet:
    // the box can cut a spring between two of them before either touches it (a ridge landing
    // between two columns).
    // (Blocks of kBlock consecutive particles, each with the box of their positions: a box body
    // whose reach misses a block's box has none of its particles.)
    const double reach = 1.1 * longestSpring(c);
    const std::size_t n = x.size(), nBlocks = (n + kBlock - 1) / kBlock;
    edgeBlocks_.assign(nBlocks, Block{});
    for (std::size_t i = 0; i < n; ++i)
        edgeBlocks_[i / kBlock].grow(x[i]);
    for (std::uint32_t bi = 0; bi < bodies.size(); ++bi) {
        const BodySnapshot& b = bodies[bi];
        if (!b.box) continue;
        const Vec3 lo = b.aabbMin.array() - reach, hi = b.aabbMax.array() + reach;
        for (std::size_t k = 0; k < nBlocks; ++k) {
            const Block& bl = edgeBlocks_[k];
            if ((bl.hi.array() < lo.array()).any() || (bl.lo.array() > hi.array()).any()) continue;
            for (std::size_t i = k * kBlock, end = std::min(n, i + kBlock); i < end; ++i) {
                if (edgeBody_[i] >= 0 || w[i] == 0.0) continue;
                if ((x[i].array() < lo.array()).any() || (x[i].array() > hi.array()).any())
                    continue;
                edgeBody_[i] = std::int32_t(bi);
                edgeRegion_[i] = boxRegion(b.boxHalf, b.pose.toLocal(x[i]));
                onBox = true;
            }
        }
    }
    if (!onBox) return; // no particle near a box
    // The boxes that do not move, and whether each kept its pose and size since the last pass
    // (then the springs found clear of it before may skip the test, edgeClear_).
    boxVersion_.assign(bodies.size(), 0);
    stillBoxesNext_.clear();
    for (std::uint32_t bi = 0; bi < bodies.size(); ++bi) {
        const BodySnapshot& b = bodies[bi];
        if (!b.box || b.dynamicBody || !b.still) continue;
        const auto seen = std::find_if(stillBoxes_.begin(), stillBoxes_.end(),
                                       [&](const StillBox& k) { return k.body == b.object; });
        const bool same = seen != stillBoxes_.end() && seen->pose.t == b.pose.t &&
                          seen->pose.R == b.pose.R && seen->half == b.boxHalf;
        boxVersion_[bi] = same ? seen->version : ++lastBoxVersion_;
        stillBoxesNext_.push_back({b.object, b.pose, b.boxHalf, boxVersion_[bi]});
    }
    stillBoxes_.swap(stillBoxesNext_);
    edgeClear_.resize(springs.size());
    // Found clear of box bi before, and neither end has moved that far since.
    auto stillClear = [&](std::size_t si, const Spring& s, std::int32_t bi) {
        const std::uint64_t version = boxVersion_[std::size_t(bi)];
        const EdgeClearance& clear = edgeClear_[si];
        const double room2 = clear.room * clear.room;
        return version != 0 && clear.version == version &&
               (x[s.a] - clear.a).squaredNorm() < room2 && (x[s.b] - clear.b).squaredNorm() < room2;
    };
    for (std::size_t si = 0; si < springs.size(); ++si) {
        const Spring& s = springs[si];
        const std::int32_t ba = edgeBody_[s.a], bb = edgeBody_[s.b];
        if ((ba < 0 && bb < 0) || (w[s.a] == 0.0 && w[s.b] == 0.0)) continue;
        // Both ends in one face's prism of the same box: nothing to test (collideSpringWithBox
        // says why), decided here for the many springs lying on a face.
        if (ba >= 0 &&
            !(bb == ba && edgeRegion_[s.a] == edgeRegion_[s.b] &&
              isBoxFaceRegion(edgeRegion_[s.a])) &&
            !stillClear(si, s, ba))
            collideSpringWithBox(c, si, std::uint32_t(ba));
        if (bb >= 0 && bb != ba && !stillClear(si, s, bb))
            collideSpringWithBox(c, si, std::uint32_t(bb));
    }
}

void ContactSolver::collideSpringWithBox(Cloth& c, std::size_t si, std::uint32_t bi) {
    BodySnapshot& b = bodies[bi];
    // A dynamic box lighter than the cloth is left to the particle contacts: the corner
    // pushes of a whole draped cloth would tip it.
    if (b.dynamicBody && b.invMass * clothMass_ > 1.0) return;
    const Spring& s = c.topology().springs()[si];
    Vec3List& x = c.mutablePositions();
    const std::uint64_t version = boxVersion_[bi];
    EdgeClearance& clear = edgeClear_[si];
    const auto& w = c.inverseMasses();
    const double h = contact_.thickness;
    // A lower bound on the spring's distance from the box beyond the thickness: kept for the
    // next passes. The bound is measured in the box's frame, whose rotation comes from Bullet's
    // single precision (it stretches lengths by up to about 4e-7), and the ends' moves in the
    // world: the room keeps a relative margin far above both, and one above the rounding.
    auto keepClear = [&](double lowerBound) {
        const double room = (lowerBound - h) * (1.0 - 1e-5) - 1e-6 * h;
        if (version != 0 && room > 0.0) clear = {version, x[s.a], x[s.b], room};
    };
    // Both ends in one face's prism (convex): the distance is linear along the spring and its
    // ends, which their own contacts hold, are the nearest points.
    auto region = [&](Index i) {
        return edgeBody_[i] == std::int32_t(bi) ? edgeRegion_[i]
                                                : boxRegion(b.boxHalf, b.pose.toLocal(x[i]));
    };
    const int ra = region(s.a);
    if (ra == region(s.b) && isBoxFaceRegion(ra)) return;
    // An end's place in the box's frame and its signed distance, once per particle and pass
    // for the particles near this box (a particle has about six springs), until it moves.
    auto endOf = [&](Index i, Vec3& p, Vec3& g) {
        if (edgeBody_[i] != std::int32_t(bi)) {
            p = b.pose.toLocal(x[i]);
            return boxSignedDistance(b.boxHalf, p, g);
        }
        if (!edgeCached_[i]) {
            edgeLocal_[i] = b.pose.toLocal(x[i]);
            edgeDistance_[i] = boxSignedDistance(b.boxHalf, edgeLocal_[i], edgeGradient_[i]);
            edgeCached_[i] = 1;
        }
        p = edgeLocal_[i];
        g = edgeGradient_[i];
        return edgeDistance_[i];
    };
    Vec3 pa, pb, ga, gb;
    const double da = endOf(s.a, pa, ga);
    const double db = endOf(s.b, pb, gb);
    // The distance is 1-Lipschitz: no point of the spring is nearer than (da + db - length) / 2.
    // An end inside the box is its particle contact's to resolve (a deep impact), not a spring
    // cutting a corner.
    if (ga == gb || da < 0.0 || db < 0.0) return;
    // An end coming out of a body slowly (contact.depenetrationSpeed) takes the spring with it.
    if (exiting(s.a) || exiting(s.b)) return;
    if (const double apart = 0.5 * (da + db - (pb - pa).norm()); apart >= h) {
        keepClear(apart);
        return;
    }
    const SegmentDeepest deepest = deepestOnSegment(b.boxHalf, pa, pb, ga, gb);
    const double t = deepest.t, d = deepest.d;
    const Vec3& g = deepest.g;
    // The signed distance is convex: it lies above its tangent at the deepest point found,
    // d + (g . (pb - pa)) (t' - t) along the spring, whose least value is at an end.
    const double slope = g.dot(pb - pa);
    keepClear(d + std::min(-slope * t, slope * (1.0 - t)));
    // Near an end the particle's own contact holds it; only the middle of the spring.
    if (t < 0.05 || t > 0.95) return;
    const Vec3 local = pa + t * (pb - pa);
    if (!(d < h) || d < -h) return; // (deeper: a particle contact's, after an impact)
    const double beta[2] = {1.0 - t, t};
    const Index ends[2] = {s.a, s.b};
    const double weight = beta[0] * beta[0] * w[s.a] + beta[1] * beta[1] * w[s.b];
    if (!(weight > 0.0)) return;
    const Vec3 n = b.pose.R * g;
    // A dynamic box pressing the spring into a static or kinematic body that holds an end
    // (a crate on a rug on the floor) moves nothing: see collideParticle.
    if (b.dynamicBody && (heldAgainst(x, s.a, n) || heldAgainst(x, s.b, n))) return;
    const double depth = h - d;
    const Vec3 point = b.pose.toWorld(local - d * g); // on the surface
    stats.maxDepth = std::max(stats.maxDepth, depth);
    ++stats.edgeContacts;
    for (int k = 0; k < 2; ++k) {
        const Index i = ends[k];
        if (w[i] == 0.0) continue;
        x[i] += (beta[k] * w[i] * depth / weight) * n;
        edgeCached_[i] = 0;
        touching_[i] = 1;
        projected_.push_back(i);
        boxes_.update(i, x[i], stepStart()[i], false);
        // No limiter plane: a spring pushed off an edge its pinned neighbours hold it against
        // would make the walk spend its whole budget every step.
    }
    if (!b.dynamicBody) edgeHits_.push_back(EdgeHit{si, bi, t, n, point});
    stopApproach(c, si, b, t, n, point, true);
}

void ContactSolver::stopApproach(Cloth& c, std::size_t si, BodySnapshot& b, double t, const Vec3& n,
                                 const Vec3& point, bool friction) {
    const Spring& s = c.topology().springs()[si];
    Vec3List& v = c.mutableVelocities();
    const auto& w = c.inverseMasses();
    const double beta[2] = {1.0 - t, t};
    const Index ends[2] = {s.a, s.b};
    const double weight = beta[0] * beta[0] * w[s.a] + beta[1] * beta[1] * w[s.b];
    if (!(weight > 0.0)) return;
    const Vec3 rel = beta[0] * v[s.a] + beta[1] * v[s.b] - b.velocityAt(point);
    const double vn = rel.dot(n);
    if (vn >= 0.0) return;
    auto share = [&](const Vec3& j) {
        for (int k = 0; k < 2; ++k)
            v[ends[k]] += (beta[k] * w[ends[k]]) * j;
        exchange(b, j, point);
    };
    const double lambda = -vn / (weight + b.inverseMassAlong(point, n));
    share(lambda * n);
    Vec3 j;
    if (friction && coulombImpulse(rel, n, weight, b, point, b.friction * lambda, j)) share(j);
}

void ContactSolver::stopEdgeApproach(Cloth& c) {
    // Only against boxes the cloth does not move (collideSpringWithBox lists only those).
    // Against a dynamic box the stop would also hand the walk's pull on the spring (which the
    // pins hold) to the body; measured, that made a 20 kg box thrown through a banner on two
    // light posts stretch the spring between them to 0.32 instead of 0.19, and a cloth on a
    // stack of dynamic boxes fall asleep 1.5 s later.
    for (const EdgeHit& e : edgeHits_)
        stopApproach(c, e.spring, bodies[e.body], e.t, e.normal, e.point, false);
}

} // namespace drape::bullet::detail
