// fuzz_mesh: libFuzzer target, the input is a format byte and a mesh file (see harness.hpp,
// runMeshInput).
#include "harness.hpp"

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <system_error>

namespace {

std::filesystem::path workDir;

void removeWorkDir() {
    std::error_code ec;
    std::filesystem::remove_all(workDir, ec);
}

} // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
    workDir = drape::fuzz::makeWorkDir();
    std::atexit(removeWorkDir);
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    try {
        const drape::fuzz::Outcome outcome = drape::fuzz::runMeshInput(data, size, workDir);
        // DRAPE_FUZZ_VERBOSE=1 says what became of each input (when replaying a few).
        static const bool verbose = std::getenv("DRAPE_FUZZ_VERBOSE") != nullptr;
        if (verbose)
            std::fprintf(stderr, "fuzz_mesh: %s\n",
                         outcome.accepted ? "accepted" : outcome.message.c_str());
    } catch (const std::exception& e) {
        std::fprintf(stderr, "fuzz_mesh: unexpected exception: %s\n", e.what());
        std::abort();
    }
    return 0;
}
