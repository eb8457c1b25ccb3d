// self_collision.hpp (private to the core): particle-triangle collision of a cloth with itself
// (the paper's particle against "triangular patch of fabrics" test), with a spatial hash as
// broadphase; the step's "self_collision" stage (ClothSettings::selfCollision) runs it.
#pragma once

#include "drape/forces.hpp"
#include "drape/topology.hpp"

#include <array>
#include <cstdint>
#include <utility>
#include <vector>

namespace drape::detail {

struct SelfCollisionCounts {
    std::size_t pairTests = 0; ///< particle-triangle pairs given to the exact test
    std::size_t contacts = 0;  ///< pairs closer than the thickness that were corrected
};

/// Keeps every free particle at least `thickness` [m] from every triangle of the same cloth
/// that it is not a corner of, on the side it was on at the previous step (`xPrev`).
/// A contact moves the particle and the triangle's corners apart along the triangle normal,
/// weighted by inverse mass and barycentric coordinates (momentum is conserved), removes
/// their approaching normal velocity, and applies Coulomb friction `friction` [-].
class SelfCollider {
  public:
    SelfCollisionCounts run(const ClothTopology& topology, const std::vector<double>& invMass,
                            const Vec3List& xPrev, Vec3List& x, Vec3List& v, double thickness,
                            double friction, int iterations);

    /// Forgets the pair list: the next pass builds it afresh (Cloth does so at the start of
    /// each step, so a step's result depends on its starting state only).
    void invalidate() { valid_ = false; }

  private:
    /// The pair list reaches this many thicknesses: passes reuse it until a particle has
    /// moved half a thickness since it was built.
    static constexpr double kReach = 2.0;
    /// Lists each particle's triangles within `reach` (see self_collision.cpp).
    void buildPairs(const ClothTopology& topology, const Vec3List& x, double thickness,
                    double reach);
    /// Whether the pair list still holds every pair nearer than `thickness` at x.
    bool pairsHold(const Vec3List& x, double thickness) const;
    /// Lists the entries (particles) of each key of cells_ by key (see self_collision.cpp).
    void buildTable();
    /// The range of listed_ holding the entries of cell key `key` (empty if none).
    std::pair<std::size_t, std::size_t> entriesAt(std::uint64_t key) const;
    /// A key's slot hash (the keys themselves are a multiplicative hash of the cell).
    static std::uint64_t mix(std::uint64_t key) {
        key ^= key >> 33;
        key *= 0xff51afd7ed558ccdull;
        return key ^ (key >> 33);
    }
    std::vector<std::pair<std::uint64_t, Index>> cells_; ///< (cell key, particle), by particle
    std::vector<std::uint64_t> slotKey_;
    std::vector<unsigned char> slotUsed_;
    std::vector<std::size_t> slotBegin_, fill_; ///< per slot: its first entry in listed_
    std::vector<std::uint32_t> entrySlot_;      ///< per entry of cells_: its key's slot
    std::vector<Index> listed_;                 ///< particles by slot
    std::size_t tableMask_ = 0;
    std::vector<std::size_t> pairStart_; ///< per particle: its first entry in pairTriangle_
    std::vector<Index> pairTriangle_;    ///< each particle's listed triangles, ascending
    Vec3List built_;                     ///< positions the list was built at
    std::vector<std::array<std::int64_t, 3>> particleCell_; ///< each particle's grid cell
    std::vector<std::pair<Index, Index>> found_;            ///< (particle, triangle) by triangle
    double builtThickness_ = 0.0, builtReach_ = 0.0;
    bool valid_ = false;
};

} // namespace drape::detail
