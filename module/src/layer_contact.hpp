// layer_contact.hpp (private to the core): one particle kept off one triangle of cloth, the
// response that self-collision (self_collision.cpp) and the collision of two cloths
// (cloth_pair.cpp) share, and the grid hash both broadphases use.
#pragma once

#include "drape/forces.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <initializer_list>
#include <utility>
#include <vector>

namespace drape::detail {

/// The integer coordinate of a uniform grid's cell along one axis (invCell = 1 / cell size).
inline std::int64_t cellCoord(double v, double invCell) {
    return static_cast<std::int64_t>(std::floor(v * invCell));
}

/// A grid cell's hash key: unequal cells may share a key, which only adds candidates the exact
/// test rejects.
inline std::uint64_t cellKey(std::int64_t i, std::int64_t j, std::int64_t k) {
    const auto ui = static_cast<std::uint64_t>(i), uj = static_cast<std::uint64_t>(j),
               uk = static_cast<std::uint64_t>(k);
    return (ui * 73856093ull) ^ (uj * 19349663ull) ^ (uk * 83492791ull);
}

/// The entries of a grid's cells by cell key (`add` them, `build`, then look them up with `at`):
/// each distinct key gets a slot of an open-addressing hash table (linear probing, at least twice
/// as many slots as entries), and the entries of a key are listed contiguously in the order they
/// were added. Built and looked up in time linear in the entries (no sort).
class CellTable {
  public:
    void clear() { cells_.clear(); }
    void add(std::uint64_t key, Index entry) { cells_.emplace_back(key, entry); }
    std::size_t size() const { return cells_.size(); }

    void build() {
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
        mask_ = mask;
    }

    /// The entries of key `key` (an empty range if none), in the order they were added.
    std::pair<const Index*, const Index*> at(std::uint64_t key) const {
        if (slotUsed_.empty()) return {nullptr, nullptr};
        std::size_t slot = static_cast<std::size_t>(mix(key)) & mask_;
        while (slotUsed_[slot]) {
            if (slotKey_[slot] == key)
                return {listed_.data() + slotBegin_[slot], listed_.data() + slotBegin_[slot + 1]};
            slot = (slot + 1) & mask_;
        }
        return {nullptr, nullptr};
    }

  private:
    /// A key's slot hash (the keys themselves are a multiplicative hash of the cell).
    static std::uint64_t mix(std::uint64_t key) {
        key ^= key >> 33;
        key *= 0xff51afd7ed558ccdull;
        return key ^ (key >> 33);
    }
    std::vector<std::pair<std::uint64_t, Index>> cells_; ///< (cell key, entry) as added
    std::vector<std::uint64_t> slotKey_;
    std::vector<unsigned char> slotUsed_;
    std::vector<std::size_t> slotBegin_, fill_; ///< per slot: its first entry in listed_
    std::vector<std::uint32_t> entrySlot_;      ///< per entry of cells_: its key's slot
    std::vector<Index> listed_;                 ///< the entries by slot
    std::size_t mask_ = 0;
};

/// Whether every point of the lists (each `now` against where it was, `built`, of the same
/// size) moved less than `slack` from where the mean move of all of them took it. A pair's
/// distance does not see a common translation, so pair lists built with a reach of the
/// thickness plus twice the slack still hold every pair nearer than the thickness (a falling
/// cloth, or two cloths carried together, keep theirs). A non-finite move fails.
inline bool
movedTogetherWithin(std::initializer_list<std::pair<const Vec3List*, const Vec3List*>> moves,
                    double slack) {
    Vec3 mean = Vec3::Zero();
    std::size_t count = 0;
    for (const auto& [now, built] : moves) {
        for (std::size_t i = 0; i < now->size(); ++i)
            mean += (*now)[i] - (*built)[i];
        count += now->size();
    }
    if (count == 0) return true;
    mean /= static_cast<double>(count);
    const double slack2 = slack * slack;
    for (const auto& [now, built] : moves)
        for (std::size_t i = 0; i < now->size(); ++i)
            if (!(((*now)[i] - (*built)[i] - mean).squaredNorm() < slack2)) return false;
    return true;
}

/// A particle or a triangle's corner: its position, velocity and inverse mass (0: held, or a
/// cloth that does not give way).
struct LayerPoint {
    Vec3* x;
    Vec3* v;
    double w;
};

/// Whether a contact is held fast: the points that can move carry so small a share of the
/// contact point (a free corner next to held ones: its barycentric weight small) that moving
/// the contact point by d would move one of them by more than four times d. Such a contact is
/// left alone (as between held points): the linearised projection threw the free corner of a
/// triangle two of whose corners were held by violation / weight (1e14 m once), and capped at
/// the violation it pushed the corner again in every pass.
inline bool heldFast(const LayerPoint& p, const std::array<LayerPoint, 3>& c, const Vec3& bary,
                     double denom) {
    const double most = std::max({p.w, bary[0] * c[0].w, bary[1] * c[1].w, bary[2] * c[2].w});
    return most > 4.0 * denom;
}

/// Moves particle `p` and the triangle's corners `c` apart along the unit normal `nrm` (toward
/// p's side) by `violation` (thickness - gap > 0), weighted by inverse mass and the closest
/// point's barycentric weights `bary`, `denom` = w_p + sum bary_k^2 w_k > 0: the linearised
/// projection of (x_p - sum bary_k x_k) . nrm >= thickness, which keeps momentum. Then removes
/// their approaching relative normal velocity with the same weights and applies Coulomb
/// friction `friction`. Returns the approaching normal speed removed (0 if they were parting).
inline double separateLayers(const LayerPoint& p, const std::array<LayerPoint, 3>& c,
                             const Vec3& bary, const Vec3& nrm, double violation, double denom,
                             double friction) {
    // The linearised projection moves corner k by bary_k w_k lambda, up to violation / bary_k
    // when the other points are held: a corner with a small share of the contact point next to
    // a held one was thrown 1e14 m (two curtains pinned along their tops, their edges meeting).
    // No point moves, or changes its velocity, by more than the contact asks of the contact
    // point itself; where nothing is held the cap is never reached (same result).
    const double most = std::max({p.w, bary[0] * c[0].w, bary[1] * c[1].w, bary[2] * c[2].w});
    double lambda = violation / denom;
    if (most * lambda > violation) lambda = violation / most;
    *p.x += (p.w * lambda) * nrm;
    for (int k = 0; k < 3; ++k)
        *c[k].x -= (bary[k] * c[k].w * lambda) * nrm;
    const Vec3 vTri = bary[0] * *c[0].v + bary[1] * *c[1].v + bary[2] * *c[2].v;
    const Vec3 rel = *p.v - vTri;
    const double vn = rel.dot(nrm);
    if (!(vn < 0.0)) return 0.0;
    double jn = -vn / denom;
    if (most * jn > -vn) jn = -vn / most;
    Vec3 dv = jn * nrm;
    const Vec3 vt = rel - vn * nrm;
    const double vtLen = vt.norm();
    if (vtLen > 0.0 && friction > 0.0) {
        double jt = std::min(vtLen / denom, friction * jn);
        if (most * jt > vtLen) jt = vtLen / most;
        dv -= (jt / vtLen) * vt;
    }
    *p.v += p.w * dv;
    for (int k = 0; k < 3; ++k)
        *c[k].v -= (bary[k] * c[k].w) * dv;
    return -vn;
}

} // namespace drape::detail
