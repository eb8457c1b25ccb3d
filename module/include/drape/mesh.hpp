// drape/mesh.hpp: indexed triangle meshes, vertex welding, validation and the rectangular
// sheet generator. A cloth is built from any TriangleMesh (see topology.hpp).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry> // cross products

#include <array>
#include <cstdint>
#include <vector>

namespace drape {

using Vec3 = Eigen::Vector3d;
using Index = std::uint32_t;
using Triangle = std::array<Index, 3>;

/// Limits that keep a hostile mesh from exhausting memory.
inline constexpr std::size_t kMaxParticles = 16u * 1024u * 1024u; ///< vertices per cloth
inline constexpr std::size_t kMaxTriangles = 32u * 1024u * 1024u; ///< triangles per cloth

/// An indexed triangle mesh: positions in metres (or scene units), counter-clockwise triangles.
struct TriangleMesh {
    std::vector<Vec3> vertices;      ///< vertex positions [m]
    std::vector<Triangle> triangles; ///< vertex indices of each triangle
};

/// Result of welding: the welded mesh and, for every input vertex, its index in the output.
struct WeldResult {
    TriangleMesh mesh;
    std::vector<Index> remap; ///< remap[old vertex] = new vertex
};

/// Merges vertices closer than `tolerance` [m] (exact duplicates when tolerance is 0).
/// Output vertex order follows the first occurrence of each welded vertex, so a mesh without
/// duplicates keeps its vertex order. Throws on out-of-range indices or non-finite vertices.
WeldResult weldVertices(const TriangleMesh& mesh, double tolerance);

/// Checks that a mesh can be a cloth: at least one triangle, finite vertices, indices in range,
/// no repeated vertex in a triangle and no triangle whose area is below
/// `minAreaRatio` (>= 0 and finite, else drape::Error InvalidArgument) times the square of its
/// longest edge. Throws drape::Error naming the triangle.
void validateMesh(const TriangleMesh& mesh, double minAreaRatio = 1e-10);

/// Triangles a mesh cannot use as cloth, as removed by dropUnusableTriangles.
struct UnusableTriangles {
    /// A repeated vertex, or an area below minAreaRatio times the longest edge squared
    /// (validateMesh's criterion). Indices into the mesh as it was, increasing.
    std::vector<std::size_t> degenerate;
    /// The same three vertices as an earlier triangle (in any order, so either winding):
    /// two copies would double the springs' stiffness (ClothTopology::build refuses them).
    /// Indices into the mesh as it was, increasing; the first copy is kept.
    std::vector<std::size_t> duplicate;
    bool empty() const { return degenerate.empty() && duplicate.empty(); }
};

/// Removes degenerate and duplicate triangles (see UnusableTriangles), keeping the order of
/// the others; vertices are left as they are (some may then be used by no triangle).
/// Throws like validateMesh on out-of-range indices or non-finite vertices. What remains
/// passes validateMesh with the same minAreaRatio, and ClothTopology::build's duplicate check.
UnusableTriangles dropUnusableTriangles(TriangleMesh& mesh, double minAreaRatio = 1e-10);

/// Area of triangle t [m^2].
double triangleArea(const TriangleMesh& mesh, std::size_t t);

/// A rectangular sheet of rows x cols particles with spacing s in the plane spanned by two
/// unit axes. Particle (r, c) sits at origin + c s uAxis + r s vAxis and has index r cols + c.
struct SheetSpec {
    Index rows = 2;              ///< particles along vAxis (>= 2)
    Index cols = 2;              ///< particles along uAxis (>= 2)
    double spacing = 1.0;        ///< distance between neighbouring particles [m]
    Vec3 origin = Vec3::Zero();  ///< position of particle (0, 0) [m]
    Vec3 uAxis = Vec3::UnitX();  ///< direction of increasing column (normalised internally)
    Vec3 vAxis = -Vec3::UnitY(); ///< direction of increasing row (normalised internally)
};

/// Generates the sheet. Each grid cell is split along alternating diagonals (a checkerboard
/// of "/" and "\" cells) so that neither diagonal direction is favoured and the sheet has no
/// built-in shear bias. Throws on rows or cols < 2, non-positive spacing, parallel axes.
TriangleMesh makeSheet(const SheetSpec& spec);

/// Index of particle (row, col) in a sheet made by makeSheet.
inline Index sheetIndex(const SheetSpec& spec, Index row, Index col) {
    return row * spec.cols + col;
}

} // namespace drape
