// cloth_pair.hpp: collision between two cloths (engine-neutral). drape::bullet runs it for
// the cloths of one world after every Bullet sub-step; a program that steps cloths itself
// calls it after each step of both.
#pragma once

#include "drape/cloth.hpp"

#include <memory>
#include <utility>
#include <vector>

namespace drape {
namespace detail {
class CellTable; // layer_contact.hpp
} // namespace detail

/// What one collideCloths call did.
struct ClothPairStats {
    std::size_t pairTests = 0; ///< particle-triangle pairs given to the exact test
    std::size_t contacts = 0;  ///< pairs found nearer than the thickness, or crossed, and moved
    bool wokeA = false;        ///< cloth a was asleep and the other's approach woke it
    bool wokeB = false;        ///< the same for cloth b
    /// The pair lists were built in this call (false: kept from the last call on the same two
    /// cloths, or no list was needed: the cloths' swept boxes did not meet, or both slept).
    bool listsBuilt = false;
};

/// Keeps every particle of each cloth `thickness` from every triangle of the other, on the side
/// it was on at the start of the step both took (`aStart`, `bStart`: their positions before
/// it), and so catches a particle that crossed a triangle in the step (the particle-triangle
/// test of the paper's collision handling, between two cloths). A contact moves the particle
/// and the triangle's corners apart along the triangle's normal, weighted by inverse mass and
/// barycentric coordinates (the two cloths' momentum is kept), removes their approaching normal
/// velocity and applies Coulomb friction; held particles do not move. A sleeping cloth does not
/// give way (the other cloth rests on it) and is woken when the other approaches it faster than
/// resting under gravity does (|g| dt) by the speed of a fall from its sleep distance d,
/// sqrt(2 |g| d) (0.44 m/s for 1 cm; without gravity d over its sleep time). Particle against
/// triangle only: an edge of one cloth can pass an edge of the other where no particle is near
/// a triangle (two thin strips crossed), so keep the thickness near the mesh spacing. Moves can
/// stretch springs past the strain limiter's bound; the cloths' next steps bring them back.
/// Call it after every step both cloths take, with their positions before it, and take short
/// steps: NOT once after Cloth::step(1/60), whose automatic sub-steps (11-22 at 60 Hz with the
/// defaults) happen inside it; step both with Cloth::step(dt / n), n = the larger
/// Cloth::substepsFor(dt) of the two, and call it after each. Once a frame a towel sinks
/// through a net within half a second; after each of those steps it stays on it. (Two free
/// sheets, one thrown at the other, stay apart at 2 m/s with one step a frame; one that crossed
/// the other at 30 m/s within a frame is put back with the sub-steps; drape::bullet does this
/// for the cloths of a world.) A collider
/// keeps its pair lists for the next call on the same two cloths while they hold.
/// Deterministic (pairs in the order of particles, then triangles). Throws drape::Error
/// (InvalidArgument) for a start of the wrong size, a cloth paired with itself (self-collision
/// is ClothSettings::selfCollision), invalid settings or a call from inside a step.
class ClothPairCollider {
  public:
    ClothPairCollider();
    ~ClothPairCollider();
    /// A copy keeps the pair lists (its grid, scratch only, is its own).
    ClothPairCollider(const ClothPairCollider& other);
    ClothPairCollider& operator=(const ClothPairCollider& other);
    ClothPairCollider(ClothPairCollider&&) noexcept;
    ClothPairCollider& operator=(ClothPairCollider&&) noexcept;

    ClothPairStats collide(Cloth& a, const Vec3List& aStart, Cloth& b, const Vec3List& bStart,
                           const ClothPairSettings& settings, double dt);

  private:
    /// The pair lists reach this many thicknesses and are kept, from one call to the next on
    /// the same two cloths, while no particle of either is farther than half the reach beyond
    /// the thickness from where it was when they were built, moved by the mean move of both
    /// (listsHold).
    static constexpr double kReach = 2.0;
    /// Lists (particle of `from`, triangle of `onto`) whose swept boxes (start and end; the
    /// triangle's grown by `reach`) overlap, into `pairs`.
    void findPairs(const Cloth& from, const Vec3List& fromStart, const Cloth& onto,
                   const Vec3List& ontoStart, double reach,
                   std::vector<std::pair<Index, Index>>& pairs);
    bool listsHold(const Cloth& a, const Vec3List& aStart, const Cloth& b, const Vec3List& bStart,
                   double thickness) const;
    const Cloth* builtA_ = nullptr; ///< the cloths the lists were built for (compared only)
    const Cloth* builtB_ = nullptr;
    Vec3List builtAt_[2];                          ///< their positions then
    double builtReach_ = 0.0;                      ///< the reach they were built with [m]
    std::unique_ptr<detail::CellTable> cells_;     ///< the triangles by grid cell (findPairs)
    std::vector<Index> near_;                      ///< one particle's candidate triangles
    std::vector<std::pair<Index, Index>> ab_, ba_; ///< pairs of a onto b, of b onto a
    std::vector<Index> abTris_, baTris_;           ///< the triangles of b in ab_, of a in ba_
    /// Per triangle of b (index 0) and of a (1), those listed: its normal at the start (not
    /// unit) and its unit normal in the pass.
    std::vector<Vec3> startFace_[2], unitFace_[2];
};

/// One call of a ClothPairCollider (its scratch memory not kept).
ClothPairStats collideCloths(Cloth& a, const Vec3List& aStart, Cloth& b, const Vec3List& bStart,
                             const ClothPairSettings& settings, double dt);

/// Throws drape::Error (InvalidArgument) naming the first invalid value of `settings`
/// (`who` prefixes the names).
void validateClothPair(const ClothPairSettings& settings, const std::string& who);

} // namespace drape
