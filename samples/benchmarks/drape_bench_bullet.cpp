// drape-bench-bullet: time per step of the paper's Experiment II in a Bullet world, built
// exactly as drape-run builds samples/scenes/experiment2_tablecloth.json (drape::samples), and
// of btSoftBody on the same scene (the compare report's engine, drape::reports).
//
//   drape-bench-bullet                                  all cases, 5 repetitions
//   drape-bench-bullet --benchmark_filter=drape         drape only
//   drape-bench-bullet --scene=path/to/scene.json       another scene file (same cases)
//
// One repetition = a fresh world (untimed), one untimed warm-up step (initial forces, the
// stability estimate, the first broadphase pass), then `steps` timed steps from there: the
// cloth falls, hits the desk, slides and settles within the window (11.58 s at dt 0.01 for
// the default 1158 steps). One benchmark iteration is one step, so the Time and CPU columns
// are per step; the figure shown is the median over the repetitions.
//
// Counters (per step, over the timed window, from the cloth's own phase timers, see
// drape/timers.hpp): <phase>_us for every phase that ran (integrate, strain_limit,
// bullet_contacts_before_limit (contacts found), bullet_contacts (after the limiter's walk),
// springs, damping, contact_force, integrate_finish, and bullet_bodies, the
// handle's work around the cloth step: body snapshot, impulses, proxy), cloth_us = their sum
// (the cloth's part of the world step); "a/b" phases are parts of phase a and are not summed
// again (bullet_contacts/limiter: the follow-up walks the contact stage runs where its
// re-projection moved particles; contacts_own_us = both contact phases without them). Also the wall
// time per step of the first and the last 400 steps (falling against resting), the cloth's own
// limiter rounds per step, and the state at the end of the window.
#include <drape/cloth.hpp>
#include <drape/error.hpp>
#include <drape/strain_limit.hpp>
#include <drape_samples/scene.hpp>
#include <drape_samples/simulation.hpp>
#if DRAPE_BENCH_HAVE_REPORTS
#include <drape_reports/engines.hpp>
#include <drape_reports/scenes.hpp>
#endif

#include <benchmark/benchmark.h>

#include "bench_common.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

namespace {

using namespace drape;
using Clock = std::chrono::steady_clock;

constexpr int kWindow = 400; ///< steps at either end of the run reported separately

double seconds(Clock::time_point a, Clock::time_point b) {
    return std::chrono::duration<double>(b - a).count();
}

/// drape: the scene file through drape::samples::Simulation (what drape-run steps).
void runDrape(benchmark::State& state, samples::SceneDesc scene) {
    std::unique_ptr<samples::Simulation> sim;
    try {
        sim = std::make_unique<samples::Simulation>(scene);
        sim->step(); // untimed warm-up step
    } catch (const std::exception& e) {
        state.SkipWithError(e.what());
        return;
    }
    Cloth& cloth = sim->cloth();
    cloth.timers().reset();
    const std::uint64_t before = cloth.stepCount();
    std::vector<double> perStep;
    perStep.reserve(static_cast<std::size_t>(state.max_iterations));
    std::size_t contacts = 0, rounds = 0, capped = 0;
    const int maxRounds = cloth.settings().limiter.maxRounds;
    try {
        for (auto _ : state) {
            const auto t0 = Clock::now();
            sim->step();
            perStep.push_back(seconds(t0, Clock::now()));
            contacts += sim->contactCount();
            rounds += std::size_t(cloth.lastLimiterStats().rounds);
            capped += cloth.lastLimiterStats().rounds >= maxRounds;
        }
    } catch (const std::exception& e) {
        state.SkipWithError(e.what());
        return;
    }
    const auto steps = static_cast<double>(cloth.stepCount() - before);
    if (steps <= 0) return;
    double clothSeconds = 0.0;
    for (const PhaseTimer& t : cloth.timers().all()) {
        if (t.calls == 0) continue;
        state.counters[t.name + "_us"] = 1e6 * t.seconds / steps;
        // forces_refresh wraps the force terms' own timers (and runs only when the cached
        // forces are stale), and "a/b" is a part of phase a: leave them out of the sum so
        // nothing is counted twice.
        if (t.name != "forces_refresh" && t.name.find('/') == std::string::npos)
            clothSeconds += t.seconds;
    }
    state.counters["cloth_us"] = 1e6 * clothSeconds / steps;
    // The contact stage without the limiter passes it runs (its own work: queries,
    // projection, friction, re-projection).
    const PhaseTimer* stage = cloth.timers().find("bullet_contacts");
    const PhaseTimer* stageBefore = cloth.timers().find("bullet_contacts_before_limit");
    const PhaseTimer* stageLimiter = cloth.timers().find("bullet_contacts/limiter");
    if (stage) {
        const double own = stage->seconds + (stageBefore ? stageBefore->seconds : 0.0) -
                           (stageLimiter ? stageLimiter->seconds : 0.0);
        state.counters["contacts_own_us"] = 1e6 * own / steps;
    }
    const std::size_t w = std::min<std::size_t>(kWindow, perStep.size());
    double first = 0.0, last = 0.0;
    for (std::size_t i = 0; i < w; ++i) {
        first += perStep[i];
        last += perStep[perStep.size() - 1 - i];
    }
    state.counters["first400_us"] = w ? 1e6 * first / double(w) : 0.0;
    state.counters["last400_us"] = w ? 1e6 * last / double(w) : 0.0;
    state.counters["contacts_per_step"] = double(contacts) / steps;
    // The cloth's own limiter (before the contact stage): rounds per step, and the share of
    // steps in which it stopped at its round cap; the contact stage's limiter passes per step.
    state.counters["limiter_rounds_per_step"] = double(rounds) / steps;
    state.counters["limiter_capped_share"] = double(capped) / steps;
    if (stageLimiter)
        state.counters["stage_limiter_passes_per_step"] = double(stageLimiter->calls) / steps;
    state.counters["max_strain"] = cloth.maxStrain();
    state.counters["kinetic_J"] = cloth.kineticEnergy();
    state.counters["particles"] = double(cloth.particleCount());
}

#if DRAPE_BENCH_HAVE_REPORTS
/// btSoftBody on the same scene, through the compare report's engine.
void runSoftBody(benchmark::State& state, reports::ClothScene scene, int piterations,
                 int substeps) {
    std::unique_ptr<reports::ClothEngine> engine;
    try {
        engine = reports::makeSoftBodyEngine(scene, piterations, substeps);
        engine->step(); // untimed warm-up step
    } catch (const std::exception& e) {
        state.SkipWithError(e.what());
        return;
    }
    for (auto _ : state)
        engine->step();
    std::vector<Vec3> x, v;
    engine->state(x, v);
    const auto topology = ClothTopology::build(scene.mesh);
    state.counters["max_strain"] = maxSpringStrain(*topology, x);
    double ke = 0.0;
    for (const Vec3& vi : v)
        ke += 0.5 * scene.particleMass * vi.squaredNorm();
    state.counters["kinetic_J"] = ke;
    state.counters["particles"] = double(x.size());
}
#endif

using bench::cpuModel;
using bench::loadAverage;

/// Shows only the median of the repetitions of each case, then all medians as one Markdown
/// table with the per-phase times in microseconds.
class MedianReporter : public benchmark::ConsoleReporter {
  public:
    MedianReporter() : ConsoleReporter(OO_None) {}
    void ReportRuns(const std::vector<Run>& runs) override {
        const std::vector<Run> keep = bench::keepMedians(runs);
        if (keep.empty()) return;
        ConsoleReporter::ReportRuns(keep);
        for (const Run& r : keep)
            rows_.push_back(r);
    }
    void Finalize() override {
        ConsoleReporter::Finalize();
        auto& out = GetOutputStream();
        out << "\nload average at the end: " << loadAverage() << "\n\n"
            << "| case | median wall us/step | median CPU us/step | cloth us/step | "
               "contact stage us/step (own / its limiter passes) | strain_limit us/step | "
               "integrate us/step | springs us/step | bullet_bodies us/step | "
               "first 400 / last 400 steps wall us | max strain at end |\n"
               "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
        for (const Run& r : rows_) {
            const std::string name = r.run_name.function_name;
            if (r.error_occurred) {
                out << "| " << name << " | failed: " << r.error_message << " | | | | | | | | | |\n";
                continue;
            }
            auto c = [&](const char* key) {
                const auto it = r.counters.find(key);
                return it == r.counters.end() ? -1.0 : it->second.value;
            };
            auto cell = [](double v, const char* f) {
                if (v < 0.0) return std::string("-");
                char b[64];
                std::snprintf(b, sizeof b, f, v);
                return std::string(b);
            };
            out << "| " << name << " | " << cell(r.GetAdjustedRealTime(), "%.1f") << " | "
                << cell(r.GetAdjustedCPUTime(), "%.1f") << " | " << cell(c("cloth_us"), "%.1f")
                << " | "
                << (c("bullet_contacts_us") < 0.0
                        ? std::string("-")
                        : cell(c("bullet_contacts_us") +
                                   std::max(0.0, c("bullet_contacts_before_limit_us")),
                               "%.1f") +
                              " (" + cell(c("contacts_own_us"), "%.1f") + " / " +
                              cell(c("bullet_contacts/limiter_us"), "%.1f") + ")")
                << " | " << cell(c("strain_limit_us"), "%.1f") << " | "
                << cell(c("integrate_us"), "%.1f") << " | " << cell(c("springs_us"), "%.1f")
                << " | " << cell(c("bullet_bodies_us"), "%.1f") << " | "
                << (c("first400_us") < 0.0
                        ? std::string("-")
                        : cell(c("first400_us"), "%.1f") + " / " + cell(c("last400_us"), "%.1f"))
                << " | " << cell(c("max_strain"), "%.4f") << " |\n";
        }
    }

  private:
    std::vector<Run> rows_;
};

} // namespace

int main(int argc, char** argv) {
    std::string scenePath = DRAPE_BENCH_SCENES_DIR "/experiment2_tablecloth.json";
    int steps = 1158; // the paper's 11.58 s at dt 0.01
    bool softBody = true;
    // Our own flags first; the rest goes to Google Benchmark.
    std::vector<char*> args{argv[0]};
    std::string reps = "--benchmark_repetitions=5",
                aggregates = "--benchmark_report_aggregates_only=true";
    args.push_back(reps.data());
    args.push_back(aggregates.data());
    for (int i = 1; i < argc; ++i) {
        if (std::strncmp(argv[i], "--scene=", 8) == 0) {
            scenePath = argv[i] + 8;
        } else if (std::strncmp(argv[i], "--steps=", 8) == 0) {
            steps = std::max(1, std::atoi(argv[i] + 8));
        } else if (std::strcmp(argv[i], "--no-softbody") == 0) {
            softBody = false;
        } else {
            args.push_back(argv[i]);
        }
    }
    samples::SceneDesc scene;
    try {
        scene = samples::loadScene(scenePath);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "drape-bench-bullet: %s\n", e.what());
        return 1;
    }
    const std::string prefix = scene.name + "/";
    benchmark::RegisterBenchmark((prefix + "drape/steps_" + std::to_string(steps)).c_str(),
                                 runDrape, scene)
        ->Iterations(steps)
        ->Unit(benchmark::kMicrosecond);
#if DRAPE_BENCH_HAVE_REPORTS
    if (softBody) {
        try {
            const reports::ClothScene cs = reports::fromSceneFile(scene);
            for (auto [p, s] : std::vector<std::pair<int, int>>{{1, 1}, {4, 1}, {4, 4}}) {
                const std::string name = prefix + "btSoftBody/piterations_" + std::to_string(p) +
                                         "_substeps_" + std::to_string(s) + "/steps_" +
                                         std::to_string(steps);
                benchmark::RegisterBenchmark(name.c_str(), runSoftBody, cs, p, s)
                    ->Iterations(steps)
                    ->Unit(benchmark::kMicrosecond);
            }
        } catch (const std::exception& e) {
            std::fprintf(stderr, "drape-bench-bullet: no btSoftBody cases: %s\n", e.what());
        }
    }
#else
    if (softBody)
        std::fprintf(stderr,
                     "drape-bench-bullet: built without drape::reports: no btSoftBody cases\n");
#endif
    int n = static_cast<int>(args.size());
    benchmark::AddCustomContext("cpu_model", cpuModel());
    benchmark::AddCustomContext("scene", scenePath);
    benchmark::AddCustomContext("load_average_at_start", loadAverage());
    benchmark::AddCustomContext("time_per_step",
                                "the Time/CPU columns are per step (one iteration = one step)");
    benchmark::Initialize(&n, args.data());
    if (benchmark::ReportUnrecognizedArguments(n, args.data())) return 1;
    MedianReporter reporter;
    benchmark::RunSpecifiedBenchmarks(&reporter);
    benchmark::Shutdown();
    return 0;
}
