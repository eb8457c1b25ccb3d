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
#include <string>
#include <vector>

namespace drape::samples {

/// A mesh read from a file, welded.
struct ImportedMesh {
    TriangleMesh mesh;                                ///< welded vertices, triangles
    std::map<std::string, std::vector<Index>> groups; ///< group name -> welded vertex indices
    std::size_t rawVertexCount = 0;                   ///< vertices before welding
    std::size_t skippedPrimitives = 0;                ///< points and lines ignored
    /// What was read but not used, or not read, each a sentence naming the file (files the
    /// mesh names that were refused, degenerate triangles dropped...). drape-run prints them.
    std::vector<std::string> warnings;
};

/// Whether this build reads and writes mesh files (DRAPE_WITH_ASSIMP).
bool meshIoAvailable();

/// Reads a mesh file. Vertices closer than weldTolerance [m] are merged (negative: 1e-9 of
/// the bounding-box diagonal). Welded vertex order is the order of first use in the file's
/// vertex arrays, so a file written by exportMesh comes back in the same order.
/// Throws SceneError naming the file and the problem (missing, unreadable, no triangles,
/// non-finite coordinates, too many vertices).
ImportedMesh importMesh(const std::filesystem::path& file, double weldTolerance = -1.0);

/// Applies scale, then rotation (x, y, z in degrees), then translation to every vertex.
void transformMesh(TriangleMesh& mesh, const Vec3& scale, const Vec3& rotationDeg,
                   const Vec3& translation);

/// Reads a MeshDesc's file and applies its transform.
ImportedMesh importMesh(const MeshDesc& desc);

/// Writes a mesh; the format follows the extension (.obj, .ply, .gltf, .glb).
/// Vertex i of the mesh is vertex i of the file. Throws SceneError on failure.
void exportMesh(const TriangleMesh& mesh, const std::filesystem::path& file);

} // namespace drape::samples
