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

namespace detail {
struct SpringLayout; // module/src/spring_layout.hpp: the kernels' private layouts
}

/// 1e-9 times the diagonal of the finite vertices' bounding box [m]: the weld tolerance used
/// when none is given (TopologyOptions::weldTolerance): exact and near-exact duplicates.
double automaticWeldTolerance(const std::vector<Vec3>& vertices);

/// The weld tolerance a mesh file gets when none is given (io::MeshImportOptions::weldTolerance)
/// [m]: the larger of the vertices' (above) and 1e-3 times the median length of the
/// triangles' edges. It welds the copies of a vertex an exporter leaves at a seam also when
/// they are apart by rounding (a garment's panels 10 um apart on a 2.5 cm mesh fell apart at
/// the seams), and vertices a hair apart that no cloth could step (an edge of 1e-3 times the
/// median needs 1000 times the sub-steps). The triangles this collapses are dropped, with a
/// warning, by the importer.
double automaticWeldTolerance(const TriangleMesh& mesh);

/// Options for ClothTopology::build.
struct TopologyOptions {
    /// Vertices closer than this are welded into one particle [m] (>= 0). Not given:
    /// automaticWeldTolerance, which welds exact and near-exact duplicates (the seams an
    /// exporter leaves) without touching real geometry.
    std::optional<double> weldTolerance;
    /// A triangle whose area is below this times its longest edge squared is degenerate
    /// (>= 0 and finite; ClothTopology::build refuses other values).
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
    /// Edges used by exactly one triangle (the cloth's border).
    std::size_t boundaryEdgeCount() const { return boundaryEdges_; }
    /// The springs laid out for the core's kernels (families, packed blocks, rest lengths in
    /// the forms the kernels read), built once by build(); a private type of the core.
    const detail::SpringLayout& springLayout() const { return *layout_; }

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
    std::size_t boundaryEdges_ = 0;
    std::shared_ptr<const detail::SpringLayout> layout_;
};

using TopologyPtr = std::shared_ptr<const ClothTopology>;

} // namespace drape
