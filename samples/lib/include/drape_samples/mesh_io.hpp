// drape_samples/mesh_io.hpp: cloth and collider meshes in and out through assimp.
//
// Import reads any format assimp knows (OBJ, 3DS, PLY, glTF/GLB, STL, FBX, ...), keeps the
// triangles, welds duplicate vertices (the seams exporters leave at UV and normal breaks)
// and records named groups (OBJ groups, 3DS objects, glTF meshes and nodes) as lists of
// welded vertex indices. Export writes a mesh with its vertex order preserved.
#pragma once

#include "drape_samples/scene.hpp"

#include <drape/mesh.hpp>

#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace drape::samples {

/// A mesh read from a file, welded.
struct ImportedMesh {
    TriangleMesh mesh;                                ///< welded vertices, triangles
    std::map<std::string, std::vector<Index>> groups; ///< group name -> welded vertex indices
    std::size_t rawVertexCount = 0;                   ///< vertices before welding
    std::size_t skippedPrimitives = 0;                ///< points and lines ignored
    std::size_t droppedDegenerate = 0; ///< triangles with two corners at one point or no area
    std::size_t droppedDuplicates = 0; ///< triangles repeating an earlier one's corners
    std::size_t droppedVertices = 0;   ///< welded vertices no kept triangle uses
    /// What was read but not used, or not read, each a sentence naming the file (files the
    /// mesh names that were refused, degenerate triangles dropped...). drape-run prints them.
    std::vector<std::string> warnings;
};

/// Whether this build reads and writes mesh files (DRAPE_WITH_ASSIMP).
bool meshIoAvailable();

/// How importMesh reads a file.
struct MeshImportOptions {
    /// Vertices closer than this are merged [m]; not given: drape::automaticWeldTolerance.
    std::optional<double> weldTolerance;
    /// Degenerate triangles (two corners at one point, or no area), duplicate triangles and
    /// vertices no triangle uses: refuse the mesh (true) or drop them with a warning (false).
    bool refuseDegenerate = false;
    /// Apply scale, then rotation, then translation before welding, and require every vertex
    /// to land within the scene's coordinate range (kMaxCoordinate).
    bool transform = false;
    Vec3 scale = Vec3::Ones();
    Vec3 rotationDeg = Vec3::Zero();
    Vec3 translation = Vec3::Zero();
};

/// Reads a mesh file. Welded vertex order is the order of first use in the file's vertex
/// arrays, so a file written by exportMesh comes back in the same order. assimp's
/// FindDegenerates and FindInvalidData steps and drape's own test after welding
/// (drape::dropUnusableTriangles) find degenerate and duplicate triangles; they and the
/// vertices left unused are dropped with a warning saying how many and where (mesh and face),
/// or refused (options.refuseDegenerate). Files the mesh names (material libraries, buffers)
/// are opened through a guarded IO system (regular files only, size limits); header counts
/// beyond what the file can hold are refused naming the count.
/// Throws SceneError naming the file and the problem (missing, unreadable, no usable triangle,
/// non-finite coordinates, too many vertices...).
ImportedMesh importMesh(const std::filesystem::path& file, const MeshImportOptions& options);
/// importMesh with only a weld tolerance given.
ImportedMesh importMesh(const std::filesystem::path& file,
                        std::optional<double> weldTolerance = std::nullopt);

/// Applies scale, then rotation (x, y, z in degrees), then translation to every vertex.
void transformMesh(TriangleMesh& mesh, const Vec3& scale, const Vec3& rotationDeg,
                   const Vec3& translation);

/// Reads a MeshDesc's file with its weld tolerance, transform (applied before welding) and
/// degenerate_triangles choice.
ImportedMesh importMesh(const MeshDesc& desc);
/// What tells apart the meshes importMesh(desc) gives: the file and every option, exactly (a
/// key for reading a file that many bodies name once).
std::string meshDescKey(const MeshDesc& desc);

/// Writes a mesh; the format follows the extension (.obj, .ply, .gltf, .glb).
/// Vertex i of the mesh is vertex i of the file. Throws SceneError on failure.
void exportMesh(const TriangleMesh& mesh, const std::filesystem::path& file);

} // namespace drape::samples
