// drape_samples/mesh_io.hpp: the scene format's meshes (MeshDesc) through drape::io.
//
// The reading and writing itself is drape::io (drape/io/mesh_io.hpp, installed with drape);
// this header adds what a scene file asks for: a MeshDesc's file with its weld tolerance,
// transform and degenerate_triangles choice, and a key that tells such meshes apart.
#pragma once

#include "drape_samples/scene.hpp"

#include <drape/io/mesh_io.hpp>

#include <string>

namespace drape::samples {

using io::exportMesh;
using io::ImportedMesh;
using io::importMesh;
using io::MeshImportOptions;
using io::transformMesh;

/// Whether this build reads and writes mesh files (DRAPE_WITH_ASSIMP): drape::io::available().
bool meshIoAvailable();

/// Reads a MeshDesc's file with its weld tolerance, transform (applied before welding) and
/// degenerate_triangles choice; `cloth`: MeshImportOptions::cloth (false for a body's mesh).
/// Throws SceneError naming the file and the problem.
ImportedMesh importMesh(const MeshDesc& desc, bool cloth = true);
/// What tells apart the meshes importMesh(desc) gives: the file and every option, exactly (a
/// key for reading a file that many bodies name once).
std::string meshDescKey(const MeshDesc& desc);

} // namespace drape::samples
