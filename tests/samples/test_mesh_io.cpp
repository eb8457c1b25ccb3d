// Mesh I/O through assimp: export then import gives back the same vertices (in the same
// order) and triangles; duplicates are welded; groups are found; broken files are named.
#include "drape_samples/mesh_io.hpp"
#include "drape_samples/simulation.hpp"

#include <drape/error.hpp>
#include <drape/topology.hpp>

#include <catch2/catch.hpp>

#include <cstdio>

#include <chrono>
#include <cstring>
#include <fcntl.h>
#include <filesystem>
#include <fstream>
#include <future>
#include <memory>
#include <sys/stat.h>
#include <thread>
#include <unistd.h>

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

TEST_CASE("an OBJ file's groups are its g names, each name of a g line, never its materials",
          "[mesh]") {
    if (!meshIoAvailable()) {
        WARN("skipped: built without assimp");
        return;
    }
    // A skirt whose faces use the materials "cotton" and "waistband", and a real group
    // "waistband" elsewhere: assimp names its meshes after the materials, which used to add
    // the skirt's waistband-material face to the group (6 vertices instead of 3, a pin by
    // name pinning the skirt) and make a group "cotton". "g a b" puts a face in a and b.
    const fs::path file = fs::temp_directory_path() / "drape_test_obj_groups.obj";
    writeText(file, "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\nv 2 1 0\n"
                    "v 0 5 0\nv 1 5 0\nv 1 6 0\nv 5 5 0\nv 6 5 0\nv 6 6 0\n"
                    "g skirt\nusemtl cotton\nf 1 2 3\nusemtl waistband\nf 1 3 4\n"
                    "usemtl cotton\nf 2 5 6\n"
                    "g waistband\nusemtl waistband\nf 7 8 9\n"
                    "g hem trim\nf 10 11 12\n");
    const ImportedMesh m = importMesh(file);
    fs::remove(file);
    CHECK(m.groups.count("cotton") == 0);
    REQUIRE(m.groups.count("waistband"));
    CHECK(m.groups.at("waistband").size() == 3u);
    for (Index i : m.groups.at("waistband"))
        CHECK(m.mesh.vertices[i].y() >= 5.0);
    REQUIRE(m.groups.count("skirt"));
    CHECK(m.groups.at("skirt").size() == 6u);
    CHECK(m.groups.count("hem trim") == 0);
    REQUIRE(m.groups.count("hem"));
    REQUIRE(m.groups.count("trim"));
    CHECK(m.groups.at("hem") == m.groups.at("trim"));
    CHECK(m.groups.at("hem").size() == 3u);
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
    // drape::io's errors are drape::Errors of kind FileError; a scene's MeshDesc turns them
    // into the SceneError drape-run reports.
    ErrorCode code = ErrorCode::InvalidArgument;
    try {
        io::importMesh(outDir() / "missing.obj");
    } catch (const Error& e) {
        code = e.code();
    }
    CHECK(code == ErrorCode::FileError);
    MeshDesc missing;
    missing.file = outDir() / "missing.obj";
    CHECK_THROWS_AS(importMesh(missing), SceneError);
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
    // Formats the reader gets wrong or crashes on (a review): refused by name, before assimp
    // reads them. Triangle strips in a PLY came in as one triangle; a 3MF file aborted the
    // process.
    writeText(outDir() / "strips.ply", "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\n"
                                       "property float y\nproperty float z\nelement tristrips 1\n"
                                       "property list int int vertex_indices\nend_header\n0 0 0\n"
                                       "1 0 0\n0 1 0\n1 1 0\n4 0 1 2 3\n");
    CHECK_THROWS_WITH(importMesh(outDir() / "strips.ply"),
                      Contains("strips.ply: PLY triangle strips (element tristrips)"));
    writeText(outDir() / "printed.3mf", "PK");
    CHECK_THROWS_WITH(importMesh(outDir() / "printed.3mf"),
                      Contains("printed.3mf: 3MF files are not read"));
    writeText(outDir() / "range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99\n");
    CHECK_THROWS_WITH(importMesh(outDir() / "range.obj"),
                      Contains("range.obj: assimp cannot read it: OBJ: vertex index out of range"));
    writeText(outDir() / "unknown.xyz123", "1 2 3\n");
    CHECK_THROWS_WITH(importMesh(outDir() / "unknown.xyz123"), Contains("assimp cannot read it"));
    CHECK_THROWS_WITH(importMesh(fs::path(DRAPE_SAMPLES_DIR)), Contains("is a folder"));
    CHECK_THROWS_WITH(exportMesh(testMesh(), outDir() / "cloth.docx"),
                      Contains("unknown mesh format \".docx\" for export"));
    CHECK_THROWS_WITH(exportMesh(testMesh(), "/nonexistent-folder/x.obj"),
                      Contains("x.obj: cannot open it for writing"));
}

TEST_CASE("deep node trees and Collada arrays shorter than their count are refused, not crashed on",
          "[mesh][hostile]") {
    using Catch::Matchers::Contains;
    // A glTF chain of 30,000 nodes (assimp walks it recursively: the stack ran out).
    const std::string tri =
        R"("meshes": [], "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}])";
    std::string nodes;
    for (int i = 0; i < 30000; ++i)
        nodes += (i ? "," : "") + std::string(R"({"children": [)") + std::to_string(i + 1) + "]}";
    nodes += R"(,{})";
    writeText(outDir() / "chain.gltf", "{" + tri + R"(, "nodes": [)" + nodes + "]}");
    CHECK_THROWS_WITH(importMesh(outDir() / "chain.gltf"),
                      Contains("chain.gltf: glTF nodes nested deeper than 1000 levels"));
    // A cycle of children.
    writeText(outDir() / "cycle.gltf",
              "{" + tri +
                  R"(, "nodes": [{"children": [1]}, {"children": [2]}, {"children": [1]}]})");
    CHECK_THROWS_WITH(importMesh(outDir() / "cycle.gltf"), Contains("is its own ancestor"));

    // Collada: 10,000 nested <node> elements.
    auto collada = [](const std::string& geometry, const std::string& scene) {
        return std::string(
                   R"(<?xml version="1.0"?><COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">)") +
               "<library_geometries>" + geometry + "</library_geometries>" +
               R"(<library_visual_scenes><visual_scene id="s">)" + scene +
               R"(</visual_scene></library_visual_scenes><scene><instance_visual_scene url="#s"/></scene></COLLADA>)";
    };
    std::string deep;
    for (int i = 0; i < 10000; ++i)
        deep += R"(<node id="n)" + std::to_string(i) + R"(">)";
    for (int i = 0; i < 10000; ++i)
        deep += "</node>";
    writeText(outDir() / "deep.dae", collada("", deep));
    CHECK_THROWS_WITH(importMesh(outDir() / "deep.dae"),
                      Contains("deep.dae: Collada nodes nested deeper than 1000 levels"));
    // A float_array declaring fewer values than it holds, none, or a negative count.
    auto geometry = [](const std::string& count) {
        return std::string(
                   R"(<geometry id="g"><mesh><source id="p"><float_array id="pa" count=")") +
               count + R"(">0 0 0 1 0 0 0 1 0</float_array></source></mesh></geometry>)";
    };
    for (const char* count : {"3", "0", "-9"}) {
        INFO("count " << count);
        writeText(outDir() / "short.dae", collada(geometry(count), ""));
        CHECK_THROWS_WITH(importMesh(outDir() / "short.dae"),
                          Contains("short.dae: Collada <float_array> \"pa\""));
    }
    writeText(outDir() / "short.dae", collada(geometry("3"), ""));
    CHECK_THROWS_WITH(importMesh(outDir() / "short.dae"),
                      Contains("declares count=\"3\" but holds 9 values"));
}

TEST_CASE("a mesh export that cannot be written completely (a full disk) is an error",
          "[mesh][errors][io]") {
    using Catch::Matchers::Contains;
    // /dev/full takes the open and refuses every write (ENOSPC), like a full disk.
    if (!fs::exists("/dev/full")) {
        WARN("skipped: no /dev/full");
        return;
    }
    for (const char* name : {"full.obj", "full.ply", "full.glb"}) {
        const fs::path link = outDir() / name;
        fs::remove(link);
        fs::create_symlink("/dev/full", link);
        INFO(name);
        CHECK_THROWS_WITH(exportMesh(testMesh(), link),
                          Contains(std::string(name) + ": writing it failed (disk full?)"));
        fs::remove(link);
    }
}

namespace {

/// Runs importMesh on another thread and waits at most `seconds`. A FIFO that the import
/// blocks on is then opened for writing and closed (which releases a blocked reader), so a
/// failing test ends instead of hanging the suite.
struct BoundedImport {
    bool finished = false;
    std::string error;
    ImportedMesh mesh;
};
BoundedImport importWithin(const fs::path& file, double seconds, const fs::path& fifo) {
    auto result = std::make_shared<BoundedImport>();
    auto done = std::make_shared<std::promise<void>>();
    std::future<void> ready = done->get_future();
    std::thread worker([file, result, done] {
        try {
            result->mesh = importMesh(file);
        } catch (const std::exception& e) {
            result->error = e.what();
        }
        done->set_value();
    });
    const bool inTime =
        ready.wait_for(std::chrono::duration<double>(seconds)) == std::future_status::ready;
    if (!inTime) {
        const int fd = ::open(fifo.c_str(), O_WRONLY | O_NONBLOCK);
        if (fd >= 0) ::close(fd);
    }
    worker.join();
    BoundedImport out = *result;
    out.finished = inTime;
    return out;
}

fs::path makeFifo(const fs::path& path) {
    fs::remove(path);
    REQUIRE(::mkfifo(path.c_str(), 0600) == 0);
    return path;
}

std::string importError(const fs::path& file) {
    try {
        importMesh(file);
    } catch (const Error& e) {
        return e.what();
    }
    FAIL("accepted: " << file);
    return {};
}

void writeBytes(const fs::path& p, const std::string& bytes) {
    std::ofstream f(p, std::ios::binary);
    f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

std::string le32(std::uint32_t v) {
    std::string s(4, '\0');
    for (int i = 0; i < 4; ++i)
        s[static_cast<std::size_t>(i)] = static_cast<char>((v >> (8 * i)) & 0xFFu);
    return s;
}

std::string floats(std::initializer_list<float> values) {
    std::string s;
    for (float f : values) {
        char b[4];
        std::memcpy(b, &f, 4);
        s.append(b, 4);
    }
    return s;
}

} // namespace

TEST_CASE("an OBJ whose material library is a FIFO loads in bounded time, with a warning",
          "[mesh][hostile][io]") {
    if (!meshIoAvailable()) return;
    using Catch::Matchers::Contains;
    const fs::path dir = outDir() / "fifo";
    fs::create_directories(dir);
    const fs::path fifo = makeFifo(dir / "materials.mtl");
    writeText(dir / "fifo_mtl.obj", "mtllib materials.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n"
                                    "usemtl cloth\nf 1 2 3\nf 2 4 3\n");
    const BoundedImport r = importWithin(dir / "fifo_mtl.obj", 30.0, fifo);
    REQUIRE(r.finished); // assimp's own IO system blocks in open() forever here
    INFO(r.error);
    REQUIRE(r.error.empty());
    CHECK(r.mesh.mesh.triangles.size() == 2);
    REQUIRE(r.mesh.warnings.size() == 1);
    CHECK_THAT(r.mesh.warnings[0], Contains("fifo_mtl.obj: did not open") &&
                                       Contains("materials.mtl, which it names: not a regular "
                                                "file (a FIFO); read without it"));

    // The mesh file itself a FIFO: refused at once.
    const fs::path fifoMesh = makeFifo(dir / "mesh_fifo.obj");
    const BoundedImport m = importWithin(fifoMesh, 30.0, fifoMesh);
    REQUIRE(m.finished);
    CHECK_THAT(m.error, Contains("mesh_fifo.obj: cannot read: not a regular file (a FIFO)"));

    // A glTF whose buffer is a FIFO: refused, the FIFO named.
    const fs::path fifoBin = makeFifo(dir / "buffer.bin");
    writeText(dir / "fifo_buffer.gltf",
              R"({"asset": {"version": "2.0"}, "buffers": [{"byteLength": 36, "uri": "buffer.bin"}],
                  "bufferViews": [{"buffer": 0, "byteLength": 36}],
                  "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                                 "min": [0, 0, 0], "max": [1, 1, 0]}],
                  "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
                  "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}], "scene": 0})");
    const BoundedImport g = importWithin(dir / "fifo_buffer.gltf", 30.0, fifoBin);
    REQUIRE(g.finished);
    CHECK_THAT(g.error, Contains("fifo_buffer.gltf: assimp cannot read it: ") &&
                            Contains("buffer.bin: not a regular file (a FIFO)"));
}

TEST_CASE("files a mesh names that are devices or folders are not read", "[mesh][hostile][io]") {
    if (!meshIoAvailable()) return;
    using Catch::Matchers::Contains;
    const fs::path dir = outDir() / "devices";
    fs::create_directories(dir);
    // /dev/zero never ends: a material library read from it would exhaust memory.
    fs::remove(dir / "zero.mtl");
    fs::create_symlink("/dev/zero", dir / "zero.mtl");
    writeText(dir / "zero_mtl.obj", "mtllib zero.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    ImportedMesh m = importMesh(dir / "zero_mtl.obj");
    CHECK(m.mesh.triangles.size() == 1);
    REQUIRE(m.warnings.size() == 1);
    CHECK_THAT(m.warnings[0], Contains("zero.mtl, which it names: not a regular file (a character "
                                       "device)"));
    fs::create_directories(dir / "folder.mtl");
    writeText(dir / "folder_mtl.obj", "mtllib folder.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    m = importMesh(dir / "folder_mtl.obj");
    REQUIRE(m.warnings.size() == 1);
    CHECK_THAT(m.warnings[0],
               Contains("folder.mtl, which it names: not a regular file (a folder)"));
    // A plain mesh has no warnings.
    writeText(dir / "plain.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    CHECK(importMesh(dir / "plain.obj").warnings.empty());
}

TEST_CASE("header counts larger than the file can hold are refused, naming the count",
          "[mesh][hostile][counts]") {
    if (!meshIoAvailable()) return;
    using Catch::Matchers::Contains;
    const fs::path dir = outDir() / "counts";
    fs::create_directories(dir);
    // Binary STL: 80-byte header, a triangle count, 50 bytes per triangle.
    const std::string facet = floats({0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0}) + std::string(2, '\0');
    writeBytes(dir / "huge.stl", std::string(80, ' ') + le32(4000000000u) + facet + facet);
    CHECK_THAT(
        importError(dir / "huge.stl"),
        Contains("huge.stl: binary STL header claims 4000000000 triangles, which need "
                 "200000000084 bytes (84 + 50 per triangle), but the file has only 184 bytes"));
    writeBytes(dir / "three.stl", std::string(80, ' ') + le32(3u) + facet + facet);
    CHECK_THAT(importError(dir / "three.stl"),
               Contains("binary STL header claims 3 triangles, which need 234 bytes"));
    const std::string facet2 = floats({0, 0, 1, 1, 0, 0, 1, 1, 0, 0, 1, 0}) + std::string(2, '\0');
    writeBytes(dir / "two.stl", std::string(80, ' ') + le32(2u) + facet + facet2);
    const ImportedMesh two = importMesh(dir / "two.stl");
    CHECK(two.mesh.triangles.size() == 2);
    CHECK(two.mesh.vertices.size() == 4);

    // ASCII PLY with billions of vertices in a few bytes.
    writeText(dir / "huge_ascii.ply",
              "ply\nformat ascii 1.0\nelement vertex 4000000000\nproperty float x\n"
              "property float y\nproperty float z\nelement face 1\n"
              "property list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    CHECK_THAT(
        importError(dir / "huge_ascii.ply"),
        Contains("huge_ascii.ply: PLY header claims 4000000000 \"vertex\" elements, at least "
                 "6 bytes each, but the file has only 26 bytes after its header"));
    // Binary PLY: the face count is the hostile one.
    writeBytes(dir / "huge_binary.ply",
               "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"
               "property float y\nproperty float z\nelement face 3000000000\n"
               "property list uchar int vertex_indices\nend_header\n" +
                   floats({0, 0, 0, 1, 0, 0, 0, 1, 0}) + std::string(1, '\3') + le32(0) + le32(1) +
                   le32(2));
    CHECK_THAT(importError(dir / "huge_binary.ply"),
               Contains("PLY header claims 3000000000 \"face\" elements, at least 1 byte each"));
    // A count beyond 64 bits is named as written.
    writeText(dir / "digits.ply", "ply\nformat ascii 1.0\nelement vertex 123456789012345678901234\n"
                                  "property float x\nend_header\n0\n");
    CHECK_THAT(importError(dir / "digits.ply"),
               Contains("PLY header claims 123456789012345678901234 \"vertex\" elements"));
    // OFF.
    writeText(dir / "huge.off", "OFF\n3 4000000000 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    CHECK_THAT(
        importError(dir / "huge.off"),
        Contains("huge.off: OFF header claims 3 vertices and 4000000000 faces, which need at "
                 "least 8000000017 bytes, but the file has only 45 bytes"));
    // Collada arrays.
    writeText(
        dir / "huge.dae",
        R"(<?xml version="1.0"?><COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1"><library_geometries><geometry id="g"><mesh>
<source id="p"><float_array id="pa" count="3000000000">0 0 0 1 0 0 0 1 0</float_array></source>
</mesh></geometry></library_geometries></COLLADA>)");
    CHECK_THAT(importError(dir / "huge.dae"),
               Contains("huge.dae: Collada <float_array> claims count=\"3000000000\", more items "
                        "than the file"));
    // Honest headers still load.
    writeText(dir / "fine.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    CHECK(importMesh(dir / "fine.off").mesh.triangles.size() == 1);
    writeText(dir / "fine.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                                "property float y\nproperty float z\nelement face 1\n"
                                "property list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n"
                                "0 1 0\n3 0 1 2\n");
    CHECK(importMesh(dir / "fine.ply").mesh.triangles.size() == 1);
}

namespace {

/// A 3 x 3 grid of vertices (8 triangles, faces 0-7) in an OBJ group "sheet", then `extra`.
std::string gridObj(const std::string& extraVertices, const std::string& extraFaces) {
    std::string s = "o sheet\n";
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c)
            s += "v " + std::to_string(c) + " " + std::to_string(r) + " 0\n";
    s += extraVertices;
    for (int r = 0; r < 2; ++r)
        for (int c = 0; c < 2; ++c) {
            const int a = 1 + r * 3 + c, b = a + 1, d = a + 3, e = d + 1;
            s +=
                "f " + std::to_string(a) + " " + std::to_string(b) + " " + std::to_string(e) + "\n";
            s +=
                "f " + std::to_string(a) + " " + std::to_string(e) + " " + std::to_string(d) + "\n";
        }
    return s + extraFaces;
}

} // namespace

TEST_CASE("degenerate and duplicate triangles are dropped with a warning saying how many and where",
          "[mesh][degenerate]") {
    if (!meshIoAvailable()) return;
    using Catch::Matchers::Contains;
    const fs::path dir = outDir() / "degenerate";
    fs::create_directories(dir);
    // Vertices 10-13: a copy of vertex 1's position (exact: assimp's FindDegenerates finds the
    // triangle using it), a point 1e-13 m from vertex 2 (welded: drape finds that one), a
    // vertex on the line through vertices 1 and 2 (no area), and a vertex no face uses
    // (assimp's OBJ reader never passes that one on: drape counts it from the file).
    const std::string extraV = "v 0 0 0\nv 1.0000000000001 0 0\nv 3 0 0\nv 5 5 5\n";
    // Faces 8-11: collapsed exactly, collapsed by welding, zero area, and face 0 again with
    // the other winding (a duplicate).
    const std::string extraF = "f 1 10 5\nf 2 11 6\nf 1 2 12\nf 1 5 2\n";
    writeText(dir / "few_collapsed.obj", gridObj(extraV, extraF));
    const ImportedMesh m = importMesh(dir / "few_collapsed.obj");
    CHECK(m.mesh.triangles.size() == 8);
    CHECK(m.mesh.vertices.size() == 9);
    CHECK(m.droppedDegenerate == 3);
    CHECK(m.droppedDuplicates == 1);
    CHECK(m.droppedVertices == 2); // (3, 0, 0), whose only triangle was dropped, and (5, 5, 5)
    REQUIRE(m.warnings.size() == 1);
    INFO(m.warnings[0]);
    CHECK_THAT(m.warnings[0],
               Contains("few_collapsed.obj: dropped 3 degenerate triangles (two corners at one "
                        "point, or no area: mesh \"sheet\" faces 8, 9, 10), 1 duplicate triangle "
                        "(the same three corners as an earlier one: mesh \"sheet\" face 11), 2 "
                        "vertices no triangle uses; 8 of 12 triangles kept"));
    // What is left builds a cloth (ClothTopology::build refuses all four).
    CHECK_NOTHROW(ClothTopology::build(m.mesh));

    // The scene option refuses instead, with the same count and places.
    MeshImportOptions refuse;
    refuse.refuseDegenerate = true;
    CHECK_THROWS_WITH(importMesh(dir / "few_collapsed.obj", refuse),
                      Contains("few_collapsed.obj: has 3 degenerate triangles") &&
                          Contains("mesh \"sheet\" faces 8, 9, 10") &&
                          Contains("refused (MeshImportOptions::refuseDegenerate, a scene's "
                                   "mesh \"degenerate_triangles\": \"refuse\""));
    // Its code says what was refused (review 16: it was FileError).
    try {
        importMesh(dir / "few_collapsed.obj", refuse);
    } catch (const Error& e) {
        CHECK(e.code() == ErrorCode::DegenerateTriangle);
    }

    // A clean mesh: no warning, and the refuse option accepts it.
    writeText(dir / "clean.obj", gridObj("", ""));
    CHECK(importMesh(dir / "clean.obj").warnings.empty());
    CHECK(importMesh(dir / "clean.obj", refuse).mesh.triangles.size() == 8);
    // The same mesh with one vertex nothing uses (written before the faces, or after them):
    // refused when asked, as SCENES.md says.
    writeText(dir / "unused.obj", gridObj("v 9 9 9\n", ""));
    CHECK_THROWS_WITH(importMesh(dir / "unused.obj", refuse),
                      Contains("unused.obj: has 1 vertex no triangle uses; refused"));
    CHECK(importMesh(dir / "unused.obj").droppedVertices == 1);

    // Nothing usable left: an error, not an empty cloth.
    writeText(dir / "all_collapsed.obj", "v 0 0 0\nv 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\nf 1 3 4\n");
    CHECK_THROWS_WITH(importMesh(dir / "all_collapsed.obj"),
                      Contains("all_collapsed.obj: contains no usable triangle: all 2 are "
                               "degenerate or duplicates"));
    // A mesh whose vertices all sit at one point (assimp's FindInvalidData deletes it).
    writeText(dir / "one_point.obj", gridObj("", "") + "o blob\nv 7 7 7\nv 7 7 7\nv 7 7 7\n"
                                                       "f 10 11 12\n");
    const ImportedMesh blob = importMesh(dir / "one_point.obj");
    CHECK(blob.mesh.triangles.size() == 8);
    REQUIRE(blob.warnings.size() == 1);
    CHECK_THAT(blob.warnings[0], Contains("1 degenerate triangle") && Contains("mesh \"blob\""));
}

TEST_CASE("an edge far shorter than the mesh's others is named in a warning",
          "[mesh][degenerate]") {
    if (!meshIoAvailable()) return;
    using Catch::Matchers::Contains;
    const fs::path dir = outDir() / "sliver";
    fs::create_directories(dir);
    // The 1 m grid with vertex 10 placed 5 mm from vertex 1 (beyond the automatic weld
    // tolerance, 1e-3 of the median edge) and a sliver face (1, 10, 2): its edges 1-10 (5e-3
    // m) and 10-2 are springs of the cloth, the first far shorter than every other edge
    // (median 1 m).
    writeText(dir / "sliver.obj", gridObj("v 0.003 -0.004 0\n", "f 1 10 2\n"));
    const ImportedMesh m = importMesh(dir / "sliver.obj");
    CHECK(m.mesh.vertices.size() == 10);
    CHECK(m.mesh.triangles.size() == 9);
    REQUIRE(m.warnings.size() == 1);
    INFO(m.warnings[0]);
    CHECK_THAT(m.warnings[0], Contains("sliver.obj: 1 edge shorter than 1 % of the median edge "
                                       "(1 m): vertices 0 and 9, 0.005 m apart") &&
                                  Contains("weld such vertices (a weld tolerance above 0.005 m)"));
    // Welded as the warning says, the sliver is gone and so is the warning.
    MeshImportOptions weld;
    weld.weldTolerance = 0.01;
    const ImportedMesh welded = importMesh(dir / "sliver.obj", weld);
    CHECK(welded.mesh.vertices.size() == 9);
    for (const std::string& w : welded.warnings)
        CHECK_THAT(w, !Contains("shorter than"));
    // 10 um from vertex 1 (1e-5 of the median edge): welded without being asked, the sliver
    // dropped with a warning.
    writeText(dir / "hair.obj", gridObj("v 0.000006 -0.000008 0\n", "f 1 10 2\n"));
    const ImportedMesh hair = importMesh(dir / "hair.obj");
    CHECK(hair.mesh.vertices.size() == 9);
    CHECK(hair.mesh.triangles.size() == 8);
    REQUIRE(hair.warnings.size() == 1);
    CHECK_THAT(hair.warnings[0], Contains("dropped 1 degenerate triangle"));
}

TEST_CASE("edges that no cloth surface has are named in a warning: fins and flipped windings",
          "[mesh][degenerate]") {
    if (!meshIoAvailable()) return;
    using Catch::Matchers::Contains;
    const fs::path dir = outDir() / "surface";
    fs::create_directories(dir);
    // A fin: a third triangle on the grid's diagonal 1-5 (OBJ numbering; the importer numbers
    // vertices in the order the faces first use them: 0 and 2).
    writeText(dir / "fin.obj", gridObj("v 0.5 0.5 1\n", "f 1 5 10\n"));
    const ImportedMesh fin = importMesh(dir / "fin.obj");
    REQUIRE(fin.warnings.size() == 1);
    INFO(fin.warnings[0]);
    CHECK_THAT(fin.warnings[0],
               Contains("fin.obj: 1 edge is shared by more than two triangles (vertices 0 and 2)"));
    // The grid's first triangle wound the other way (1 5 2: vertices 0, 1, 2): its two inner
    // edges join triangles wound against it.
    std::string flippedText = gridObj("", "");
    const std::string first = "f 1 2 5\n";
    REQUIRE(flippedText.find(first) != std::string::npos);
    flippedText.replace(flippedText.find(first), first.size(), "f 1 5 2\n");
    writeText(dir / "flipped.obj", flippedText);
    const ImportedMesh flipped = importMesh(dir / "flipped.obj");
    REQUIRE(flipped.warnings.size() == 1);
    INFO(flipped.warnings[0]);
    CHECK_THAT(flipped.warnings[0],
               Contains("flipped.obj: 2 edges join two triangles wound against each other "
                        "(vertices 0 and 1; vertices 1 and 2)"));
    // The grid as it is: no warning.
    writeText(dir / "grid.obj", gridObj("", ""));
    CHECK(importMesh(dir / "grid.obj").warnings.empty());
    // A triangle soup of a 6 x 6 grid (50 triangles, each with its own copies of its corners)
    // whose copies differ by up to `apart` [m].
    auto soupObj = [](double apart) {
        std::string soup;
        int v = 0;
        for (int r = 0; r < 5; ++r)
            for (int c = 0; c < 5; ++c) {
                const double x0 = 0.1 * c, z0 = 0.1 * r;
                const double corners[2][3][2] = {
                    {{x0, z0}, {x0 + 0.1, z0}, {x0, z0 + 0.1}},
                    {{x0 + 0.1, z0}, {x0 + 0.1, z0 + 0.1}, {x0, z0 + 0.1}}};
                for (const auto& tri : corners) {
                    for (const auto& p : tri) {
                        const double noise = 0.5 * apart * ((v * 7919) % 13 - 6) / 6.0;
                        char line[96];
                        std::snprintf(line, sizeof line, "v %.12f 0 %.12f\n", p[0] + noise,
                                      p[1] - noise);
                        soup += line;
                        ++v;
                    }
                    soup += "f " + std::to_string(v - 2) + " " + std::to_string(v - 1) + " " +
                            std::to_string(v) + "\n";
                }
            }
        return soup;
    };
    // Apart by float rounding (2e-7 m): welded by the automatic tolerance (1e-3 of the
    // median edge), one surface, no warning.
    writeText(dir / "rounded.obj", soupObj(2e-7));
    const ImportedMesh rounded = importMesh(dir / "rounded.obj");
    CHECK(rounded.mesh.vertices.size() == 36);
    CHECK(rounded.warnings.empty());
    // Apart by 1 mm (1 % of the spacing): not welded, loose triangles, named; with a weld
    // tolerance of 2 mm it is one surface, no warning.
    writeText(dir / "soup.obj", soupObj(1e-3));
    const ImportedMesh loose = importMesh(dir / "soup.obj");
    REQUIRE(loose.mesh.vertices.size() > 36); // not welded into the 36 grid points
    REQUIRE(loose.warnings.size() == 2);
    INFO(loose.warnings[0]);
    CHECK_THAT(loose.warnings[0], Contains("edges border a single triangle"));
    CHECK_THAT(loose.warnings[1], Contains("the cloth is 50 separate pieces"));
    const ImportedMesh welded = importMesh(dir / "soup.obj", 2e-3);
    CHECK(welded.mesh.vertices.size() == 36);
    CHECK(welded.warnings.empty());
}

TEST_CASE("a mesh of separate pieces, and one too large for metres, are named in a warning",
          "[mesh]") {
    if (!meshIoAvailable()) return;
    using Catch::Matchers::Contains;
    const fs::path dir = outDir() / "pieces";
    fs::create_directories(dir);
    // Two squares 1 cm apart (two panels whose seam does not meet): two pieces.
    writeText(dir / "panels.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
                                  "v 1.01 0 0\nv 2 0 0\nv 2 1 0\nv 1.01 1 0\n"
                                  "f 1 2 3\nf 1 3 4\nf 5 6 7\nf 5 7 8\n");
    const ImportedMesh panels = importMesh(dir / "panels.obj");
    REQUIRE(panels.warnings.size() == 1);
    CHECK_THAT(panels.warnings[0],
               Contains("panels.obj: the cloth is 2 separate pieces (the largest has 4 of 8 "
                        "vertices)") &&
                   Contains("weld them with a larger weld tolerance"));
    // Welded at the seam, one piece and no warning; a body's mesh may be many pieces.
    CHECK(importMesh(dir / "panels.obj", 0.02).warnings.empty());
    MeshImportOptions body;
    body.cloth = false;
    CHECK(importMesh(dir / "panels.obj", body).warnings.empty());
    // A 1 m square written in millimetres.
    writeText(dir / "millimetres.obj", "v 0 0 0\nv 1000 0 0\nv 1000 1000 0\nv 0 1000 0\n"
                                       "f 1 2 3\nf 1 3 4\n");
    const ImportedMesh mm = importMesh(dir / "millimetres.obj");
    REQUIRE(mm.warnings.size() == 1);
    CHECK_THAT(mm.warnings[0], Contains("millimetres.obj: the mesh is 1414 m across") &&
                                   Contains("\"scale\": 0.001 or 0.01"));
    // In a program in centimetres (units_per_metre 100) the same file is 14 m across: no
    // warning (review 16: it was told to scale a 2 m cloth by 0.01); 100 times larger it is
    // named in the program's unit.
    MeshImportOptions centimetres;
    centimetres.unitsPerMetre = 100.0;
    CHECK(importMesh(dir / "millimetres.obj", centimetres).warnings.empty());
    writeText(dir / "micrometres.obj", "v 0 0 0\nv 100000 0 0\nv 100000 100000 0\nv 0 100000 0\n"
                                       "f 1 2 3\nf 1 3 4\n");
    const ImportedMesh um = importMesh(dir / "micrometres.obj", centimetres);
    REQUIRE(um.warnings.size() == 1);
    CHECK_THAT(um.warnings[0], Contains("the mesh is 1.414e+05 units across, 1414 m at 100 units "
                                        "per metre") &&
                                   Contains("the file's unit in scene units"));
    centimetres.unitsPerMetre = 0.0;
    CHECK_THROWS_WITH(importMesh(dir / "millimetres.obj", centimetres),
                      Contains("MeshImportOptions::unitsPerMetre must be in [1e-6, 1e6], got 0"));
}

TEST_CASE("points and lines in a mesh file are named in a warning: the cloth is its triangles",
          "[mesh]") {
    if (!meshIoAvailable()) return;
    using Catch::Matchers::Contains;
    const fs::path dir = outDir() / "primitives";
    fs::create_directories(dir);
    // The 3 x 3 grid with a polyline (two segments) and a point of its own vertices.
    writeText(dir / "lines.obj", gridObj("", "l 1 2 3\np 5\n"));
    const ImportedMesh m = importMesh(dir / "lines.obj");
    CHECK(m.mesh.triangles.size() == 8);
    CHECK(m.mesh.vertices.size() == 9);
    CHECK(m.skippedPrimitives == 3);
    REQUIRE(m.warnings.size() == 1);
    INFO(m.warnings[0]);
    CHECK_THAT(m.warnings[0], Contains("lines.obj: skipped 3 points or lines"));
}

TEST_CASE("a binary STL with a few collapsed facets loads, as assimp's spider does",
          "[mesh][degenerate]") {
    if (!meshIoAvailable()) return;
    using Catch::Matchers::Contains;
    const fs::path dir = outDir() / "degenerate";
    fs::create_directories(dir);
    auto facet = [](std::initializer_list<float> corners) {
        std::string f = floats({0, 0, 1});
        f += floats(corners);
        return f + std::string(2, '\0');
    };
    std::string body;
    // A strip of 6 good triangles, then 2 facets with a corner repeated.
    for (int i = 0; i < 3; ++i) {
        const auto x = static_cast<float>(i);
        body += facet({x, 0, 0, x + 1, 0, 0, x + 1, 1, 0});
        body += facet({x, 0, 0, x + 1, 1, 0, x, 1, 0});
    }
    body += facet({0, 0, 0, 0, 0, 0, 1, 1, 0});
    body += facet({2, 1, 0, 3, 1, 0, 3, 1, 0});
    writeBytes(dir / "collapsed.stl", std::string(80, ' ') + le32(8) + body);
    const ImportedMesh m = importMesh(dir / "collapsed.stl");
    CHECK(m.mesh.triangles.size() == 6);
    CHECK(m.droppedDegenerate == 2);
    REQUIRE(m.warnings.size() == 1);
    CHECK_THAT(m.warnings[0], Contains("collapsed.stl: dropped 2 degenerate triangles") &&
                                  Contains("faces 6, 7") && Contains("6 of 8 triangles kept"));
}

TEST_CASE("a scene's mesh with degenerate triangles runs, or is refused when asked",
          "[mesh][degenerate][scenes]") {
    if (!meshIoAvailable()) return;
    using Catch::Matchers::Contains;
    const fs::path dir = outDir() / "degenerate";
    fs::create_directories(dir);
    writeText(dir / "scene_mesh.obj", gridObj("v 0 0 0\n", "f 1 10 5\nf 1 2 5\n"));
    const std::string cloth = R"({"cloth": {"mesh": {"file": "scene_mesh.obj", "scale": 0.1)";
    const std::string rest = R"(}, "total_mass": 0.1, "stiffness": 5.0},
                                 "simulation": {"time_step": 0.001, "duration": 0.01}})";
    Simulation sim(parseScene(cloth + rest, "degenerate.json", dir));
    CHECK(sim.cloth().topology().triangleCount() == 8);
    REQUIRE(sim.warnings().size() == 1);
    CHECK_THAT(sim.warnings()[0],
               Contains("dropped 1 degenerate triangle") && Contains("1 duplicate triangle"));
    sim.step();
    CHECK_THROWS_WITH(Simulation(parseScene(cloth + R"(, "degenerate_triangles": "refuse")" + rest,
                                            "degenerate.json", dir)),
                      Contains("scene_mesh.obj: has 1 degenerate triangle"));
}

TEST_CASE("a mesh file that many bodies name is read once, and another transform is another mesh",
          "[mesh][scenes]") {
    if (!meshIoAvailable() || !rigidBodiesAvailable()) return;
    using Catch::Matchers::Contains;
    const fs::path dir = outDir() / "shared";
    fs::create_directories(dir);
    // A mesh with a vertex nothing uses: every import of it warns once.
    writeText(dir / "rock.obj", gridObj("v 9 9 9\n", ""));
    std::string bodies;
    for (int i = 0; i < 5; ++i)
        bodies += std::string(i ? "," : "") + R"({"name": "rock)" + std::to_string(i) +
                  R"(", "position": [)" + std::to_string(i) + R"(, -1, 0], "shape": {"type": "mesh",
                      "mesh": {"file": "rock.obj", "scale": 0.1}}})";
    bodies += R"(, {"name": "big", "shape": {"type": "mesh", "mesh": {"file": "rock.obj",
                   "scale": 0.2}}, "position": [0, -2, 0]})";
    const std::string text =
        R"({"cloth": {"sheet": {"rows": 3, "cols": 3, "spacing": 0.1}, "total_mass": 0.1,
                      "stiffness": 5.0},
            "simulation": {"time_step": 0.001, "duration": 0.01}, "rigid_bodies": [)" +
        bodies + "]}";
    Simulation sim(parseScene(text, "shared.json", dir));
    // Five bodies at scale 0.1 share one import, the one at scale 0.2 has its own: two
    // imports, two warnings (it was one per body).
    std::size_t rockWarnings = 0;
    for (const auto& w : sim.warnings())
        rockWarnings += w.find("rock.obj") != std::string::npos;
    CHECK(rockWarnings == 2);
    sim.step();
}

TEST_CASE("a mesh transform that puts a vertex outside the coordinate range is refused",
          "[mesh][ranges]") {
    if (!meshIoAvailable()) return;
    using Catch::Matchers::Contains;
    const fs::path dir = outDir() / "ranges";
    fs::create_directories(dir);
    writeText(dir / "ten.obj", "v 0 0 0\nv 10 0 0\nv 0 10 0\nf 1 2 3\n");
    MeshDesc d;
    d.file = dir / "ten.obj";
    d.scale = Vec3::Constant(1e6); // in range, and so are the coordinates; the product is not
    CHECK_THROWS_WITH(importMesh(d),
                      Contains("ten.obj: vertex 1 lands at (1e+07, 0, 0) m after mesh.scale, "
                               "rotation_deg and translation, outside the [-1e+06, 1e+06] m "
                               "coordinate range"));
    d.scale = Vec3::Constant(2.0);
    d.translation = Vec3(0.0, 0.0, 5.0);
    const ImportedMesh m = importMesh(d);
    CHECK(m.mesh.vertices[1].isApprox(Vec3(20.0, 0.0, 5.0)));
}

TEST_CASE("a sliver that sets the automatic sub-steps is named with what the rest would take",
          "[mesh][scenes][substeps]") {
    if (!meshIoAvailable()) return;
    using Catch::Matchers::Contains;
    const fs::path dir = outDir() / "stiff_spot";
    fs::create_directories(dir);
    // A 0.5 m sheet of 21 x 21 vertices hanging from its top row, and the same sheet with one
    // sliver triangle off its first corner: an edge 2 % of the spacing, long enough for no
    // weld and no short-edge warning, and its vertex nearly massless (review 14's T-shirt,
    // one 0.76 mm edge, took 91 sub-steps a frame where its cloth needs 56).
    // And a 9 x 9 sheet with one cell split in four round a vertex 0.4 % of the spacing from
    // its corner: a short spring whose triangles are not slivers, so both its ends stand out,
    // and of 81 particles the stiffest 1 % is one of them (review 17: the estimate said 80
    // sub-steps where the mesh without that vertex takes 12).
    for (const auto& [n, edge] : {std::pair<int, double>{21, 0.02}, {9, 0.004}}) {
        const bool fan = n == 9;
        const int r0 = 3, c0 = 3; // the split cell (fan)
        INFO(n << " x " << n << ", a sliver edge of " << edge << " spacings");
        const double spacing = 0.025;
        auto sheet = [&](bool sliver) {
            std::string s;
            char line[96];
            for (int r = 0; r < n; ++r)
                for (int c = 0; c < n; ++c) {
                    std::snprintf(line, sizeof line, "v %.6f %.6f 0\n", c * spacing, -r * spacing);
                    s += line;
                }
            if (sliver && !fan) {
                std::snprintf(line, sizeof line, "v %.7f %.7f 0\n", edge * spacing * 0.6,
                              edge * spacing * 0.8);
                s += line;
            }
            if (sliver && fan) {
                std::snprintf(line, sizeof line, "v %.7f %.7f 0\n", (c0 + edge * 0.6) * spacing,
                              -(r0 + edge * 0.8) * spacing);
                s += line;
            }
            auto face = [&s](int i, int j, int k) {
                s += "f " + std::to_string(i) + " " + std::to_string(j) + " " + std::to_string(k) +
                     "\n";
            };
            const int v = n * n + 1;
            for (int r = 0; r + 1 < n; ++r)
                for (int c = 0; c + 1 < n; ++c) {
                    const int a = 1 + r * n + c, b = a + 1, d = a + n, e = d + 1;
                    if (sliver && fan && r == r0 && c == c0) {
                        face(a, v, b); // the cell in four round v, wound as the others
                        face(b, v, e);
                        face(e, v, d);
                        face(d, v, a);
                        continue;
                    }
                    face(a, e, b);
                    face(a, d, e);
                }
            if (sliver && !fan) face(1, 2, v);
            return s;
        };
        const std::string plainFile = "plain" + std::to_string(n) + ".obj";
        const std::string sliverFile = "sliver" + std::to_string(n) + ".obj";
        writeText(dir / plainFile, sheet(false));
        writeText(dir / sliverFile, sheet(true));
        auto scene = [&](const std::string& file) {
            return parseScene(R"({"cloth": {"mesh": {"file": ")" + file + R"("}},
                                 "pins": [{"box": {"min": [-1, -0.00001, -1],
                                                   "max": [1, 0.00001, 1]}}],
                                 "simulation": {"time_step": 0.0166667, "substeps": "auto",
                                                "duration": 1}})",
                              file + ".json", dir);
        };
        const Simulation plain(scene(plainFile));
        const Simulation sliver(scene(sliverFile));
        INFO("sub-steps: plain " << plain.substeps() << ", sliver " << sliver.substeps());
        // The sliver is what makes the cloth dear, and the even sheet is not named.
        REQUIRE(2 * sliver.substeps() >= 3 * plain.substeps());
        for (const std::string& w : plain.warnings())
            CHECK_THAT(w, !Contains("set its stable time step"));
        std::string named;
        for (const std::string& w : sliver.warnings())
            if (w.find("set its stable time step") != std::string::npos) named = w;
        INFO(named);
        REQUIRE_FALSE(named.empty());
        CHECK_THAT(named, Contains("\"auto\" takes " + std::to_string(sliver.substeps())));
        // It names an end of the short edge: its shortest spring is that edge.
        const std::string springKey = "its shortest spring ";
        const auto sp = named.find(springKey);
        REQUIRE(sp != std::string::npos);
        CHECK(std::stod(named.substr(sp + springKey.size())) ==
              Approx(edge * spacing).epsilon(0.01));
        // Its estimate of what the rest of the cloth would take is near what the cloth without the
        // sliver does take.
        const auto at = named.find("where about ");
        REQUIRE(at != std::string::npos);
        const int estimate = std::stoi(named.substr(at + 12));
        CHECK(estimate >= plain.substeps() * 2 / 3);
        CHECK(estimate <= plain.substeps() * 3 / 2);
    }
}
