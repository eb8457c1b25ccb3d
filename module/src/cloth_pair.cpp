// Collision between two cloths (see drape/cloth_pair.hpp).
//
// Broadphase, each way (the particles of one cloth against the triangles of the other): the
// triangles whose swept boxes (their corners at the step's start and end, grown by the reach)
// reach the particles' swept box go into a uniform grid, a hash table of cells (CellTable,
// built in time linear in its entries); the cell is the mean extent of those boxes and at
// least the reach (doubled while the boxes would fill more than eight cells each on average, so
// a fast cloth cannot make the table explode). Each particle looks in the cells its path's box
// covers and keeps the triangles whose swept box holds that path's box. Hash keys of unequal
// cells may meet: that only adds candidates the box test drops.
//
// Narrowphase, for particle p and triangle (a, b, c) at the step's end, q the closest point
// of the triangle to p with weights bary, n the unit normal turned toward the side p was on
// at the step's start (the sign of (p0 - q0) . n0, q0 with the same weights): a contact when
// the gap (p - q) . n is below the thickness and p lies over the triangle, or beside its rim
// by less than the thickness and less than it lies off its plane; a gap below zero (p crossed it)
// only as deep as p's move relative to the triangle in the step, plus the thickness, could have
// carried it. The response is self-collision's (layer_contact.hpp).
#include "drape/cloth_pair.hpp"

#include "drape/error.hpp"
#include "drape/geometry.hpp"
#include "layer_contact.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace drape {
namespace {

using detail::cellCoord;
using detail::cellKey;

struct Box {
    Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity());
    Vec3 hi = Vec3::Constant(-std::numeric_limits<double>::infinity());
    void add(const Vec3& p) {
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
    }
    bool overlaps(const Box& o) const {
        return (lo.array() <= o.hi.array()).all() && (o.lo.array() <= hi.array()).all();
    }
};

Box sweptBox(const Vec3List& start, const Vec3List& end) {
    Box b;
    for (std::size_t i = 0; i < end.size(); ++i) {
        b.add(start[i]);
        b.add(end[i]);
    }
    return b;
}

Box triangleBox(const Triangle& t, const Vec3List& start, const Vec3List& end, double grow) {
    Box b;
    for (int k = 0; k < 3; ++k) {
        b.add(start[t[k]]);
        b.add(end[t[k]]);
    }
    b.lo.array() -= grow;
    b.hi.array() += grow;
    return b;
}

/// Cells a box covers along each axis at cell size `cell` (as a double: no overflow).
double cellsOf(const Box& b, double cell) {
    double n = 1.0;
    for (int d = 0; d < 3; ++d)
        n *= std::floor(b.hi[d] / cell) - std::floor(b.lo[d] / cell) + 1.0;
    return n;
}

} // namespace

void validateClothPair(const ClothPairSettings& s, const std::string& who) {
    if (!std::isfinite(s.thickness) || !(s.thickness > 0.0))
        throw Error(ErrorCode::InvalidArgument, who +
                                                    "thickness must be positive and finite, got " +
                                                    std::to_string(s.thickness));
    if (!std::isfinite(s.friction) || s.friction < 0.0)
        throw Error(ErrorCode::InvalidArgument,
                    who + "friction must be >= 0 and finite, got " + std::to_string(s.friction));
    if (s.iterations < 1)
        throw Error(ErrorCode::InvalidArgument,
                    who + "iterations must be >= 1, got " + std::to_string(s.iterations));
}

ClothPairCollider::ClothPairCollider() : cells_(std::make_unique<detail::CellTable>()) {}
ClothPairCollider::~ClothPairCollider() = default;
ClothPairCollider::ClothPairCollider(ClothPairCollider&&) noexcept = default;
ClothPairCollider& ClothPairCollider::operator=(ClothPairCollider&&) noexcept = default;

ClothPairCollider::ClothPairCollider(const ClothPairCollider& other)
    : builtA_(other.builtA_),
      builtB_(other.builtB_), builtAt_{other.builtAt_[0], other.builtAt_[1]},
      builtReach_(other.builtReach_), cells_(std::make_unique<detail::CellTable>()), ab_(other.ab_),
      ba_(other.ba_), abTris_(other.abTris_), baTris_(other.baTris_) {}

ClothPairCollider& ClothPairCollider::operator=(const ClothPairCollider& other) {
    if (this != &other) *this = ClothPairCollider(other);
    return *this;
}

void ClothPairCollider::findPairs(const Cloth& from, const Vec3List& fromStart, const Cloth& onto,
                                  const Vec3List& ontoStart, double reach,
                                  std::vector<std::pair<Index, Index>>& pairs) {
    pairs.clear();
    const Vec3List& xf = from.positions();
    const Vec3List& xo = onto.positions();
    const auto& tris = onto.topology().triangles();
    const Box paths = sweptBox(fromStart, xf);
    // The triangles that reach the particles' box, and the mean extent of their boxes.
    std::vector<Box> boxes;
    std::vector<Index> kept;
    Box region; // of the triangles kept
    double extent = 0.0;
    for (std::size_t ti = 0; ti < tris.size(); ++ti) {
        const Box b = triangleBox(tris[ti], ontoStart, xo, reach);
        if (!b.overlaps(paths)) continue;
        kept.push_back(static_cast<Index>(ti));
        boxes.push_back(b);
        region.add(b.lo);
        region.add(b.hi);
        extent += (b.hi - b.lo).maxCoeff();
    }
    if (kept.empty()) return;
    double cell = std::max(reach, extent / static_cast<double>(kept.size()));
    for (int tries = 0; tries < 64; ++tries) {
        double entries = 0.0;
        for (const Box& b : boxes)
            entries += cellsOf(b, cell);
        if (entries <= 8.0 * static_cast<double>(kept.size()) + 64.0) break;
        cell *= 2.0;
    }
    const double invCell = 1.0 / cell;
    if (!cells_) cells_ = std::make_unique<detail::CellTable>(); // moved from
    detail::CellTable& table = *cells_;
    table.clear();
    for (std::size_t e = 0; e < kept.size(); ++e) {
        const Box& b = boxes[e];
        for (auto i = cellCoord(b.lo.x(), invCell); i <= cellCoord(b.hi.x(), invCell); ++i)
            for (auto j = cellCoord(b.lo.y(), invCell); j <= cellCoord(b.hi.y(), invCell); ++j)
                for (auto k = cellCoord(b.lo.z(), invCell); k <= cellCoord(b.hi.z(), invCell); ++k)
                    table.add(cellKey(i, j, k), static_cast<Index>(e));
    }
    table.build();
    for (std::size_t p = 0; p < xf.size(); ++p) {
        Box path;
        path.add(fromStart[p]);
        path.add(xf[p]);
        if (!path.overlaps(region)) continue;
        near_.clear();
        // The cells of the path's part in the triangles' region; a path across more cells than
        // there are entries (a particle thrown far in one step) looks at every box instead.
        Box cellsBox;
        cellsBox.lo = path.lo.cwiseMax(region.lo);
        cellsBox.hi = path.hi.cwiseMin(region.hi);
        if (cellsOf(cellsBox, cell) > static_cast<double>(table.size())) {
            for (std::size_t e = 0; e < boxes.size(); ++e)
                if (boxes[e].overlaps(path)) near_.push_back(static_cast<Index>(e));
        } else {
            for (auto i = cellCoord(cellsBox.lo.x(), invCell);
                 i <= cellCoord(cellsBox.hi.x(), invCell); ++i)
                for (auto j = cellCoord(cellsBox.lo.y(), invCell);
                     j <= cellCoord(cellsBox.hi.y(), invCell); ++j)
                    for (auto k = cellCoord(cellsBox.lo.z(), invCell);
                         k <= cellCoord(cellsBox.hi.z(), invCell); ++k) {
                        const auto [first, last] = table.at(cellKey(i, j, k));
                        for (const Index* e = first; e != last; ++e)
                            if (boxes[*e].overlaps(path)) near_.push_back(*e);
                    }
        }
        std::sort(near_.begin(), near_.end());
        near_.erase(std::unique(near_.begin(), near_.end()), near_.end());
        // Within the reach of the triangle now, give or take what both moved in the step (the
        // box test above is looser: a particle over a flat cloth listed a dozen of its
        // triangles instead of the five or six near it).
        const double own = (xf[p] - fromStart[p]).norm();
        for (const Index e : near_) {
            const Triangle& t = tris[kept[e]];
            const double moved = own + std::max({(xo[t[0]] - ontoStart[t[0]]).norm(),
                                                 (xo[t[1]] - ontoStart[t[1]]).norm(),
                                                 (xo[t[2]] - ontoStart[t[2]]).norm()});
            Vec3 bary;
            const Vec3 q = closestPointOnTriangle(xf[p], xo[t[0]], xo[t[1]], xo[t[2]], bary);
            if ((xf[p] - q).norm() > reach + moved) continue;
            pairs.emplace_back(static_cast<Index>(p), kept[e]);
        }
    }
}

// A pair not listed was farther apart than the reach at the end of the step the lists were
// built for (by more than both moved in that step, so it came no nearer than the reach then
// either). A pair's distance does not see a translation of both cloths: since then every
// particle of both cloths at the start of this step is within `slack` of where it was at that
// end moved by one common translation (the mean move of all their particles), and so is every
// particle at the step's end with another. Then so is every point of a triangle (an average of
// its corners), and every point of the step's straight paths (with the translation between the
// two). So the pair is still farther apart than the reach less twice the slack, the thickness,
// all through this step: no contact, no crossing. (A cape and a skirt on a running character
// keep their lists.)
bool ClothPairCollider::listsHold(const Cloth& a, const Vec3List& aStart, const Cloth& b,
                                  const Vec3List& bStart, double thickness) const {
    if (builtA_ != &a || builtB_ != &b || builtReach_ != kReach * thickness ||
        builtAt_[0].size() != a.particleCount() || builtAt_[1].size() != b.particleCount())
        return false;
    const double slack = 0.5 * (builtReach_ - thickness);
    return detail::movedTogetherWithin({{&aStart, &builtAt_[0]}, {&bStart, &builtAt_[1]}}, slack) &&
           detail::movedTogetherWithin(
               {{&a.positions(), &builtAt_[0]}, {&b.positions(), &builtAt_[1]}}, slack);
}

ClothPairStats ClothPairCollider::collide(Cloth& a, const Vec3List& aStart, Cloth& b,
                                          const Vec3List& bStart, const ClothPairSettings& s,
                                          double dt) {
    validateClothPair(s, "ClothPairSettings::");
    if (&a == &b)
        throw Error(ErrorCode::InvalidArgument,
                    "collideCloths: a cloth with itself (that is ClothSettings::selfCollision)");
    if (a.inStep() || b.inStep())
        throw Error(ErrorCode::InvalidArgument,
                    "collideCloths: not allowed during a cloth's own step (from a stage)");
    if (aStart.size() != a.particleCount() || bStart.size() != b.particleCount())
        throw Error(ErrorCode::InvalidArgument,
                    "collideCloths: the start positions have " + std::to_string(aStart.size()) +
                        " and " + std::to_string(bStart.size()) + " entries, the cloths " +
                        std::to_string(a.particleCount()) + " and " +
                        std::to_string(b.particleCount()) + " particles");
    if (!std::isfinite(dt) || !(dt > 0.0))
        throw Error(ErrorCode::InvalidArgument,
                    "collideCloths: the step must be positive and finite, got " +
                        std::to_string(dt));
    ClothPairStats stats;
    const bool aAsleep = a.isAsleep(), bAsleep = b.isAsleep();
    if (aAsleep && bAsleep) return stats; // neither moved
    const double h = s.thickness;
    {
        Box ba = sweptBox(aStart, a.positions()), bb = sweptBox(bStart, b.positions());
        ba.lo.array() -= h;
        ba.hi.array() += h;
        if (!ba.overlaps(bb)) return stats;
    }
    if (!listsHold(a, aStart, b, bStart, h)) {
        findPairs(a, aStart, b, bStart, kReach * h, ab_);
        findPairs(b, bStart, a, aStart, kReach * h, ba_);
        const auto trianglesOf = [](const std::vector<std::pair<Index, Index>>& pairs,
                                    std::vector<Index>& out) {
            out.clear();
            for (const auto& pr : pairs)
                out.push_back(pr.second);
            std::sort(out.begin(), out.end());
            out.erase(std::unique(out.begin(), out.end()), out.end());
        };
        trianglesOf(ab_, abTris_);
        trianglesOf(ba_, baTris_);
        builtA_ = &a;
        builtB_ = &b;
        builtAt_[0] = a.positions();
        builtAt_[1] = b.positions();
        builtReach_ = kReach * h;
        stats.listsBuilt = true;
    }
    if (ab_.empty() && ba_.empty()) return stats;

    // A sleeping cloth is woken by an approach faster than resting on it (|g| dt a step) by
    // the speed of a fall from its sleep distance, sqrt(2 |g| d) (without gravity, d over its
    // quiet time).
    const double g = std::max(a.settings().gravity.norm(), b.settings().gravity.norm());
    const auto wake = [g, dt](const SleepSettings& sleep) {
        return g * dt + std::max(std::sqrt(2.0 * g * sleep.distance), sleep.distance / sleep.time);
    };
    const double wakeA = wake(a.settings().sleep), wakeB = wake(b.settings().sleep);
    bool movedA = false, movedB = false;
    // Particles of `pc` (asleep: no give) against the triangles of `tc`.
    // Each pass looks at the triangles' normals (now, once a pass; and at the start) from these
    // arrays, each triangle once instead of once a pair.
    const auto normals = [](const std::vector<Index>& listed, const Cloth& tc, const Vec3List& x,
                            std::vector<Vec3>& out, bool unit) {
        const auto& tris = tc.topology().triangles();
        out.resize(tris.size());
        for (const Index ti : listed) {
            const Triangle& t = tris[ti];
            const Vec3 face = (x[t[1]] - x[t[0]]).cross(x[t[2]] - x[t[0]]);
            const double len = face.norm();
            out[ti] = !unit ? face : len > 0.0 ? Vec3(face / len) : Vec3(Vec3::Zero());
        }
    };
    normals(abTris_, b, bStart, startFace_[0], false);
    normals(baTris_, a, aStart, startFace_[1], false);
    // Particles of `pc` (asleep: no give) against the triangles of `tc`.
    const auto pass = [&](const std::vector<std::pair<Index, Index>>& pairs,
                          const std::vector<Index>& listed, int dir, Cloth& pc,
                          const Vec3List& pStart, bool pAsleep, double pWake, bool& pMoved,
                          bool& pWoken, Cloth& tc, const Vec3List& tStart, bool tAsleep,
                          double tWake, bool& tMoved, bool& tWoken) {
        std::size_t contacts = 0;
        Vec3List& xp = pc.state_.x;
        Vec3List& vp = pc.state_.v;
        Vec3List& xt = tc.state_.x;
        Vec3List& vt = tc.state_.v;
        const std::vector<double>& mp = pc.invMass_;
        const std::vector<double>& mt = tc.invMass_;
        const auto& tris = tc.topology().triangles();
        normals(listed, tc, xt, unitFace_[dir], true);
        const std::vector<Vec3>& unitFace = unitFace_[dir];
        const std::vector<Vec3>& startFace = startFace_[dir];
        for (const auto& [p, ti] : pairs) {
            const Triangle& t = tris[ti];
            const double wp = pAsleep ? 0.0 : mp[p];
            const double w0 = tAsleep ? 0.0 : mt[t[0]], w1 = tAsleep ? 0.0 : mt[t[1]],
                         w2 = tAsleep ? 0.0 : mt[t[2]];
            if (wp == 0.0 && w0 == 0.0 && w1 == 0.0 && w2 == 0.0) continue;
            ++stats.pairTests;
            // The side p started on (of the triangle's plane at the start), the gap now along
            // the normal toward it (the same for every point of the plane): most pairs end
            // here, before the closest point. The normal is the pass's; the exact one (the
            // corners may have moved in the pass) for a contact.
            // A particle that started in the triangle's plane (within a thousandth of the
            // thickness) has no side: two cloths lying in one plane, overlapping at their
            // edges (two curtain panels meeting), are left to pass in it until one leaves it.
            const double side = (pStart[p] - tStart[t[0]]).dot(startFace[ti]);
            if (std::abs(side) <= 1e-3 * h * startFace[ti].norm()) continue;
            const Vec3& x0 = xt[t[0]];
            if ((side >= 0.0 ? 1.0 : -1.0) * (xp[p] - x0).dot(unitFace[ti]) >= h) continue;
            const Vec3 &x1 = xt[t[1]], &x2 = xt[t[2]];
            Vec3 face = (x1 - x0).cross(x2 - x0);
            const double len = face.norm();
            if (!(len > 0.0)) continue;
            face /= len;
            const Vec3 nrm = side >= 0.0 ? face : Vec3(-face);
            const double gap = (xp[p] - x0).dot(nrm);
            if (gap >= h) continue;
            if (gap < 0.0) {
                // Crossed: only as deep as p's move relative to the triangle in the step could
                // have carried it (at most its own move and its corners' largest).
                const double reach =
                    (xp[p] - pStart[p]).norm() +
                    std::max({(x0 - tStart[t[0]]).norm(), (x1 - tStart[t[1]]).norm(),
                              (x2 - tStart[t[2]]).norm()}) +
                    h;
                if (-gap > reach) continue;
            }
            Vec3 bary;
            const Vec3 off = xp[p] - closestPointOnTriangle(xp[p], x0, x1, x2, bary);
            // Beside the triangle rather than over it: the nearest point on its rim, and the
            // particle no farther off the plane than it is beside the rim (a cloth lying next
            // to the other in its plane, their edges a few millimetres apart or on each other
            // -- two panels of a curtain meeting -- is no contact).
            if (bary.minCoeff() <= 0.0) { // nearest on the rim
                const double beside2 = off.squaredNorm() - gap * gap;
                if (beside2 >= h * h || beside2 >= gap * gap) continue;
            }
            if (gap < 0.0) {
                const Vec3 moved = (xp[p] - pStart[p]) -
                                   (bary[0] * (x0 - tStart[t[0]]) + bary[1] * (x1 - tStart[t[1]]) +
                                    bary[2] * (x2 - tStart[t[2]]));
                if (-gap > moved.norm() + h) continue; // never on the other side near it
            }
            const double denom =
                wp + bary[0] * bary[0] * w0 + bary[1] * bary[1] * w1 + bary[2] * bary[2] * w2;
            if (!(denom > 0.0)) continue;
            const detail::LayerPoint particle{&xp[p], &vp[p], wp};
            const std::array<detail::LayerPoint, 3> corners = {
                detail::LayerPoint{&xt[t[0]], &vt[t[0]], w0},
                detail::LayerPoint{&xt[t[1]], &vt[t[1]], w1},
                detail::LayerPoint{&xt[t[2]], &vt[t[2]], w2}};
            if (detail::heldFast(particle, corners, bary, denom)) continue;
            ++contacts;
            const double approach =
                detail::separateLayers(particle, corners, bary, nrm, h - gap, denom, s.friction);
            if (wp != 0.0) pMoved = true;
            if (w0 != 0.0 || w1 != 0.0 || w2 != 0.0) tMoved = true;
            if (pAsleep && approach > pWake) pWoken = true;
            if (tAsleep && approach > tWake) tWoken = true;
        }
        return contacts;
    };
    for (int iter = 0; iter < s.iterations; ++iter) {
        const std::size_t contacts =
            pass(ab_, abTris_, 0, a, aStart, aAsleep, wakeA, movedA, stats.wokeA, b, bStart,
                 bAsleep, wakeB, movedB, stats.wokeB) +
            pass(ba_, baTris_, 1, b, bStart, bAsleep, wakeB, movedB, stats.wokeB, a, aStart,
                 aAsleep, wakeA, movedA, stats.wokeA);
        stats.contacts += contacts;
        if (contacts == 0) break;
    }
    // Moved positions need their forces again at the next step's start.
    if (movedA) a.state_.forcesValid = false;
    if (movedB) b.state_.forcesValid = false;
    if (stats.wokeA) a.wake();
    if (stats.wokeB) b.wake();
    return stats;
}

ClothPairStats collideCloths(Cloth& a, const Vec3List& aStart, Cloth& b, const Vec3List& bStart,
                             const ClothPairSettings& settings, double dt) {
    ClothPairCollider collider;
    return collider.collide(a, aStart, b, bStart, settings, dt);
}

} // namespace drape
