// mesh_io.cpp: assimp import (triangles, welding, named groups) and export (order-preserving).
#include "drape_samples/mesh_io.hpp"

#include <drape/error.hpp>

#include <Eigen/Geometry>

#include <cctype>
#include <cmath>
#include <fstream>
#include <limits>

#if DRAPE_SAMPLES_HAVE_ASSIMP
#include <assimp/Exporter.hpp>
#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#endif

namespace drape::samples {

namespace {

[[noreturn]] void meshFail(const std::filesystem::path& file, const std::string& what) {
    throw SceneError(file.string() + ": " + what);
}

} // namespace

void transformMesh(TriangleMesh& mesh, const Vec3& scale, const Vec3& rotationDeg,
                   const Vec3& translation) {
    const double d2r = 3.14159265358979323846 / 180.0;
    const Eigen::Matrix3d r = (Eigen::AngleAxisd(rotationDeg.z() * d2r, Vec3::UnitZ()) *
                               Eigen::AngleAxisd(rotationDeg.y() * d2r, Vec3::UnitY()) *
                               Eigen::AngleAxisd(rotationDeg.x() * d2r, Vec3::UnitX()))
                                  .toRotationMatrix();
    for (Vec3& v : mesh.vertices)
        v = r * v.cwiseProduct(scale) + translation;
    // A mirroring scale flips every triangle; restore counter-clockwise order.
    if (scale.x() * scale.y() * scale.z() < 0.0)
        for (Triangle& t : mesh.triangles)
            std::swap(t[1], t[2]);
}

ImportedMesh importMesh(const MeshDesc& desc) {
    ImportedMesh m = importMesh(desc.file, desc.weldTolerance);
    transformMesh(m.mesh, desc.scale, desc.rotationDeg, desc.translation);
    return m;
}

#if DRAPE_SAMPLES_HAVE_ASSIMP

bool meshIoAvailable() {
    return true;
}

namespace {

std::string lowerExtension(const std::filesystem::path& file) {
    std::string ext = file.extension().string();
    for (char& ch : ext)
        ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    return ext;
}

/// True for a PLY file (it starts with "ply", as assimp's PLY reader demands; whatever follows,
/// a NUL byte included) whose header never ends: assimp 5.2's PLY reader then waits forever
/// at the end of the file for a line that starts with the token "end_header" (leading
/// blanks allowed).
bool isPlyWithoutEndHeader(const std::filesystem::path& file) {
    std::ifstream in(file, std::ios::binary);
    std::string line;
    if (!std::getline(in, line) || line.compare(0, 3, "ply") != 0) return false;
    const std::string token = "end_header";
    while (std::getline(in, line)) {
        const std::size_t start = line.find_first_not_of(" \t");
        if (start == std::string::npos || line.compare(start, token.size(), token) != 0) continue;
        const std::size_t after = start + token.size();
        if (after == line.size() || std::isspace(static_cast<unsigned char>(line[after])))
            return false;
    }
    return true;
}

struct RawMesh {
    TriangleMesh mesh;
    std::map<std::string, std::vector<Index>> rawGroups; // raw vertex indices
    std::size_t skipped = 0;
};

void gather(const aiScene& scene, const aiNode& node, const aiMatrix4x4& parent, RawMesh& out,
            const std::filesystem::path& file) {
    const aiMatrix4x4 world = parent * node.mTransformation;
    for (unsigned k = 0; k < node.mNumMeshes; ++k) {
        if (node.mMeshes[k] >= scene.mNumMeshes) meshFail(file, "node refers to a missing mesh");
        const aiMesh& m = *scene.mMeshes[node.mMeshes[k]];
        const std::size_t base = out.mesh.vertices.size();
        if (base + m.mNumVertices > kMaxSceneParticles * 8)
            meshFail(file, "too many vertices (limit " + std::to_string(kMaxSceneParticles * 8) +
                               " before welding)");
        for (unsigned i = 0; i < m.mNumVertices; ++i) {
            const aiVector3D p = world * m.mVertices[i];
            const Vec3 v(p.x, p.y, p.z);
            if (!v.allFinite())
                meshFail(file, "vertex " + std::to_string(i) + " of mesh \"" + m.mName.C_Str() +
                                   "\" is not finite");
            out.mesh.vertices.push_back(v);
        }
        for (unsigned f = 0; f < m.mNumFaces; ++f) {
            const aiFace& face = m.mFaces[f];
            if (face.mNumIndices != 3) {
                ++out.skipped;
                continue;
            }
            Triangle t{};
            for (unsigned c = 0; c < 3; ++c) {
                if (face.mIndices[c] >= m.mNumVertices)
                    meshFail(file, "face " + std::to_string(f) + " of mesh \"" + m.mName.C_Str() +
                                       "\" has an index out of range");
                t[c] = static_cast<Index>(base + face.mIndices[c]);
            }
            out.mesh.triangles.push_back(t);
        }
        std::vector<Index> all(m.mNumVertices);
        for (unsigned i = 0; i < m.mNumVertices; ++i)
            all[i] = static_cast<Index>(base + i);
        for (const std::string& name :
             {std::string(m.mName.C_Str()), std::string(node.mName.C_Str())}) {
            if (name.empty()) continue;
            auto& g = out.rawGroups[name];
            g.insert(g.end(), all.begin(), all.end());
        }
    }
    for (unsigned c = 0; c < node.mNumChildren; ++c)
        gather(scene, *node.mChildren[c], world, out, file);
}

} // namespace

ImportedMesh importMesh(const std::filesystem::path& file, double weldTolerance) {
    std::error_code ec;
    if (!std::filesystem::exists(file, ec)) meshFail(file, "mesh file not found");
    if (std::filesystem::is_directory(file, ec)) meshFail(file, "is a folder, not a mesh file");
    const auto size = std::filesystem::file_size(file, ec);
    if (ec) meshFail(file, "cannot read: " + ec.message());
    if (size == 0) meshFail(file, "mesh file is empty");
    if (size > 512u * 1024u * 1024u) meshFail(file, "mesh file larger than 512 MiB");

    if (isPlyWithoutEndHeader(file))
        meshFail(file, "PLY header has no end_header line (the file is truncated or not PLY)");

    Assimp::Importer importer;
    // Points and lines stay in their meshes (they are skipped below) so that the order of
    // first use of every vertex is the file's order.
    const aiScene* scene = importer.ReadFile(file.string(), aiProcess_ValidateDataStructure);
    if (!scene || !scene->mRootNode)
        meshFail(file, std::string("assimp cannot read it: ") + importer.GetErrorString());
    // assimp 5.2's triangulation asserts (aborts the process) on a mesh that declares polygons
    // but has none, which some malformed files produce (a PLY polygon whose indices are out of
    // range is dropped after the mesh was marked): check before triangulating.
    for (unsigned i = 0; i < scene->mNumMeshes; ++i) {
        const aiMesh& m = *scene->mMeshes[i];
        if (!(m.mPrimitiveTypes & aiPrimitiveType_POLYGON)) continue;
        bool polygon = false;
        for (unsigned f = 0; f < m.mNumFaces && !polygon; ++f) polygon = m.mFaces[f].mNumIndices > 3;
        if (!polygon)
            meshFail(file, "mesh \"" + std::string(m.mName.C_Str()) +
                               "\" declares polygons but has none (the file is malformed)");
    }
    scene = importer.ApplyPostProcessing(aiProcess_Triangulate);
    if (!scene || !scene->mRootNode)
        meshFail(file, std::string("assimp cannot triangulate it: ") + importer.GetErrorString());
    if (scene->mFlags & AI_SCENE_FLAGS_INCOMPLETE)
        meshFail(file, "assimp reports the file as incomplete");

    RawMesh raw;
    gather(*scene, *scene->mRootNode, aiMatrix4x4(), raw, file);
    if (raw.mesh.triangles.empty())
        meshFail(file,
                 "contains no triangles" +
                     (raw.skipped ? " (only " + std::to_string(raw.skipped) + " points or lines)"
                                  : std::string()));

    double tol = weldTolerance;
    if (tol < 0.0) {
        Vec3 lo = raw.mesh.vertices[0], hi = lo;
        for (const Vec3& v : raw.mesh.vertices) {
            lo = lo.cwiseMin(v);
            hi = hi.cwiseMax(v);
        }
        tol = 1e-9 * (hi - lo).norm();
    }
    WeldResult welded;
    try {
        welded = weldVertices(raw.mesh, tol);
    } catch (const drape::Error& e) {
        meshFail(file, e.what());
    }
    // Drop vertices no triangle uses (point clouds, helper vertices), keeping the order.
    std::vector<Index> used(welded.mesh.vertices.size(), 0);
    for (const Triangle& t : welded.mesh.triangles)
        for (Index i : t)
            used[i] = 1;
    std::vector<Index> compact(used.size(), Index(-1));
    ImportedMesh out;
    for (std::size_t i = 0; i < used.size(); ++i)
        if (used[i]) {
            compact[i] = static_cast<Index>(out.mesh.vertices.size());
            out.mesh.vertices.push_back(welded.mesh.vertices[i]);
        }
    if (out.mesh.vertices.size() > kMaxSceneParticles)
        meshFail(file, std::to_string(out.mesh.vertices.size()) +
                           " vertices after welding exceeds the limit of " +
                           std::to_string(kMaxSceneParticles));
    out.mesh.triangles.reserve(welded.mesh.triangles.size());
    for (const Triangle& t : welded.mesh.triangles)
        out.mesh.triangles.push_back({compact[t[0]], compact[t[1]], compact[t[2]]});
    for (const auto& [name, rawIdx] : raw.rawGroups) {
        std::vector<Index> g;
        std::vector<unsigned char> seen(out.mesh.vertices.size(), 0);
        for (Index r : rawIdx) {
            const Index w = compact[welded.remap[r]];
            if (w == Index(-1) || seen[w]) continue;
            seen[w] = 1;
            g.push_back(w);
        }
        if (!g.empty()) out.groups[name] = std::move(g);
    }
    out.rawVertexCount = raw.mesh.vertices.size();
    out.skippedPrimitives = raw.skipped;
    return out;
}

void exportMesh(const TriangleMesh& mesh, const std::filesystem::path& file) {
    const std::string ext = lowerExtension(file);
    const char* format = nullptr;
    if (ext == ".obj")
        format = "objnomtl";
    else if (ext == ".ply")
        format = "ply";
    else if (ext == ".gltf")
        format = "gltf2";
    else if (ext == ".glb")
        format = "glb2";
    // STL and 3DS are left out: STL has no shared vertices and assimp's 3DS writer splits
    // them, so neither could keep vertex i of the cloth as vertex i of the file.
    else
        meshFail(file,
                 "unknown mesh format \"" + ext + "\" for export (use .obj, .ply, .gltf or .glb)");
    if (mesh.vertices.empty() || mesh.triangles.empty()) meshFail(file, "nothing to export");
    // The file stores single precision: a vertex beyond its range would be written as inf.
    constexpr double kFloatMax = static_cast<double>(std::numeric_limits<float>::max());
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i)
        if (!(mesh.vertices[i].cwiseAbs().maxCoeff() <= kFloatMax))
            meshFail(file, "vertex " + std::to_string(i) + " is not finite or beyond the "
                           "single-precision range of the file; nothing written");

    // Area-weighted vertex normals, so that other tools shade the mesh smoothly.
    std::vector<Vec3> normals(mesh.vertices.size(), Vec3::Zero());
    for (const Triangle& t : mesh.triangles) {
        if (t[0] >= mesh.vertices.size() || t[1] >= mesh.vertices.size() ||
            t[2] >= mesh.vertices.size())
            meshFail(file, "triangle index out of range");
        const Vec3 n = (mesh.vertices[t[1]] - mesh.vertices[t[0]])
                           .cross(mesh.vertices[t[2]] - mesh.vertices[t[0]]);
        for (Index i : t)
            normals[i] += n;
    }

    aiScene scene;
    scene.mRootNode = new aiNode("cloth");
    scene.mNumMaterials = 1;
    scene.mMaterials = new aiMaterial* [1] { new aiMaterial() };
    scene.mNumMeshes = 1;
    scene.mMeshes = new aiMesh* [1] { new aiMesh() };
    scene.mRootNode->mNumMeshes = 1;
    scene.mRootNode->mMeshes = new unsigned[1]{0};
    aiMesh& m = *scene.mMeshes[0];
    m.mName = aiString("cloth");
    m.mMaterialIndex = 0;
    m.mNumVertices = static_cast<unsigned>(mesh.vertices.size());
    m.mVertices = new aiVector3D[m.mNumVertices];
    m.mNormals = new aiVector3D[m.mNumVertices];
    for (unsigned i = 0; i < m.mNumVertices; ++i) {
        const Vec3& v = mesh.vertices[i];
        const Vec3 n = normals[i].norm() > 0.0 ? Vec3(normals[i].normalized()) : Vec3::UnitY();
        m.mVertices[i] = aiVector3D(static_cast<ai_real>(v.x()), static_cast<ai_real>(v.y()),
                                    static_cast<ai_real>(v.z()));
        m.mNormals[i] = aiVector3D(static_cast<ai_real>(n.x()), static_cast<ai_real>(n.y()),
                                   static_cast<ai_real>(n.z()));
    }
    // assimp's OBJ writer numbers vertices in the order faces first use them. One point
    // primitive per vertex, written before the triangles, makes that order the particle
    // order ("p i" lines; importMesh skips points but keeps the order).
    const bool pointPrefix = ext == ".obj";
    const std::size_t pointFaces = pointPrefix ? mesh.vertices.size() : 0;
    m.mNumFaces = static_cast<unsigned>(pointFaces + mesh.triangles.size());
    m.mFaces = new aiFace[m.mNumFaces];
    for (std::size_t i = 0; i < pointFaces; ++i) {
        m.mFaces[i].mNumIndices = 1;
        m.mFaces[i].mIndices = new unsigned[1]{static_cast<unsigned>(i)};
    }
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
        aiFace& f = m.mFaces[pointFaces + t];
        f.mNumIndices = 3;
        f.mIndices =
            new unsigned[3]{mesh.triangles[t][0], mesh.triangles[t][1], mesh.triangles[t][2]};
    }
    m.mPrimitiveTypes = static_cast<unsigned>(aiPrimitiveType_TRIANGLE) |
                        (pointPrefix ? static_cast<unsigned>(aiPrimitiveType_POINT) : 0u);

    Assimp::Exporter exporter;
    if (exporter.Export(&scene, format, file.string()) != AI_SUCCESS)
        meshFail(file, std::string("assimp cannot write it: ") + exporter.GetErrorString());
}

#else // no assimp

bool meshIoAvailable() {
    return false;
}

ImportedMesh importMesh(const std::filesystem::path& file, double) {
    meshFail(file, "this build has no mesh import (configure with -DDRAPE_WITH_ASSIMP=ON)");
}

void exportMesh(const TriangleMesh&, const std::filesystem::path& file) {
    meshFail(file, "this build has no mesh export (configure with -DDRAPE_WITH_ASSIMP=ON)");
}

#endif

} // namespace drape::samples
