// drape/io/mesh_io.hpp: cloth and collider meshes in and out through assimp (drape::io).
//
// Import reads any format assimp knows (OBJ, 3DS, PLY, glTF/GLB, STL, FBX, Collada, OFF...),
// keeps the triangles, welds duplicate vertices (the seams exporters leave at UV and normal
// breaks) and records named groups (OBJ groups, 3DS objects, glTF meshes and nodes) as lists
// of welded vertex indices. An OBJ file's groups are the names of its `g` lines, each name of
// a line (`g a b`: groups a and b), and an `o` line's name where no `g` follows it; its
// materials (`usemtl`) are no groups. Export writes a mesh with its vertex order preserved, so a
// cloth's particle i is vertex i of the file. This is the loader drape-run uses.
//
//     #include <drape/io/mesh_io.hpp>                      // target_link_libraries(... drape::io)
//     drape::io::ImportedMesh garment = drape::io::importMesh("shirt.obj");
//     auto topology = drape::ClothTopology::build(garment.mesh);
//     ...
//     drape::io::exportMesh(cloth.mesh(), "shirt_draped.obj");
//
// Hostile files are refused with a drape::Error (ErrorCode::FileError) whose message starts
// with the file's path: missing or unreadable files, files that are not regular files (a FIFO,
// a device), header counts beyond what the file can hold, node trees deeper than
// kMaxNodeDepth, non-finite coordinates, more than kMaxMeshVertices vertices. Every file assimp
// opens on the mesh's behalf (material libraries, glTF buffers) goes through a guarded reader:
// regular files only, at most kMaxMeshFileBytes each and kMaxImportBytes in all. The import
// runs on a thread of its own with a 256 MiB stack (assimp's readers recurse).
#pragma once

#include <drape/mesh.hpp>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace drape::io {

/// Limits importMesh enforces before and while reading.
inline constexpr std::size_t kMaxMeshVertices = 1u << 20;        ///< welded vertices per mesh
inline constexpr std::uint64_t kMaxMeshFileBytes = 512ull << 20; ///< size of any one file
inline constexpr std::uint64_t kMaxImportBytes = 2048ull << 20;  ///< bytes read per import
/// The deepest node tree a mesh file may have: assimp reads node trees recursively (and
/// frees them so), and a chain of tens of thousands of nodes would exhaust the stack.
inline constexpr std::size_t kMaxNodeDepth = 1000;
/// With MeshImportOptions::transform, every transformed vertex lies within +-this [m].
inline constexpr double kMaxMeshCoordinate = 1e6;

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
    /// mesh names that were refused, degenerate triangles dropped...).
    std::vector<std::string> warnings;
};

/// Whether this build of drape::io reads and writes mesh files (drape was configured with
/// DRAPE_WITH_ASSIMP, the default). Without it importMesh and exportMesh throw.
bool available();

/// How importMesh reads a file.
struct MeshImportOptions {
    /// Vertices closer than this are merged [m]; not given: drape::automaticWeldTolerance of
    /// the file's triangles (1e-3 of the median edge: seams apart by rounding are closed).
    std::optional<double> weldTolerance;
    /// Degenerate triangles (two corners at one point, or no area), duplicate triangles and
    /// vertices no triangle uses: refuse the mesh (true) or drop them with a warning (false).
    bool refuseDegenerate = false;
    /// The mesh becomes a cloth: also warn about what a cloth does not expect, separate
    /// pieces (each moves on its own: a garment's panels whose seams do not meet) and a size
    /// beyond 100 m (a file in millimetres or centimetres). A collider's mesh: false.
    bool cloth = true;
    /// The program's length unit, in units per metre (ClothSettings::inUnits; 100: a world in
    /// centimetres), in [1e-6, 1e6]: a file that names its unit (FBX) comes in in it, and the
    /// warnings give lengths in it and look for a cloth over 100 m across in it.
    double unitsPerMetre = 1.0;
    /// Apply scale, then rotation, then translation before welding, and require every vertex
    /// to land within kMaxMeshCoordinate.
    bool transform = false;
    Vec3 scale = Vec3::Ones();
    Vec3 rotationDeg = Vec3::Zero();
    Vec3 translation = Vec3::Zero();
};

/// Reads a mesh file. Its coordinates are read in single precision (assimp's): about 7
/// digits, so a mesh modelled far from its origin loses its shape (rest lengths 2 % off at
/// 10 km, 13 % at 100 km; at 1e7 m most triangles come out degenerate and are dropped). Model
/// it near its origin and place it with `options.translation` (with `options.transform`,
/// applied in double precision).
/// Welded vertex order is the order of first use in the file's vertex
/// arrays, so a file written by exportMesh comes back in the same order. assimp's
/// FindDegenerates and FindInvalidData steps and drape's own test after welding
/// (drape::dropUnusableTriangles) find degenerate and duplicate triangles; they and the
/// vertices left unused (an OBJ's unused vertices included) are dropped with a warning saying
/// how many and where (mesh and face), or refused (options.refuseDegenerate: ErrorCode::
/// DegenerateTriangle). Throws drape::Error (ErrorCode::FileError otherwise) naming the file
/// and the problem.
ImportedMesh importMesh(const std::filesystem::path& file, const MeshImportOptions& options);
/// importMesh with only a weld tolerance given.
ImportedMesh importMesh(const std::filesystem::path& file,
                        std::optional<double> weldTolerance = std::nullopt);

/// Applies scale, then rotation (x, y, z in degrees), then translation to every vertex; a
/// mirroring scale keeps the triangles counter-clockwise.
void transformMesh(TriangleMesh& mesh, const Vec3& scale, const Vec3& rotationDeg,
                   const Vec3& translation);

/// Writes a mesh; the format follows the extension (.obj, .ply, .gltf, .glb). Vertex i of the
/// mesh is vertex i of the file. A failed write (a full disk) is an error, not a short file.
/// Throws drape::Error (ErrorCode::FileError) naming the file.
void exportMesh(const TriangleMesh& mesh, const std::filesystem::path& file);

} // namespace drape::io
