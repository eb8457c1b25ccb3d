// fuzz_scene: libFuzzer target, the input is a scene file (see harness.hpp, runSceneInput).
#include "harness.hpp"

#include <cstdio>
#include <cstdlib>
#include <exception>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    static const drape::fuzz::ScenePaths paths{DRAPE_FUZZ_SAMPLES_DIR "/scenes",
                                               DRAPE_FUZZ_SAMPLES_DIR "/meshes"};
    try {
        const drape::fuzz::Outcome outcome = drape::fuzz::runSceneInput(data, size, paths);
        // DRAPE_FUZZ_VERBOSE=1 says what became of each input (when replaying a few).
        static const bool verbose = std::getenv("DRAPE_FUZZ_VERBOSE") != nullptr;
        if (verbose)
            std::fprintf(stderr, "fuzz_scene: %s\n",
                         outcome.accepted ? "accepted" : outcome.message.c_str());
    } catch (const std::exception& e) {
        // Not a drape error: a bug. Abort so that libFuzzer saves the input.
        std::fprintf(stderr, "fuzz_scene: unexpected exception: %s\n", e.what());
        std::abort();
    }
    return 0;
}
