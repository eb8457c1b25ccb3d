// drape-bench-cloths: several cloths in one Bullet world, stepped on 1 and on more threads
// (BulletClothSettings::threads): wall time per world step, the speed-up, and whether every
// cloth ends bit-identical.
//
//   drape-bench-cloths                        8 cloths, 1 against 2 threads, 11 repetitions
//   drape-bench-cloths --cloths 4 --threads 4 --steps 300 --repetitions 7
//   drape-bench-cloths --cloths 1 --size 316 --cloth-threads 2 --steps 20
//                                 one 1e5-particle cloth whose own loops take the threads
//
// Each cloth is the paper's Experiment I (samples/scenes/experiment1_suspended_sheet.json: a
// 35 x 35 sheet, 10 m spacing, 0.5 kg particles, 20 N/m springs, C_d = 0.05, stress-ordered
// limiting at 10 %, hanging from its two top corners; --size makes it larger with the same
// spacing), the cloths 500 m apart (more for larger ones) so that none
// touches another; the world steps at its dt, 0.01 s. One repetition = a fresh world, 20
// untimed steps, then `steps` timed ones; repetitions alternate between the thread counts, and
// the figure is the median of the repetitions' mean step. Sleep is off (a hanging sheet would
// fall asleep and cost nothing). With --cloth-threads T, each cloth's ClothSettings::threads is
// T in the run on more threads (its loops then run in the world's arena, nested in the
// per-cloth tasks), 1 in the run on one thread.
#include <drape/bullet/bullet_cloth.hpp>
#include <drape/bullet/convert.hpp>
#include <drape/cloth.hpp>
#include <drape/mesh.hpp>
#include <drape/topology.hpp>

#include <btBulletDynamicsCommon.h>

#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <memory>
#include <vector>

namespace {

using namespace drape;
using Clock = std::chrono::steady_clock;

struct Run {
    double secondsPerStep = 0.0;
    std::uint64_t hash = 0; ///< of every cloth's positions and velocities at the end
};

std::uint64_t fnv(std::uint64_t h, const void* data, std::size_t bytes) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (std::size_t k = 0; k < bytes; ++k) {
        h ^= p[k];
        h *= 1099511628211ULL;
    }
    return h;
}

Run run(int cloths, int size, int threads, int clothThreads, int steps) {
    btDefaultCollisionConfiguration config;
    btCollisionDispatcher dispatcher(&config);
    btDbvtBroadphase broadphase;
    btSequentialImpulseConstraintSolver solver;
    btDiscreteDynamicsWorld world(&dispatcher, &broadphase, &solver, &config);
    world.setGravity(btVector3(0, -9.8f, 0));
    ClothSettings s;
    s.particleMass = 0.5;
    s.springStiffness = 20.0;
    s.damping = 0.05;
    s.relativeDamping = 0.0;
    s.limiter.kind = LimiterKind::StressOrdered;
    s.limiter.maxStrain = 0.10;
    s.threads = clothThreads;
    bullet::BulletClothSettings bs;
    bs.threads = threads;
    bs.timeStep = 0.01;
    bs.sleep = false;
    std::vector<std::shared_ptr<Cloth>> all;
    std::vector<std::unique_ptr<bullet::BulletCloth>> handles;
    for (int k = 0; k < cloths; ++k) {
        SheetSpec spec;
        spec.rows = size;
        spec.cols = size;
        spec.spacing = 10.0;
        const double width = 10.0 * (size - 1);
        spec.origin = Vec3(-0.5 * width + (width + 160.0) * k, 0.0, 0.0);
        spec.uAxis = Vec3::UnitX();
        spec.vAxis = -Vec3::UnitY();
        auto cloth = std::make_shared<Cloth>(ClothTopology::build(makeSheet(spec)), s);
        cloth->pin(0);
        cloth->pin(Index(size - 1));
        handles.push_back(bullet::addCloth(&world, cloth, bs));
        all.push_back(cloth);
    }
    for (int k = 0; k < 20; ++k)
        world.stepSimulation(0.01f, 1, 0.01f);
    const auto start = Clock::now();
    for (int k = 0; k < steps; ++k)
        world.stepSimulation(0.01f, 1, 0.01f);
    Run r;
    r.secondsPerStep = std::chrono::duration<double>(Clock::now() - start).count() / steps;
    r.hash = 1469598103934665603ULL;
    for (const auto& c : all) {
        r.hash = fnv(r.hash, c->positions().data(), c->particleCount() * sizeof(Vec3));
        r.hash = fnv(r.hash, c->velocities().data(), c->particleCount() * sizeof(Vec3));
    }
    handles.clear();
    return r;
}

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    const std::size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

} // namespace

int main(int argc, char** argv) {
    CLI::App app{"drape-bench-cloths: several Experiment I cloths in one Bullet world, stepped "
                 "on 1 thread and on more"};
    int cloths = 8, threads = 2, steps = 300, repetitions = 11, size = 35, clothThreads = 1;
    app.add_option("--cloths", cloths, "cloths in the world")->check(CLI::Range(1, 256));
    app.add_option("--threads", threads, "threads to compare with 1")->check(CLI::Range(1, 256));
    app.add_option("--steps", steps, "timed world steps per repetition")
        ->check(CLI::Range(1, 100000));
    app.add_option("--repetitions", repetitions, "repetitions per thread count")
        ->check(CLI::Range(1, 1000));
    app.add_option("--size", size, "particles per side of each cloth (35: Experiment I)")
        ->check(CLI::Range(2, 2000));
    app.add_option("--cloth-threads", clothThreads,
                   "each cloth's ClothSettings::threads in the run on more threads")
        ->check(CLI::Range(1, 256));
    CLI11_PARSE(app, argc, argv);

    std::vector<double> one, many;
    std::uint64_t hashOne = 0, hashMany = 0;
    bool identical = true;
    for (int r = 0; r < repetitions; ++r) {
        const Run a = run(cloths, size, 1, 1, steps);
        const Run b = run(cloths, size, threads, clothThreads, steps);
        one.push_back(a.secondsPerStep);
        many.push_back(b.secondsPerStep);
        if (r == 0) {
            hashOne = a.hash;
            hashMany = b.hash;
        }
        identical = identical && a.hash == hashOne && b.hash == hashMany && a.hash == b.hash;
    }
    const double t1 = median(one), tn = median(many);
    std::printf("%d cloths of Experiment I's kind (%d x %d particles each, ClothSettings::threads "
                "%d in the run on more threads) in one world, dt 0.01 s, %d timed steps, median "
                "of %d repetitions:\n",
                cloths, size, size, clothThreads, steps, repetitions);
    std::printf("  1 thread   %8.3f ms per world step\n", 1e3 * t1);
    std::printf("  %d threads  %8.3f ms per world step\n", threads, 1e3 * tn);
    std::printf("  speed-up   %8.2f x\n", t1 / tn);
    std::printf("  every cloth bit-identical on 1 and %d threads: %s (state hash %016llx)\n",
                threads, identical ? "yes" : "NO", static_cast<unsigned long long>(hashOne));
    return identical ? 0 : 1;
}
