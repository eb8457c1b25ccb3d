// Mesh I/O through assimp: export then import gives back the same vertices (in the same
// order) and triangles; duplicates are welded; groups are found; broken files are named.
#include "drape_samples/mesh_io.hpp"

#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>

using namespace drape;
using namespace drape::samples;
namespace fs = std::filesystem;

namespace {

fs::path outDir() {
    const fs::path d = fs::path(DRAPE_TEST_OUT_DIR) / "mesh_io";
    fs::create_directories(d);
    return d;
}

/// A sheet bent into a curve (so that no two vertices share a plane position) with irregular
/// coordinates, to catch any reordering or loss of precision.
TriangleMesh testMesh() {
    SheetSpec spec;
    spec.rows = 6;
    spec.cols = 9;
    spec.spacing = 0.137;
    spec.origin = Vec3(-0.3, 1.1, 0.25);
    TriangleMesh m = makeSheet(spec);
    for (Vec3& v : m.vertices)
        v.z() += 0.2 * std::sin(3.0 * v.x()) + 0.01 * v.y() * v.y();
    return m;
}

void writeText(const fs::path& p, const std::string& text) {
    std::ofstream f(p, std::ios::binary);
    f << text;
}

} // namespace

TEST_CASE("export then import returns the same vertices in the same order and the same triangles",
          "[mesh]") {
    if (!meshIoAvailable()) {
        WARN("skipped: built without assimp");
        return;
    }
    const TriangleMesh m = testMesh();
    // Files store single precision; 1e-6 m on coordinates of order 1 m is float rounding.
    const double tol = 1e-6;
    for (const char* ext : {".obj", ".ply", ".gltf", ".glb"}) {
        INFO("format " << ext);
        const fs::path file = outDir() / (std::string("roundtrip") + ext);
        exportMesh(m, file);
        const ImportedMesh back = importMesh(file);
        REQUIRE(back.mesh.vertices.size() == m.vertices.size());
        REQUIRE(back.mesh.triangles.size() == m.triangles.size());
        double worst = 0.0;
        for (std::size_t i = 0; i < m.vertices.size(); ++i)
            worst = std::max(worst, (back.mesh.vertices[i] - m.vertices[i]).norm());
        CHECK(worst < tol);
        // Triangles compared as rotations of each other (a format may start a face elsewhere)
        // but with the same winding.
        std::size_t same = 0;
        for (std::size_t t = 0; t < m.triangles.size(); ++t) {
            const Triangle& a = m.triangles[t];
            const Triangle& b = back.mesh.triangles[t];
            for (int r = 0; r < 3; ++r)
                if (a[0] == b[static_cast<std::size_t>(r)] &&
                    a[1] == b[static_cast<std::size_t>((r + 1) % 3)] &&
                    a[2] == b[static_cast<std::size_t>((r + 2) % 3)]) {
                    ++same;
                    break;
                }
        }
        CHECK(same == m.triangles.size());
    }
}

TEST_CASE("duplicate vertices are welded and order follows first use", "[mesh]") {
    if (!meshIoAvailable()) {
        WARN("skipped: built without assimp");
        return;
    }
    // Two triangles sharing an edge, each with its own copies of the shared corners.
    const fs::path file = outDir() / "duplicates.obj";
    writeText(file, "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 4 5 6\n");
    const ImportedMesh m = importMesh(file);
    CHECK(m.rawVertexCount == 6);
    REQUIRE(m.mesh.vertices.size() == 4);
    REQUIRE(m.mesh.triangles.size() == 2);
    CHECK(m.mesh.vertices[0].isApprox(Vec3(0, 0, 0)));
    CHECK(m.mesh.vertices[3].isApprox(Vec3(1, 1, 0)));
    CHECK(m.mesh.triangles[1][0] == 1); // (1, 0, 0) is the second vertex
    CHECK(m.mesh.triangles[1][2] == 2); // (0, 1, 0) is the third
}

TEST_CASE("named groups of an OBJ file select their vertices", "[mesh]") {
    if (!meshIoAvailable()) {
        WARN("skipped: built without assimp");
        return;
    }
    const ImportedMesh m = importMesh(fs::path(DRAPE_SAMPLES_DIR) / "meshes" / "curtain.obj");
    CHECK(m.mesh.vertices.size() == 26u * 28u);
    CHECK(m.mesh.triangles.size() == 2u * 25u * 27u);
    REQUIRE(m.groups.count("rail"));
    REQUIRE(m.groups.count("panel"));
    const auto& rail = m.groups.at("rail");
    CHECK(rail.size() == 2u * 26u); // the faces of the top row touch the top two rows
    for (Index i : rail)
        CHECK(m.mesh.vertices[i].y() > 2.3);
}

TEST_CASE("the 3DS sample cloth (the paper's format) reads as a flat 29 x 29 sheet", "[mesh]") {
    if (!meshIoAvailable()) {
        WARN("skipped: built without assimp");
        return;
    }
    const ImportedMesh m = importMesh(fs::path(DRAPE_SAMPLES_DIR) / "meshes" / "square_cloth.3ds");
    CHECK(m.rawVertexCount > m.mesh.vertices.size()); // the 3DS reader splits vertices; we weld
    CHECK(m.mesh.vertices.size() == 29u * 29u);
    CHECK(m.mesh.triangles.size() == 2u * 28u * 28u);
    for (const Vec3& v : m.mesh.vertices)
        CHECK(v.y() == Approx(2.0).margin(1e-6));
}

TEST_CASE("a transform scales, rotates and translates, keeping triangles counter-clockwise",
          "[mesh]") {
    TriangleMesh m;
    m.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
    m.triangles = {Triangle{0, 1, 2}};
    transformMesh(m, Vec3(2, 2, 2), Vec3(0, 0, 90), Vec3(0, 0, 1));
    CHECK(m.vertices[1].isApprox(Vec3(0, 2, 1), 1e-12));
    CHECK(m.vertices[2].isApprox(Vec3(-2, 0, 1), 1e-12));
    transformMesh(m, Vec3(-1, 1, 1), Vec3::Zero(), Vec3::Zero()); // a mirror
    CHECK(m.triangles[0] == Triangle{0, 2, 1});
}

TEST_CASE("broken or missing mesh files are named with what is wrong", "[mesh][errors]") {
    if (!meshIoAvailable()) {
        WARN("skipped: built without assimp");
        return;
    }
    using Catch::Matchers::Contains;
    CHECK_THROWS_WITH(importMesh(outDir() / "missing.obj"),
                      Contains("missing.obj: mesh file not found"));
    writeText(outDir() / "empty.obj", "");
    CHECK_THROWS_WITH(importMesh(outDir() / "empty.obj"),
                      Contains("empty.obj: mesh file is empty"));
    CHECK_THROWS_WITH(importMesh(fs::path(DRAPE_TEST_DATA_DIR) / "garbage.obj"),
                      Contains("garbage.obj: "));
    writeText(outDir() / "points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\np 1 2 3\nl 1 2\n");
    CHECK_THROWS_WITH(importMesh(outDir() / "points.obj"),
                      Contains("points.obj: contains no triangles"));
    writeText(outDir() / "nan.obj", "v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    CHECK_THROWS_WITH(importMesh(outDir() / "nan.obj"),
                      Contains("nan.obj: vertex 0 of mesh") && Contains("is not finite"));
    writeText(outDir() / "range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99\n");
    CHECK_THROWS_WITH(importMesh(outDir() / "range.obj"),
                      Contains("range.obj: assimp cannot read it: OBJ: vertex index out of range"));
    writeText(outDir() / "unknown.xyz123", "1 2 3\n");
    CHECK_THROWS_WITH(importMesh(outDir() / "unknown.xyz123"), Contains("assimp cannot read it"));
    CHECK_THROWS_WITH(importMesh(fs::path(DRAPE_SAMPLES_DIR)), Contains("is a folder"));
    CHECK_THROWS_WITH(exportMesh(testMesh(), outDir() / "cloth.docx"),
                      Contains("unknown mesh format \".docx\" for export"));
    CHECK_THROWS_WITH(exportMesh(testMesh(), "/nonexistent-folder/x.obj"),
                      Contains("x.obj: assimp cannot write it"));
}
