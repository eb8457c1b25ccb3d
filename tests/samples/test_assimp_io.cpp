// GuardedIOSystem, the file access assimp gets from drape (samples/lib/src/assimp_io.hpp):
// regular files only, never blocking, read-only, size and read budgets, fseek semantics.
#include "../../integration/io/src/assimp_io.hpp"

#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
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
