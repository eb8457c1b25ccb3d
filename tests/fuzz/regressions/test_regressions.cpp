// Inputs that once crashed or hung drape under the fuzzers, replayed through the fuzzers' own
// entry points (tests/fuzz/harness.cpp). Each must now end in a clean drape error.
//
// scene/<name>: bytes for runSceneInput (a scene file); mesh/<name>: bytes for runMeshInput
// (a format byte, then the mesh file). Add a crashing input found by scripts/fuzz.sh by
// copying it here under a name that says what it is, once the bug is fixed.
#include "harness.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <fstream>
#include <iterator>
#include <vector>

namespace fs = std::filesystem;

namespace {

std::vector<fs::path> inputs(const char* kind) {
    std::vector<fs::path> files;
    const fs::path dir = fs::path(DRAPE_FUZZ_REGRESSIONS_DIR) / kind;
    if (fs::is_directory(dir))
        for (const auto& entry : fs::directory_iterator(dir))
            if (entry.is_regular_file()) files.push_back(entry.path());
    std::sort(files.begin(), files.end());
    return files;
}

std::vector<std::uint8_t> bytes(const fs::path& file) {
    std::ifstream in(file, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

} // namespace

TEST_CASE("saved fuzz_scene inputs end in a drape error", "[fuzz]") {
    const drape::fuzz::ScenePaths paths{fs::path(DRAPE_FUZZ_SAMPLES_DIR) / "scenes",
                                        fs::path(DRAPE_FUZZ_SAMPLES_DIR) / "meshes"};
    for (const fs::path& file : inputs("scene")) {
        INFO(file.filename().string());
        const auto data = bytes(file);
        drape::fuzz::Outcome outcome;
        REQUIRE_NOTHROW(outcome = drape::fuzz::runSceneInput(data.data(), data.size(), paths));
        INFO(outcome.message);
        CHECK_FALSE(outcome.accepted);
        CHECK_FALSE(outcome.message.empty());
    }
}

TEST_CASE("saved fuzz_mesh inputs end in a drape error", "[fuzz]") {
    const fs::path workDir = drape::fuzz::makeWorkDir();
    const auto files = inputs("mesh");
    CHECK_FALSE(files.empty());
    for (const fs::path& file : files) {
        INFO(file.filename().string());
        const auto data = bytes(file);
        drape::fuzz::Outcome outcome;
        REQUIRE_NOTHROW(outcome = drape::fuzz::runMeshInput(data.data(), data.size(), workDir));
        INFO(outcome.message);
        CHECK_FALSE(outcome.accepted);
        CHECK_FALSE(outcome.message.empty());
    }
    std::error_code ec;
    fs::remove_all(workDir, ec);
}
