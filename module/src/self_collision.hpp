// self_collision.hpp (private to the core): particle-triangle collision of a cloth with itself
// (the paper's particle against "triangular patch of fabrics" test), with a spatial hash as
// broadphase; the step's "self_collision" stage (ClothSettings::selfCollision) runs it.
#pragma once

#include "drape/forces.hpp"
#include "drape/topology.hpp"
#include "layer_contact.hpp"

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
    CellTable cells_;                    ///< the particles by grid cell
    std::vector<std::size_t> pairStart_; ///< per particle: its first entry in pairTriangle_
    std::vector<std::size_t> fill_;      ///< scratch: the next free entry of each particle
    std::vector<Index> pairTriangle_;    ///< each particle's listed triangles, ascending
    std::vector<double> pairThickness_;  ///< what each listed pair keeps (<= the thickness)
    std::vector<double> shortestEdge_;   ///< per particle: its shortest rest spring [m]
    double largestKeep_ = 0.0;           ///< what any pair keeps at most [m]
    Vec3List built_;                     ///< positions the list was built at
    std::vector<std::array<std::int64_t, 3>> particleCell_; ///< each particle's grid cell
    struct Found {
        Index particle, triangle;
        double thickness; ///< what the pair keeps
    };
    std::vector<Found> found_; ///< the pairs by triangle
    double builtThickness_ = 0.0, builtReach_ = 0.0;
    bool valid_ = false;
};

} // namespace drape::detail
