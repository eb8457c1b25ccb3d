// Golden determinism (as Box2D pins its own): the state hash of the paper's Experiment II, the
// shipped scene file stepped through its Bullet world, after a fixed number of steps.
//
// drape promises the same result for the same input, build and machine: any thread count, any
// run, a restored snapshot. This test pins that result across commits, so that a change which
// moves the physics by even one rounding step is seen and made on purpose.
//
// When it may change: a change to the physics or to the order of floating-point operations in a
// step (forces, integrator, limiter, contacts, the scene file, Bullet's version). Then check
// that the change is intended (the physics tests still pass), run this test, and replace
// kGoldenHash with the hash it prints, saying so in the commit message.
//
// Where it holds: the reference toolchain (GCC on x86-64 without -march=native, i.e. SSE2
// arithmetic without fused multiply-adds, the build CI makes); other compilers and -march=native
// may round differently and skip this test (DRAPE_GOLDEN_TOOLCHAIN undefined).
#include "drape/snapshot.hpp"
#include "drape_samples/simulation.hpp"

#include <catch2/catch.hpp>

#include <cstdio>
#include <filesystem>

using namespace drape;
using namespace drape::samples;

#if defined(DRAPE_GOLDEN_TOOLCHAIN)
namespace {
constexpr int kGoldenSteps = 200;
constexpr std::uint64_t kGoldenHash = 0x1e5b9b61a4be87c3ULL;

std::string hex(std::uint64_t h) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "0x%016llxULL", static_cast<unsigned long long>(h));
    return buf;
}
} // namespace
#endif

TEST_CASE("golden: Experiment II's state hash after 200 steps is pinned", "[scenes][golden]") {
#if !defined(DRAPE_GOLDEN_TOOLCHAIN)
    WARN("skipped: not the reference toolchain (GCC, x86-64, no -march=native)");
#else
    const SceneDesc scene = loadScene(std::filesystem::path(DRAPE_SAMPLES_DIR) / "scenes" /
                                      "experiment2_tablecloth.json");
    if (scene.needsBullet() && !rigidBodiesAvailable()) {
        WARN("skipped: no Bullet integration in this build");
        return;
    }
    Simulation sim(scene);
    for (int k = 0; k < kGoldenSteps; ++k)
        sim.step();
    const std::uint64_t hash = stateHash(sim.cloth());
    INFO("state hash after " << kGoldenSteps << " steps: " << hex(hash) << " (pinned: "
                             << hex(kGoldenHash) << "; see the top of this file before updating)");
    CHECK(hash == kGoldenHash);
#endif
}
