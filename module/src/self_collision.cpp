// Particle-triangle self-collision with a spatial hash (see self_collision.hpp).
//
// Broadphase: a pair list, kept while it holds (pairsHold). It lists, for each particle, the
// triangles within reach = kReach x the thickness of it (exactly measured), found through a
// uniform grid of the particles (one entry each; cell size = the largest current triangle edge
// or twice the reach, whichever is larger, so a triangle's box grown by the reach covers at
// most 3 x 3 x 3 cells) that each triangle looks into. The grid is a hash table from cell key
// to its particles, built in time linear in the entries (buildTable). A pass reuses the list
// until a particle has moved half the reach beyond the thickness away from the cloth's mean
// move since it was built: no two particles then came nearer by more than that margin, so
// every pair within the thickness is listed. Cloth builds it afresh at the start of each step.
// Pairs are tested in the order of particles, then triangles, ascending; deterministic and free
// of per-step allocations once warm (samples/benchmarks/PERF.md: a still 41 x 41 curtain
// 13.0 -> 2.7 ms a frame against the grid of triangles rebuilt in every pass).
//
// Response for particle p and triangle (a, b, c) with closest point q = sum b_k x_k and unit
// normal n pointing to the side p was on at the previous step:
//   C = thickness - (x_p - q) . n > 0 is the constraint violation,
//   lambda = C / (w_p + sum b_k^2 w_k), x_p += w_p lambda n, x_k -= b_k w_k lambda n,
// the linearised position projection of the constraint (x_p - sum b_k x_k) . n >= thickness;
// the same weights remove an approaching relative normal velocity and apply friction.
#include "self_collision.hpp"

#include "layer_contact.hpp"

#include "drape/geometry.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace drape::detail {
namespace {

// What a pair keeps apart: the thickness, but at most 0.4 times the mesh's spacing there
// (the shortest rest edge at the particle or of the triangle). A particle lies 0.71 spacings
// from the far triangle of its own cell, and a thickness near that made a cloth squeezed in
// its plane or folded push its own cells apart: a 41 x 41 sheet of 2.5 cm with 1.5 cm,
// squeezed to 90 %, went from 1.2 J to 7 kJ; folded onto itself, to 185 J and strain 16. At
// half the spacing a fold passed through itself on 21 x 21 and 31 x 31 sheets; at 0.4 it
// rests on 21 x 21 to 61 x 61 (integration/README.md, review 12). (A cloth thicker than its
// mesh can show needs a coarser mesh.)
// A particle and a triangle within that of each other in the rest shape are neighbours, not a
// collision (0: not listed; on a mesh finer than the thickness, the triangles next to a
// particle's own): pushing them apart threw a flat sheet at rest apart (a 1.2 cm mesh with the
// default 1 cm: 59 J from nothing). (Neighbours in one surface: apart along it, not across.
// Two layers of the rest shape nearer than that still collide.)
constexpr double kSpacingShare = 0.4;

double pairThickness(const Vec3List& rest, Index p, const Triangle& t, double thickness,
                     double spacingAtParticle) {
    const Vec3 &a = rest[t[0]], &b = rest[t[1]], &c = rest[t[2]];
    const double edge2 = std::min({(b - a).squaredNorm(), (c - b).squaredNorm(),
                                   (a - c).squaredNorm(), spacingAtParticle * spacingAtParticle});
    const double keep = std::min(thickness, kSpacingShare * std::sqrt(edge2));
    Vec3 restBary;
    const Vec3 restOffset = rest[p] - closestPointOnTriangle(rest[p], a, b, c, restBary);
    if (restOffset.squaredNorm() >= keep * keep) return keep;
    const Vec3 restFace = (b - a).cross(c - a);
    const double across = std::abs(restOffset.dot(restFace));
    return across <= 0.5 * restOffset.norm() * restFace.norm() ? 0.0 : keep;
}

} // namespace

// The pair list: for each particle, the triangles (ascending) within `reach` of it at x; its
// own triangles and its rest-shape neighbours are left out here once instead of every pass.
void SelfCollider::buildPairs(const ClothTopology& topology, const Vec3List& x, double thickness,
                              double reach) {
    const auto& tris = topology.triangles();
    const auto& rest = topology.restPositions();
    const std::size_t n = x.size();
    double cell = 2.0 * reach;
    for (const auto& t : tris) {
        cell = std::max({cell, (x[t[0]] - x[t[1]]).norm(), (x[t[1]] - x[t[2]]).norm(),
                         (x[t[2]] - x[t[0]]).norm()});
    }
    const double invCell = 1.0 / cell;
    // The particles by cell (one entry each), then each triangle looks in the cells its box
    // grown by the reach covers.
    cells_.clear();
    particleCell_.resize(n);
    for (std::size_t p = 0; p < n; ++p) {
        const std::array<std::int64_t, 3> c = {cellCoord(x[p].x(), invCell),
                                               cellCoord(x[p].y(), invCell),
                                               cellCoord(x[p].z(), invCell)};
        particleCell_[p] = c;
        cells_.add(cellKey(c[0], c[1], c[2]), static_cast<Index>(p));
    }
    cells_.build();

    found_.clear();
    for (std::size_t ti = 0; ti < tris.size(); ++ti) {
        const auto& t = tris[ti];
        const Vec3 &a = x[t[0]], &b = x[t[1]], &c = x[t[2]];
        const Vec3 lo = a.cwiseMin(b).cwiseMin(c).array() - reach;
        const Vec3 hi = a.cwiseMax(b).cwiseMax(c).array() + reach;
        for (auto i = cellCoord(lo.x(), invCell); i <= cellCoord(hi.x(), invCell); ++i)
            for (auto j = cellCoord(lo.y(), invCell); j <= cellCoord(hi.y(), invCell); ++j)
                for (auto k = cellCoord(lo.z(), invCell); k <= cellCoord(hi.z(), invCell); ++k) {
                    const auto [first, last] = cells_.at(cellKey(i, j, k));
                    for (const Index* e = first; e != last; ++e) {
                        const Index p = *e;
                        // Another cell with the same key: p is looked at from its own only.
                        const auto& pc = particleCell_[p];
                        if (pc[0] != i || pc[1] != j || pc[2] != k) continue;
                        if (t[0] == p || t[1] == p || t[2] == p) continue;
                        const Vec3& xp = x[p];
                        if ((xp.array() > hi.array()).any() || (xp.array() < lo.array()).any())
                            continue;
                        Vec3 bary;
                        if ((xp - closestPointOnTriangle(xp, a, b, c, bary)).squaredNorm() >=
                            reach * reach)
                            continue;
                        const double keep = pairThickness(rest, p, t, thickness, shortestEdge_[p]);
                        if (keep == 0.0) continue;
                        found_.push_back({p, static_cast<Index>(ti), keep});
                    }
                }
    }
    // By particle, each particle's triangles ascending (the triangles were visited so).
    pairStart_.assign(n + 1, 0);
    for (const auto& f : found_)
        ++pairStart_[f.particle + 1];
    for (std::size_t p = 0; p < n; ++p)
        pairStart_[p + 1] += pairStart_[p];
    fill_.assign(pairStart_.begin(), pairStart_.end() - 1);
    pairTriangle_.resize(found_.size());
    pairThickness_.resize(found_.size());
    for (const auto& f : found_) {
        const std::size_t e = fill_[f.particle]++;
        pairTriangle_[e] = f.triangle;
        pairThickness_[e] = f.thickness;
    }
    built_.assign(x.begin(), x.end());
    builtThickness_ = thickness;
    builtReach_ = reach;
    valid_ = true;
}

bool SelfCollider::pairsHold(const Vec3List& x, double thickness) const {
    if (!valid_ || builtThickness_ != thickness || built_.size() != x.size()) return false;
    // A pair's distance changes by at most twice the largest move of a particle since the
    // list was built: while that stays within the reach beyond the thickness, every pair
    // nearer than the thickness is listed. Moves are measured from the cloth's mean move, so a
    // falling cloth keeps its list.
    return movedTogetherWithin({{&x, &built_}}, 0.5 * (builtReach_ - thickness));
}

SelfCollisionCounts SelfCollider::run(const ClothTopology& topology,
                                      const std::vector<double>& invMass, const Vec3List& xPrev,
                                      Vec3List& x, Vec3List& v, double thickness, double friction,
                                      int iterations) {
    SelfCollisionCounts counts;
    const auto& tris = topology.triangles();
    const std::size_t n = x.size();
    if (shortestEdge_.size() != n) { // the topology's: once
        shortestEdge_.assign(n, std::numeric_limits<double>::infinity());
        double widest = 0.0;
        for (const Spring& sp : topology.springs()) {
            shortestEdge_[sp.a] = std::min(shortestEdge_[sp.a], sp.restLength);
            shortestEdge_[sp.b] = std::min(shortestEdge_[sp.b], sp.restLength);
        }
        for (double e : shortestEdge_)
            if (std::isfinite(e)) widest = std::max(widest, e);
        largestKeep_ = kSpacingShare * widest;
    }
    // No pair keeps more than this (pairThickness): the list need reach no farther.
    thickness = std::min(thickness, largestKeep_);
    for (int iter = 0; iter < iterations; ++iter) {
        if (!pairsHold(x, thickness)) buildPairs(topology, x, thickness, kReach * thickness);

        std::size_t contactsThisPass = 0;
        for (std::size_t p = 0; p < n; ++p) {
            for (std::size_t e = pairStart_[p]; e < pairStart_[p + 1]; ++e) {
                const auto& t = tris[pairTriangle_[e]];
                const double keep = pairThickness_[e]; // <= thickness
                const double wp = invMass[p];
                const double w0 = invMass[t[0]], w1 = invMass[t[1]], w2 = invMass[t[2]];
                if (wp == 0.0 && w0 == 0.0 && w1 == 0.0 && w2 == 0.0) continue;
                ++counts.pairTests;
                const Vec3 &a = x[t[0]], &b = x[t[1]], &c = x[t[2]];
                // Beyond the triangle's box grown by what it keeps: farther than that
                // (the exact test below would say so too, at the cost of a closest point).
                const Vec3& xp0 = x[p];
                if ((xp0.array() > a.array().max(b.array()).max(c.array()) + keep).any() ||
                    (xp0.array() < a.array().min(b.array()).min(c.array()) - keep).any())
                    continue;
                Vec3 bary;
                const Vec3 q = closestPointOnTriangle(x[p], a, b, c, bary);
                if ((x[p] - q).squaredNorm() >= keep * keep) continue;
                Vec3 face = (b - a).cross(c - a);
                const double len = face.norm();
                if (!(len > 0.0)) continue;
                face /= len;
                // Side from the previous step; the current side if the particle was in the plane.
                const Vec3 facePrev = (xPrev[t[1]] - xPrev[t[0]]).cross(xPrev[t[2]] - xPrev[t[0]]);
                const Vec3 qPrev =
                    bary[0] * xPrev[t[0]] + bary[1] * xPrev[t[1]] + bary[2] * xPrev[t[2]];
                double side = (xPrev[p] - qPrev).dot(facePrev);
                if (side == 0.0) side = (x[p] - q).dot(face);
                const Vec3 nrm = side >= 0.0 ? face : Vec3(-face);
                const double gap = (x[p] - q).dot(nrm);
                const double violation = keep - gap;
                if (violation <= 0.0) continue;
                const double denom =
                    wp + bary[0] * bary[0] * w0 + bary[1] * bary[1] * w1 + bary[2] * bary[2] * w2;
                if (!(denom > 0.0)) continue;
                const LayerPoint particle{&x[p], &v[p], wp};
                const std::array<LayerPoint, 3> corners = {LayerPoint{&x[t[0]], &v[t[0]], w0},
                                                           LayerPoint{&x[t[1]], &v[t[1]], w1},
                                                           LayerPoint{&x[t[2]], &v[t[2]], w2}};
                if (heldFast(particle, corners, bary, denom)) continue;
                ++contactsThisPass;
                separateLayers(particle, corners, bary, nrm, violation, denom, friction);
            }
        }
        counts.contacts += contactsThisPass;
        if (contactsThisPass == 0) break;
    }
    return counts;
}

} // namespace drape::detail
