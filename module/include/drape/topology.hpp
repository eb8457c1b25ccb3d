// drape/topology.hpp: the immutable part of a cloth (particles at rest, linked springs,
// triangles, adjacency). Built once from a mesh, shared by any number of Cloth instances.
#pragma once

#include "drape/mesh.hpp"

#include <memory>
#include <optional>
#include <vector>

namespace drape {

/// Marks an input vertex that became no particle (no triangle uses it).
inline constexpr Index kNoParticle = static_cast<Index>(-1);

/// A linked spring (the paper's merged structural/shear spring): one unique triangle edge.
struct Spring {
    Index a;           ///< first particle
    Index b;           ///< second particle (a < b)
    double restLength; ///< length in the initial shape [m]
};

/// A run of springs that share the index offset b - a and whose first ends a are (nearly)
/// consecutive: slot j holds the spring from first + j to first + j + offset, or a hole. A
/// mesh generated row by row (a sheet) has most of its springs in a few families; the force
/// and strain kernels then read both ends from contiguous memory instead of through an index
/// list, and the compiler can vectorise them.
struct SpringFamily {
    Index offset;     ///< b - a of every spring in the family (> 0)
    Index first;      ///< first end a of slot 0
    Index count;      ///< slots; slot j has a = first + j
    std::size_t slot; ///< where the family's slots start in the per-slot arrays
};

/// ClothTopology::springSlots() entry of a spring in no family.
inline constexpr std::size_t kNoSlot = static_cast<std::size_t>(-1);

/// Springs copied out in a fixed block order for the passes that read them front to back:
/// range r is springs[starts[r] .. starts[r + 1]), the inner blocks first (springs with both
/// ends in one contiguous range of particles), the springs crossing blocks last; index[j] is
/// the topology's index of springs[j]. Blocks never depend on the thread count, so the sums
/// are the same on one thread or many.
struct PackedSprings {
    std::vector<Spring> springs;
    std::vector<Index> index;
    std::vector<std::size_t> starts;
};

class ClothTopology;

/// A fixed split of the springs for parallel accumulation. Particles are cut into `blocks`
/// contiguous index ranges; inner[b] lists (in index order) the springs with both ends in
/// block b, crossing the springs joining two blocks. Every particle then receives its inner
/// springs first, in index order, then its crossing springs, in index order: the same
/// floating-point sums whether the blocks run on one thread or many.
struct SpringBlocks {
    std::vector<std::vector<Index>> inner;
    std::vector<Index> crossing;
};
SpringBlocks makeSpringBlocks(const ClothTopology& topology, std::size_t blocks);
/// The same split of a subset of the springs (indices into topology.springs(), ascending).
SpringBlocks makeSpringBlocks(const ClothTopology& topology, const std::vector<Index>& subset,
                              std::size_t blocks);

/// 1e-9 times the diagonal of the finite vertices' bounding box [m]: the weld tolerance used
/// when none is given (TopologyOptions::weldTolerance).
double automaticWeldTolerance(const std::vector<Vec3>& vertices);

/// Options for ClothTopology::build.
struct TopologyOptions {
    /// Vertices closer than this are welded into one particle [m] (>= 0). Not given:
    /// automaticWeldTolerance, which welds exact and near-exact duplicates (the seams an
    /// exporter leaves) without touching real geometry.
    std::optional<double> weldTolerance;
    /// A triangle whose area is below this times its longest edge squared is degenerate.
    double minAreaRatio = 1e-10;
};

/// Immutable cloth topology: particles (mesh vertices), springs (unique triangle edges with
/// rest lengths), triangles and particle adjacency in compressed rows.
class ClothTopology {
  public:
    /// Welds duplicate vertices, validates the mesh and extracts the linked springs.
    /// Throws drape::Error on any invalid input.
    static std::shared_ptr<const ClothTopology> build(const TriangleMesh& mesh,
                                                      const TopologyOptions& options = {});

    std::size_t particleCount() const { return restPositions_.size(); }
    std::size_t springCount() const { return springs_.size(); }
    std::size_t triangleCount() const { return triangles_.size(); }

    const std::vector<Vec3>& restPositions() const { return restPositions_; } ///< [m]
    const std::vector<Spring>& springs() const { return springs_; }
    const std::vector<Triangle>& triangles() const { return triangles_; }
    /// For each input vertex of the mesh given to build(), its particle index (kNoParticle
    /// for a vertex no triangle uses; such vertices are dropped).
    const std::vector<Index>& vertexToParticle() const { return vertexToParticle_; }
    /// Rest area of each triangle [m^2].
    const std::vector<double>& triangleRestAreas() const { return triangleAreas_; }
    double totalRestArea() const { return totalArea_; } ///< [m^2]

    /// Neighbours of particle i are adjacentParticles()[k] for k in
    /// [adjacencyOffsets()[i], adjacencyOffsets()[i + 1]), joined by spring adjacentSprings()[k].
    const std::vector<Index>& adjacencyOffsets() const { return adjOffsets_; }
    const std::vector<Index>& adjacentParticles() const { return adjParticles_; }
    const std::vector<Index>& adjacentSprings() const { return adjSprings_; }
    /// Rest length of spring adjacentSprings()[k], stored next to it for the limiter's walk.
    const std::vector<double>& adjacentRestLengths() const { return adjRest_; }
    /// 1 / L0^2 of spring adjacentSprings()[k], next to it (the walk's strain checks).
    const std::vector<double>& adjacentInverseSquaredRestLengths() const { return adjInvRest2_; }
    /// 1 / L0^2 of each spring, for strain checks on squared lengths without a division.
    const std::vector<double>& inverseSquaredRestLengths() const { return invRest2_; }

    /// The spring families (SpringFamily), baked once: every spring is in exactly one family
    /// slot or in looseSprings().
    const std::vector<SpringFamily>& springFamilies() const { return families_; }
    /// Per family slot: its spring, or kNoParticle for a hole.
    const std::vector<Index>& familySlotSprings() const { return slotSpring_; }
    /// Per family slot: the spring's rest length [m] (0 for a hole).
    const std::vector<double>& familySlotRestLengths() const { return slotRest_; }
    /// Per family slot: 1 / L0^2 (0 for a hole).
    const std::vector<double>& familySlotInverseSquaredRestLengths() const { return slotInvRest2_; }
    /// Per spring: its family slot, or kNoSlot for a loose spring.
    const std::vector<std::size_t>& springSlots() const { return springSlot_; }
    /// Springs in no family (irregular meshes), in index order.
    const std::vector<Index>& looseSprings() const { return looseSprings_; }
    /// Edges used by exactly one triangle (the cloth's border).
    std::size_t boundaryEdgeCount() const { return boundaryEdges_; }
    /// Number of particle blocks of the packed spring layouts: one per 16384 particles, at
    /// most 64 (fixed by the particle count alone).
    std::size_t springBlockCount() const;
    /// The loose springs (looseSprings()) packed by block: the force pass's layout for the
    /// springs in no family, baked once.
    const PackedSprings& packedLooseSprings() const { return packedLoose_; }

  private:
    ClothTopology() = default;
    std::vector<Vec3> restPositions_;
    std::vector<Spring> springs_;
    std::vector<Triangle> triangles_;
    std::vector<Index> vertexToParticle_;
    std::vector<double> triangleAreas_;
    double totalArea_ = 0.0;
    std::vector<Index> adjOffsets_;
    std::vector<Index> adjParticles_;
    std::vector<Index> adjSprings_;
    std::vector<double> adjRest_;
    std::vector<double> adjInvRest2_;
    std::vector<double> invRest2_;
    std::size_t boundaryEdges_ = 0;
    std::vector<SpringFamily> families_;
    std::vector<Index> slotSpring_;
    std::vector<double> slotRest_;
    std::vector<double> slotInvRest2_;
    std::vector<Index> looseSprings_;
    std::vector<std::size_t> springSlot_;
    PackedSprings packedLoose_;
    void bakeFamilies();
};

using TopologyPtr = std::shared_ptr<const ClothTopology>;

/// Every spring of `topology` packed by block, each range ordered for the spring-damping sweep
/// (greedy edge colours: springs that share no particle run back to back). A cloth with spring
/// damping builds it once, at construction (ForceModel); the topology itself never changes.
PackedSprings dampingSweepOrder(const ClothTopology& topology);

} // namespace drape
