// Particle-triangle self-collision with a spatial hash (see self_collision.hpp).
//
// Broadphase: every triangle's bounding box, grown by the thickness, is entered into the
// cells of a uniform grid it covers (cell size = the largest current triangle edge or twice the
// thickness, whichever is larger, so a triangle covers at most 3 x 3 x 3 cells). A particle is
// tested only against the triangles listed in its own cell, in ascending order. The grid is a
// hash table from cell key to its triangles, built in time linear in the entries (buildTable;
// it replaced a sort of every (cell key, triangle) pair, which was most of the pass's cost):
// deterministic and free of per-step allocations once warm. A candidate outside the triangle's
// box grown by the thickness is rejected before its closest point is computed.
//
// Response for particle p and triangle (a, b, c) with closest point q = sum b_k x_k and unit
// normal n pointing to the side p was on at the previous step:
//   C = thickness - (x_p - q) . n > 0 is the constraint violation,
//   lambda = C / (w_p + sum b_k^2 w_k), x_p += w_p lambda n, x_k -= b_k w_k lambda n,
// the linearised position projection of the constraint (x_p - sum b_k x_k) . n >= thickness;
// the same weights remove an approaching relative normal velocity and apply friction.
#include "self_collision.hpp"

#include "drape/geometry.hpp"

#include <algorithm>
#include <cmath>

namespace drape::detail {
namespace {

std::int64_t cellCoord(double v, double invCell) {
    return static_cast<std::int64_t>(std::floor(v * invCell));
}

std::uint64_t cellKey(std::int64_t i, std::int64_t j, std::int64_t k) {
    // A hash: unequal cells may share a key, which only adds candidates the exact test rejects.
    const auto ui = static_cast<std::uint64_t>(i), uj = static_cast<std::uint64_t>(j),
               uk = static_cast<std::uint64_t>(k);
    return (ui * 73856093ull) ^ (uj * 19349663ull) ^ (uk * 83492791ull);
}

} // namespace

// The grid's table: each distinct key of cells_ gets a slot of an open-addressing hash table
// (linear probing, at least twice as many slots as entries), and the triangles of a key are
// listed contiguously in listed_, in the order cells_ has them (ascending triangle index): what
// sorting cells_ by (key, triangle) and searching it gave, in time linear in the entries.
void SelfCollider::buildTable() {
    std::size_t size = 16;
    while (size < 2 * cells_.size())
        size *= 2;
    const std::size_t mask = size - 1;
    slotKey_.resize(size); // read only where slotUsed_ is set
    slotUsed_.assign(size, 0);
    slotBegin_.assign(size + 1, 0);
    entrySlot_.resize(cells_.size());
    for (std::size_t e = 0; e < cells_.size(); ++e) {
        const std::uint64_t key = cells_[e].first;
        std::size_t slot = static_cast<std::size_t>(mix(key)) & mask;
        while (slotUsed_[slot] && slotKey_[slot] != key)
            slot = (slot + 1) & mask;
        slotUsed_[slot] = 1;
        slotKey_[slot] = key;
        ++slotBegin_[slot + 1];
        entrySlot_[e] = static_cast<std::uint32_t>(slot);
    }
    for (std::size_t k = 0; k < size; ++k)
        slotBegin_[k + 1] += slotBegin_[k];
    fill_.assign(slotBegin_.begin(), slotBegin_.end() - 1);
    listed_.resize(cells_.size());
    for (std::size_t e = 0; e < cells_.size(); ++e)
        listed_[fill_[entrySlot_[e]]++] = cells_[e].second;
    tableMask_ = mask;
}

std::pair<std::size_t, std::size_t> SelfCollider::trianglesAt(std::uint64_t key) const {
    std::size_t slot = static_cast<std::size_t>(mix(key)) & tableMask_;
    while (slotUsed_[slot]) {
        if (slotKey_[slot] == key) return {slotBegin_[slot], slotBegin_[slot + 1]};
        slot = (slot + 1) & tableMask_;
    }
    return {0, 0};
}

SelfCollisionCounts SelfCollider::run(const ClothTopology& topology,
                                      const std::vector<double>& invMass, const Vec3List& xPrev,
                                      Vec3List& x, Vec3List& v, double thickness, double friction,
                                      int iterations) {
    SelfCollisionCounts counts;
    const auto& tris = topology.triangles();
    const auto& rest = topology.restPositions();
    const std::size_t n = x.size();
    for (int iter = 0; iter < iterations; ++iter) {
        double cell = 2.0 * thickness;
        for (const auto& t : tris) {
            cell = std::max({cell, (x[t[0]] - x[t[1]]).norm(), (x[t[1]] - x[t[2]]).norm(),
                             (x[t[2]] - x[t[0]]).norm()});
        }
        const double invCell = 1.0 / cell;
        cells_.clear();
        for (std::size_t ti = 0; ti < tris.size(); ++ti) {
            const auto& t = tris[ti];
            const Vec3 lo = x[t[0]].cwiseMin(x[t[1]]).cwiseMin(x[t[2]]).array() - thickness;
            const Vec3 hi = x[t[0]].cwiseMax(x[t[1]]).cwiseMax(x[t[2]]).array() + thickness;
            for (auto i = cellCoord(lo.x(), invCell); i <= cellCoord(hi.x(), invCell); ++i)
                for (auto j = cellCoord(lo.y(), invCell); j <= cellCoord(hi.y(), invCell); ++j)
                    for (auto k = cellCoord(lo.z(), invCell); k <= cellCoord(hi.z(), invCell); ++k)
                        cells_.emplace_back(cellKey(i, j, k), static_cast<Index>(ti));
        }
        buildTable();

        std::size_t contactsThisPass = 0;
        for (std::size_t p = 0; p < n; ++p) {
            const Vec3 xp = x[p];
            const std::uint64_t key = cellKey(
                cellCoord(xp.x(), invCell), cellCoord(xp.y(), invCell), cellCoord(xp.z(), invCell));
            const auto [first, last] = trianglesAt(key);
            for (std::size_t e = first; e < last; ++e) {
                const auto& t = tris[listed_[e]];
                if (t[0] == p || t[1] == p || t[2] == p) continue;
                const double wp = invMass[p];
                const double w0 = invMass[t[0]], w1 = invMass[t[1]], w2 = invMass[t[2]];
                if (wp == 0.0 && w0 == 0.0 && w1 == 0.0 && w2 == 0.0) continue;
                ++counts.pairTests;
                const Vec3 &a = x[t[0]], &b = x[t[1]], &c = x[t[2]];
                // Beyond the triangle's box grown by the thickness: farther than the thickness
                // (the exact test below would say so too, at the cost of a closest point).
                const Vec3& xp0 = x[p];
                if ((xp0.array() > a.array().max(b.array()).max(c.array()) + thickness).any() ||
                    (xp0.array() < a.array().min(b.array()).min(c.array()) - thickness).any())
                    continue;
                Vec3 bary;
                const Vec3 q = closestPointOnTriangle(x[p], a, b, c, bary);
                if ((x[p] - q).squaredNorm() >= thickness * thickness) continue;
                // A particle and a triangle that lie within the thickness of each other in the
                // rest shape are neighbours, not a collision (on a mesh finer than the thickness,
                // the triangles next to a particle's own): pushing them the thickness apart
                // threw a flat sheet at rest apart (a 1.2 cm mesh with the default 1 cm: 59 J
                // from nothing).
                // (Neighbours in one surface: apart along it, not across. Two layers of the
                // rest shape closer than the thickness still collide.)
                Vec3 restBary;
                const Vec3 restQ =
                    closestPointOnTriangle(rest[p], rest[t[0]], rest[t[1]], rest[t[2]], restBary);
                const Vec3 restOffset = rest[p] - restQ;
                if (restOffset.squaredNorm() < thickness * thickness) {
                    const Vec3 restFace = (rest[t[1]] - rest[t[0]]).cross(rest[t[2]] - rest[t[0]]);
                    const double across = std::abs(restOffset.dot(restFace));
                    if (across <= 0.5 * restOffset.norm() * restFace.norm()) continue;
                }
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
                const double violation = thickness - gap;
                if (violation <= 0.0) continue;
                const double denom =
                    wp + bary[0] * bary[0] * w0 + bary[1] * bary[1] * w1 + bary[2] * bary[2] * w2;
                if (!(denom > 0.0)) continue;
                ++contactsThisPass;
                const double lambda = violation / denom;
                x[p] += (wp * lambda) * nrm;
                for (int k = 0; k < 3; ++k)
                    x[t[k]] -= (bary[k] * invMass[t[k]] * lambda) * nrm;
                // Velocity: remove approach along the normal, then Coulomb friction.
                const Vec3 vTri = bary[0] * v[t[0]] + bary[1] * v[t[1]] + bary[2] * v[t[2]];
                const Vec3 rel = v[p] - vTri;
                const double vn = rel.dot(nrm);
                if (vn < 0.0) {
                    const double jn = -vn / denom;
                    Vec3 dv = jn * nrm;
                    const Vec3 vt = rel - vn * nrm;
                    const double vtLen = vt.norm();
                    if (vtLen > 0.0 && friction > 0.0) {
                        const double jt = std::min(vtLen / denom, friction * jn);
                        dv -= (jt / vtLen) * vt;
                    }
                    v[p] += wp * dv;
                    for (int k = 0; k < 3; ++k)
                        v[t[k]] -= (bary[k] * invMass[t[k]]) * dv;
                }
            }
        }
        counts.contacts += contactsThisPass;
        if (contactsThisPass == 0) break;
    }
    return counts;
}

} // namespace drape::detail
