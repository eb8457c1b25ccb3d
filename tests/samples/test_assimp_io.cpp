// GuardedIOSystem, the file access assimp gets from drape (samples/lib/src/assimp_io.hpp):
// regular files only, never blocking, read-only, size and read budgets, fseek semantics.
#include "../../integration/io/src/assimp_io.hpp"

#include "drape/io/mesh_io.hpp"

#include <assimp/Exporter.hpp>
#include <assimp/Importer.hpp>
#include <assimp/scene.h>

#include <catch2/catch.hpp>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <string>
#include <sys/stat.h>

using drape::io::detail::GuardedIOSystem;
namespace fs = std::filesystem;

namespace {

fs::path dir() {
    const fs::path d = fs::path(DRAPE_TEST_OUT_DIR) / "assimp_io";
    fs::create_directories(d);
    return d;
}

struct Closer {
    GuardedIOSystem* io;
    void operator()(Assimp::IOStream* s) const { io->Close(s); }
};
using Stream = std::unique_ptr<Assimp::IOStream, Closer>;

} // namespace

TEST_CASE("GuardedIOSystem reads regular files like fread and fseek", "[io]") {
    const fs::path file = dir() / "ten.bin";
    {
        std::ofstream f(file, std::ios::binary);
        f << "0123456789";
    }
    GuardedIOSystem io(1024, 1024);
    CHECK(io.Exists(file.c_str()));
    CHECK_FALSE(io.Exists((dir() / "missing.bin").c_str()));
    Stream s(io.Open(file.c_str(), "rb"), Closer{&io});
    REQUIRE(s);
    CHECK(s->FileSize() == 10);
    char buf[16] = {};
    CHECK(s->Read(buf, 4, 1) == 1);
    CHECK(std::string(buf, 4) == "0123");
    CHECK(s->Read(buf, 4, 2) == 1); // whole items only: 6 bytes left hold one item of 4
    CHECK(std::string(buf, 4) == "4567");
    CHECK(s->Tell() == 8);
    CHECK(s->Seek(0, aiOrigin_END) == aiReturn_SUCCESS);
    CHECK(s->Tell() == 10);
    CHECK(s->Read(buf, 1, 1) == 0);
    CHECK(s->Seek(static_cast<size_t>(-3), aiOrigin_END) == aiReturn_SUCCESS); // fseek(-3)
    CHECK(s->Tell() == 7);
    CHECK(s->Seek(static_cast<size_t>(-2), aiOrigin_CUR) == aiReturn_SUCCESS);
    CHECK(s->Tell() == 5);
    CHECK(s->Seek(6, aiOrigin_CUR) == aiReturn_FAILURE); // past the end
    CHECK(s->Tell() == 5);
    CHECK(s->Seek(11, aiOrigin_SET) == aiReturn_FAILURE);
    CHECK(s->Write("x", 1, 1) == 0);
    CHECK(io.bytesRead() == 8);
    CHECK(io.refusals().empty());
    CHECK(io.ComparePaths(file.c_str(), (dir() / "." / "ten.bin").c_str()));
}

TEST_CASE("GuardedIOSystem refuses what is not a regular file, too large, or for writing", "[io]") {
    GuardedIOSystem io(8, 12);
    const fs::path fifo = dir() / "pipe";
    fs::remove(fifo);
    REQUIRE(::mkfifo(fifo.c_str(), 0600) == 0);
    CHECK(io.Exists(fifo.c_str()));
    CHECK(io.Open(fifo.c_str(), "rb") == nullptr); // at once: no writer is waited for
    CHECK(io.Open(dir().c_str(), "rb") == nullptr);
    CHECK(io.Open("/dev/null", "rb") == nullptr);
    const fs::path big = dir() / "big.bin";
    {
        std::ofstream f(big, std::ios::binary);
        f << "0123456789";
    }
    CHECK(io.Open(big.c_str(), "rb") == nullptr); // 10 bytes, the limit is 8
    const fs::path small = dir() / "small.bin";
    {
        std::ofstream f(small, std::ios::binary);
        f << "abcdefg";
    }
    CHECK(io.Open(small.c_str(), "wb") == nullptr);
    CHECK(io.Open((dir() / "missing.bin").c_str(), "rb") == nullptr); // missing: not recorded
    REQUIRE(io.refusals().size() == 5);
    CHECK(io.refusals()[0].reason == "not a regular file (a FIFO)");
    CHECK(io.refusals()[1].reason == "not a regular file (a folder)");
    CHECK(io.refusals()[2].reason == "not a regular file (a character device)");
    CHECK(io.refusals()[3].reason == "larger than 8 bytes");
    CHECK(io.refusals()[4].reason == "opened for writing");
    // The read budget (12 bytes) holds across streams.
    char buf[8];
    Stream a(io.Open(small.c_str(), "rb"), Closer{&io});
    Stream b(io.Open(small.c_str(), "rb"), Closer{&io});
    REQUIRE(a);
    REQUIRE(b);
    CHECK(a->Read(buf, 1, 7) == 7);
    CHECK_FALSE(io.budgetExceeded());
    CHECK(b->Read(buf, 1, 7) == 5);
    CHECK(io.budgetExceeded());
    CHECK(b->Read(buf, 1, 1) == 0);
}

TEST_CASE("an FBX file's unit is read: centimetres come in as metres", "[mesh][fbx]") {
    // A 1 x 1 square in an OBJ, written as FBX by assimp's own exporter (which marks its file
    // as centimetres: UnitScaleFactor 1), and the same file marked as metres (100). drape's
    // coordinates are metres: the first comes in 0.01 wide, the second 1 wide. (Before, every
    // FBX came in at its numbers: a review's 1.7 m duck in centimetres was 166 m wide.)
    const fs::path obj = dir() / "square.obj";
    {
        std::ofstream f(obj);
        f << "v 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1\nf 1 2 3\nf 1 3 4\n";
    }
    Assimp::Importer importer;
    const aiScene* scene = importer.ReadFile(obj.string(), 0);
    REQUIRE(scene);
    Assimp::Exporter exporter;
    const fs::path cm = dir() / "square_cm.fbx";
    REQUIRE(exporter.Export(scene, "fbxa", cm.string()) == AI_SUCCESS);
    std::string text;
    {
        std::ifstream f(cm);
        text.assign(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
    }
    const std::string unit = "\"UnitScaleFactor\", \"double\", \"Number\", \"\", 1\n";
    const auto at = text.find(unit);
    REQUIRE(at != std::string::npos); // assimp marks its FBX as centimetres
    text.replace(at, unit.size(), "\"UnitScaleFactor\", \"double\", \"Number\", \"\", 100\n");
    const fs::path m = dir() / "square_m.fbx";
    {
        std::ofstream f(m);
        f << text;
    }
    auto width = [](const drape::io::ImportedMesh& mesh) {
        double lo = 1e300, hi = -1e300;
        for (const drape::Vec3& p : mesh.mesh.vertices) {
            lo = std::min(lo, p.x());
            hi = std::max(hi, p.x());
        }
        return hi - lo;
    };
    const drape::io::ImportedMesh inCm = drape::io::importMesh(cm);
    const drape::io::ImportedMesh inM = drape::io::importMesh(m);
    CHECK(width(inCm) == Approx(0.01).epsilon(1e-6));
    CHECK(width(inM) == Approx(1.0).epsilon(1e-6));
    REQUIRE(inCm.warnings.size() == 1); // says what it did
    CHECK(inCm.warnings[0].find("its unit is 0.01 m (FBX UnitScaleFactor 1)") != std::string::npos);
    CHECK(inM.warnings.empty());
    // A program in centimetres (units_per_metre 100) reads both into centimetres: 1 and 100
    // wide (review 16: the file came in in metres there, 100 times too small).
    drape::io::MeshImportOptions centimetres;
    centimetres.unitsPerMetre = 100.0;
    const drape::io::ImportedMesh cmInCm = drape::io::importMesh(cm, centimetres);
    const drape::io::ImportedMesh mInCm = drape::io::importMesh(m, centimetres);
    CHECK(width(cmInCm) == Approx(1.0).epsilon(1e-6));
    CHECK(width(mInCm) == Approx(100.0).epsilon(1e-6));
    CHECK(cmInCm.warnings.empty()); // its numbers are the program's unit already
    REQUIRE(mInCm.warnings.size() == 1);
    CHECK(mInCm.warnings[0].find("read in the program's unit, 100 per metre") != std::string::npos);
}
