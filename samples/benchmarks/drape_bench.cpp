// drape-bench: time per step of the cloth core (module/ only) on the paper's Experiment I
// (35 x 35) and on a 256 x 256 sheet with the same material, for every integrator and every
// strain limiter, plus a scaling family (Velocity-Verlet on 32 x 32 to 1000 x 1000 sheets,
// with and without the stress-ordered limiter, on 1 and 2 threads). Google Benchmark runs
// each case as a fixed number of steps per repetition and reports the median over
// repetitions (aggregates only).
//
//   drape-bench                                   all cases, 5 repetitions
//   drape-bench --benchmark_filter=exp1           only Experiment I
//   drape-bench --benchmark_filter=scaling        only the scaling family
//   drape-bench --benchmark_repetitions=9         more repetitions (later flags win)
//
// The scene is Experiment I as samples/scenes/experiment1_suspended_sheet.json defines it (read
// through drape::samples: particle mass 0.5, spacing 10, spring stiffness 20, C_d 0.05, gravity
// (0, -9.8, 0), the two top corners pinned, dt 0.01); the other sizes are that scene resized by
// samples::resizedSheet. Only Cloth::step is timed (the core; no Bullet world). Explicit Euler
// is unstable on a spring network at this dt, but within the 200 steps measured here it stays
// finite (its energy grows by a bounded factor), so all integrators share the scene's dt.
#include "drape/cloth.hpp"
#include "drape/error.hpp"
#include "drape/snapshot.hpp"
#include "drape_samples/scene.hpp"

#include <benchmark/benchmark.h>

#include "bench_common.hpp"

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <ostream>
#include <string>
#include <utility>
#include <vector>

// Under valgrind --tool=callgrind --collect-atstart=no (scripts/profile.sh), only the timed
// steps are collected: no setup, no warm-up step, no state restores. Outside valgrind the
// client request is a few instructions.
#if defined(__has_include)
#if __has_include(<valgrind/callgrind.h>)
#include <valgrind/callgrind.h>
#define DRAPE_BENCH_TOGGLE_COLLECT() CALLGRIND_TOGGLE_COLLECT
#endif
#endif
#ifndef DRAPE_BENCH_TOGGLE_COLLECT
#define DRAPE_BENCH_TOGGLE_COLLECT() ((void)0)
#endif

namespace {

using namespace drape;

/// Experiment I, read once from its scene file.
const samples::SceneDesc& experiment1() {
    static const samples::SceneDesc scene =
        samples::loadScene(DRAPE_BENCH_SCENES_DIR "/experiment1_suspended_sheet.json");
    return scene;
}

/// Experiment I resized to size x size (samples::resizedSheet; the file's own size as it is).
samples::SceneDesc experiment1(Index size) {
    const samples::SceneDesc& e1 = experiment1();
    if (e1.sheet->spec.rows == size && e1.sheet->spec.cols == size) return e1;
    return samples::resizedSheet(e1, size, size);
}

const double kDt = experiment1().timeStep;

struct SceneSpec {
    const char* name;
    Index size;        ///< particles per side
    int steps;         ///< measured steps per repetition (explicit integrators)
    int stepsImplicit; ///< measured steps per repetition for implicit Euler (much slower)
};

/// The scene file's cloth settings with another integrator, limiter and thread count.
ClothSettings sceneSettings(IntegratorKind integrator, LimiterKind limiter, int threads) {
    ClothSettings s = experiment1().cloth;
    s.integrator = integrator;
    s.limiter.kind = limiter;
    s.threads = threads;
    return s;
}

SheetSpec sheetSpec(Index size) {
    return experiment1(size).sheet->spec;
}

/// The cloth of Experiment I at size x size, pinned as the scene file pins it.
std::unique_ptr<Cloth> makeCloth(Index size, TopologyPtr topology, const ClothSettings& s) {
    auto cloth = std::make_unique<Cloth>(std::move(topology), s);
    for (Index p : samples::fixedPins(experiment1(size)))
        cloth->pin(p);
    return cloth;
}

/// One counter per phase the cloth's timers report (named "<phase>_ms"): wall milliseconds
/// per step spent in it. Phases that never ran (calls == 0) are left out.
void addPhaseCounters(benchmark::State& state, const Cloth& cloth, double steps) {
    if (steps <= 0) return;
    for (const PhaseTimer& t : cloth.timers().all()) {
        if (t.calls == 0) continue;
        state.counters[t.name + "_ms"] = 1e3 * t.seconds / steps;
    }
}

void runSteps(benchmark::State& state, SceneSpec scene, IntegratorKind integrator,
              LimiterKind limiter, bool plainWorklist) {
    const SheetSpec spec = sheetSpec(scene.size);
    ClothSettings settings = sceneSettings(integrator, limiter, 1);
    if (plainWorklist) { // the worklist alone: no warm start, no long-range attachments
        settings.limiter.warmStart = 0.0;
        settings.limiter.longRangeAttachments = false;
    }
    auto cloth = makeCloth(scene.size, ClothTopology::build(makeSheet(spec)), settings);
    // Untimed warm-up step: the first step evaluates the initial forces and estimates the
    // stability limit (a power iteration), which a running simulation pays once.
    cloth->step(kDt);
    cloth->timers().reset();
    const std::uint64_t before = cloth->stepCount();
    try {
        DRAPE_BENCH_TOGGLE_COLLECT(); // on
        for (auto _ : state)
            cloth->step(kDt);
        DRAPE_BENCH_TOGGLE_COLLECT(); // off
    } catch (const Error& e) {
        state.SkipWithError(e.what());
        return;
    }
    const auto steps = static_cast<double>(cloth->stepCount() - before);
    state.counters["particles"] = static_cast<double>(cloth->particleCount());
    state.counters["max_strain"] = cloth->maxStrain();
    // Where the time goes, per step [ms] (timers were reset after the warm-up step).
    addPhaseCounters(state, *cloth, steps);
    state.counters["limit_rounds"] = cloth->lastLimiterStats().rounds;
    if (integrator == IntegratorKind::ImplicitEuler)
        state.counters["cg_iters"] = cloth->integrator().lastIterations();
    state.SetItemsProcessed(static_cast<std::int64_t>(steps) *
                            static_cast<std::int64_t>(cloth->particleCount()));
}

// --- scaling family ------------------------------------------------------------------------
//
// Velocity-Verlet on square sheets of ~1e3 to 1e6 particles, with and without the
// stress-ordered limiter, on 1 and 2 threads. The limiter's work depends on how stretched the
// cloth is, and a hanging sheet stretches more the longer it runs; so that every size is timed
// in the same physical state, each case replays the same window of simulated time: the state
// after the untimed warm-up step (t = 0.01 s) is saved, and every kScalingWindow timed steps it
// is restored with the timer paused. Every size is therefore timed over t = 0.01 .. 0.11 s.

constexpr int kScalingWindow = 10;

struct ScalingSpec {
    Index size; ///< particles per side
    int steps;  ///< timed steps per repetition (a multiple of kScalingWindow)
};

struct ScalingCase {
    ScalingSpec spec;
    LimiterKind limiter;
    int threads;
};

/// The cloth of the scaling case that runs now, kept across its repetitions (Google Benchmark
/// runs a case's repetitions back to back), with the state to replay. Building a 1000 x 1000
/// sheet and its first step takes seconds; this pays it once per case, not per repetition.
struct PreparedCloth {
    std::string key;
    std::unique_ptr<Cloth> cloth;
    std::vector<unsigned char> start; ///< snapshot after the warm-up step
};

Cloth& preparedCloth(const std::string& key, const ScalingCase& c,
                     std::vector<unsigned char>*& start) {
    static Index topologySize = 0;
    static TopologyPtr topology;
    static PreparedCloth prepared;
    if (prepared.key != key) {
        prepared.cloth.reset(); // free the previous case's cloth before building the next
        if (topologySize != c.spec.size) {
            topology.reset();
            topology = ClothTopology::build(makeSheet(sheetSpec(c.spec.size)));
            topologySize = c.spec.size;
        }
        prepared.cloth =
            makeCloth(c.spec.size, topology,
                      sceneSettings(IntegratorKind::VelocityVerlet, c.limiter, c.threads));
        prepared.cloth->step(kDt); // untimed warm-up step (initial forces, stability estimate)
        prepared.start = saveSnapshot(*prepared.cloth);
        prepared.key = key;
    }
    start = &prepared.start;
    return *prepared.cloth;
}

/// Restores the saved state and re-primes the stability estimate that loadSnapshot drops, so
/// the next timed step does exactly what a running simulation's step does.
void restart(Cloth& cloth, const std::vector<unsigned char>& start) {
    loadSnapshot(cloth, start);
    benchmark::DoNotOptimize(cloth.stableTimeStep());
}

/// A cloth at rest, awake or asleep: a 35 x 35 sheet of cloth size (0.68 m square, 6 kg,
/// k = 5 N/m, C_d = 0.05 N s/m, 60 Hz; the limiter carries its weight) hung from its whole top row,
/// settled (untimed) until it sleeps (ClothSettings::sleep, defaults: 1 cm for 1 s), then stepped.
/// `asleep` = false runs the same settling with sleeping off: the same state, stepped awake. The
/// ratio of the two is what a sleeping cloth saves.
void runRest(benchmark::State& state, bool asleep) {
    SheetSpec spec; // not Experiment I: a sheet of cloth size, described here
    spec.rows = 35;
    spec.cols = 35;
    spec.spacing = 0.02;
    ClothSettings settings;
    settings.integrator = IntegratorKind::VelocityVerlet;
    settings.limiter.kind = LimiterKind::StressOrdered;
    settings.gravity = Vec3(0.0, -9.8, 0.0);
    settings.particleMass = 5e-3;
    settings.springStiffness = 5.0;
    settings.damping = 0.05;
    settings.sleep.enabled = true;
    const double dt = 1.0 / 60.0;
    auto cloth = std::make_unique<Cloth>(ClothTopology::build(makeSheet(spec)), settings);
    for (Index c = 0; c < spec.cols; ++c)
        cloth->pin(sheetIndex(spec, 0, c));
    const int maxSettle = 6000; // 100 s simulated
    int settled = 0;
    while (!cloth->isAsleep() && settled < maxSettle) {
        cloth->step(dt);
        ++settled;
    }
    if (!cloth->isAsleep()) {
        state.SkipWithError("the resting sheet did not fall asleep within 100 s");
        return;
    }
    if (!asleep) { // the same state, awake and with sleeping off
        settings.sleep.enabled = false;
        auto awake = std::make_unique<Cloth>(ClothTopology::build(makeSheet(spec)), settings);
        for (Index c = 0; c < spec.cols; ++c)
            awake->pin(sheetIndex(spec, 0, c));
        loadSnapshot(*awake, saveSnapshot(*cloth));
        cloth = std::move(awake);
    }
    cloth->timers().reset();
    for (auto _ : state)
        cloth->step(dt);
    state.counters["particles"] = static_cast<double>(cloth->particleCount());
    state.counters["settle_steps"] = settled;
    state.counters["asleep"] = cloth->isAsleep() ? 1.0 : 0.0;
    state.counters["max_strain"] = cloth->maxStrain();
    addPhaseCounters(state, *cloth, static_cast<double>(state.iterations()));
}

void runScaling(benchmark::State& state, std::string key, ScalingCase c) {
    try {
        std::vector<unsigned char>* start = nullptr;
        Cloth& cloth = preparedCloth(key, c, start);
        restart(cloth, *start);
        cloth.timers().reset();
        std::int64_t steps = 0;
        int inWindow = 0;
        DRAPE_BENCH_TOGGLE_COLLECT(); // on
        for (auto _ : state) {
            if (inWindow == kScalingWindow) {
                DRAPE_BENCH_TOGGLE_COLLECT(); // off
                state.PauseTiming();
                restart(cloth, *start);
                state.ResumeTiming();
                DRAPE_BENCH_TOGGLE_COLLECT(); // on
                inWindow = 0;
            }
            cloth.step(kDt);
            ++inWindow;
            ++steps;
        }
        DRAPE_BENCH_TOGGLE_COLLECT(); // off
        const auto n = static_cast<double>(cloth.particleCount());
        state.counters["particles"] = n;
        state.counters["threads"] = c.threads;
        state.counters["max_strain"] = cloth.maxStrain();
        state.counters["limit_rounds"] = cloth.lastLimiterStats().rounds;
        addPhaseCounters(state, cloth, static_cast<double>(steps));
        // CPU nanoseconds per particle per step: (n * 1e-9 * steps / cpu seconds)^-1.
        state.counters["ns_per_particle"] = benchmark::Counter(
            n * 1e-9, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
        state.SetItemsProcessed(steps * static_cast<std::int64_t>(n));
    } catch (const Error& e) {
        state.SkipWithError(e.what());
    }
}

using bench::cpuModel;
using bench::loadAverage;

/// Least-squares slope of log(y) against log(x).
double logLogSlope(const std::vector<double>& x, const std::vector<double>& y) {
    const std::size_t n = x.size();
    if (n < 2) return std::nan("");
    double mx = 0.0, my = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
        mx += std::log(x[i]);
        my += std::log(y[i]);
    }
    mx /= static_cast<double>(n);
    my /= static_cast<double>(n);
    double sxy = 0.0, sxx = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
        const double dx = std::log(x[i]) - mx;
        sxy += dx * (std::log(y[i]) - my);
        sxx += dx * dx;
    }
    return sxx > 0.0 ? sxy / sxx : std::nan("");
}

/// Shows only the median of the repetitions (or the single run) of each case on the console,
/// and at the end prints all medians again as Markdown tables: every case, then the scaling
/// family with its log-log slopes and the 2-thread speedup.
class MedianReporter : public benchmark::ConsoleReporter {
  public:
    using Run = benchmark::BenchmarkReporter::Run;

    explicit MedianReporter(std::map<std::string, ScalingCase> scaling)
        : ConsoleReporter(OO_Tabular), scaling_(std::move(scaling)) {}
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
        out << "\nload average at the end: " << loadAverage() << "\n";
        out << "\n| case | median wall ms/step | median CPU ms/step | "
               "limiter ms/step | max strain at end | limiter rounds (last step) |\n"
               "|---|---:|---:|---:|---:|---:|\n";
        for (const Run& r : rows_) {
            const std::string name = r.run_name.function_name;
            if (r.error_occurred) {
                out << "| " << name << " | failed: " << r.error_message << " | | | | |\n";
                continue;
            }
            char line[512];
            std::snprintf(line, sizeof line, "| %s | %.3f | %.3f | %.3f | %.4f | %.0f |\n",
                          name.c_str(), wallMs(r), cpuMs(r), counter(r, "strain_limit_ms"),
                          counter(r, "max_strain"), counter(r, "limit_rounds"));
            out << line;
        }
        printScaling(out);
    }

  private:
    static double counter(const Run& r, const std::string& key) {
        const auto it = r.counters.find(key);
        return it == r.counters.end() ? 0.0 : it->second.value;
    }
    static double wallMs(const Run& r) {
        return 1e3 * r.GetAdjustedRealTime() / benchmark::GetTimeUnitMultiplier(r.time_unit);
    }
    static double cpuMs(const Run& r) {
        return 1e3 * r.GetAdjustedCPUTime() / benchmark::GetTimeUnitMultiplier(r.time_unit);
    }

    void printScaling(std::ostream& out) const {
        struct Row {
            const Run* run;
            ScalingCase c;
        };
        std::vector<Row> rows;
        for (const Run& r : rows_) {
            const auto it = scaling_.find(r.run_name.function_name);
            if (it != scaling_.end() && !r.error_occurred) rows.push_back({&r, it->second});
        }
        if (rows.empty()) return;
        out << "\nScaling (Velocity-Verlet, t = 0.01 .. 0.11 s replayed; CPU = process CPU time, "
               "all threads; phases = wall ms/step from cloth.timers(); 'rest' = wall minus "
               "the phases)\n\n"
               "| particles | limiter | threads | median wall ms/step | median CPU ms/step | "
               "CPU ns/particle/step | phases ms/step | max strain | rounds |\n"
               "|---:|---|---:|---:|---:|---:|---|---:|---:|\n";
        for (const Row& row : rows) {
            const Run& r = *row.run;
            std::string phases;
            double phaseSum = 0.0;
            for (const auto& kv : r.counters) {
                const std::string& k = kv.first;
                if (k.size() < 4 || k.compare(k.size() - 3, 3, "_ms") != 0) continue;
                char part[96];
                std::snprintf(part, sizeof part, "%s%s %.3f", phases.empty() ? "" : ", ",
                              k.substr(0, k.size() - 3).c_str(), kv.second.value);
                phases += part;
                phaseSum += kv.second.value;
            }
            char part[64];
            std::snprintf(part, sizeof part, ", rest %.3f", wallMs(r) - phaseSum);
            phases += part;
            const double n = counter(r, "particles");
            char line[1024];
            std::snprintf(
                line, sizeof line, "| %.0f | %s | %d | %.3f | %.3f | %.1f | %s | %.4f | %.0f |\n",
                n, toString(row.c.limiter), row.c.threads, wallMs(r), cpuMs(r), 1e6 * cpuMs(r) / n,
                phases.c_str(), counter(r, "max_strain"), counter(r, "limit_rounds"));
            out << line;
        }

        // Slopes per (limiter, threads) series.
        std::map<std::pair<std::string, int>, std::vector<const Row*>> series;
        for (const Row& row : rows)
            series[{toString(row.c.limiter), row.c.threads}].push_back(&row);
        out << "\nLeast-squares slope of log(time per step) against log(particles) "
               "(1 = linear)\n\n"
               "| limiter | threads | sizes | slope (CPU) | slope (wall) |\n"
               "|---|---:|---:|---:|---:|\n";
        for (const auto& kv : series) {
            std::vector<double> n, cpu, wall;
            for (const Row* row : kv.second) {
                n.push_back(counter(*row->run, "particles"));
                cpu.push_back(cpuMs(*row->run));
                wall.push_back(wallMs(*row->run));
            }
            char line[256];
            if (n.size() < 2) {
                std::snprintf(line, sizeof line, "| %s | %d | %zu | n/a | n/a |\n",
                              kv.first.first.c_str(), kv.first.second, n.size());
            } else {
                std::snprintf(line, sizeof line, "| %s | %d | %zu | %.3f | %.3f |\n",
                              kv.first.first.c_str(), kv.first.second, n.size(),
                              logLogSlope(n, cpu), logLogSlope(n, wall));
            }
            out << line;
        }

        // 2-thread speedup per (size, limiter).
        std::map<std::pair<double, std::string>, std::map<int, const Run*>> bySize;
        for (const Row& row : rows)
            bySize[{counter(*row.run, "particles"), toString(row.c.limiter)}][row.c.threads] =
                row.run;
        bool header = false;
        for (const auto& kv : bySize) {
            const auto one = kv.second.find(1), two = kv.second.find(2);
            if (one == kv.second.end() || two == kv.second.end()) continue;
            if (!header) {
                out << "\n2-thread speedup (wall 1 thread / wall 2 threads; CPU ratio = process "
                       "CPU 2 threads / 1 thread, the parallel overhead)\n\n"
                       "| particles | limiter | wall speedup | CPU ratio |\n"
                       "|---:|---|---:|---:|\n";
                header = true;
            }
            char line[256];
            std::snprintf(line, sizeof line, "| %.0f | %s | %.2f | %.2f |\n", kv.first.first,
                          kv.first.second.c_str(), wallMs(*one->second) / wallMs(*two->second),
                          cpuMs(*two->second) / cpuMs(*one->second));
            out << line;
        }
    }

    std::map<std::string, ScalingCase> scaling_;
    std::vector<Run> rows_;
};

} // namespace

int main(int argc, char** argv) {
    const std::vector<SceneSpec> scenes{
        {"exp1_35x35", 35, 200, 50},   // 2 s (0.5 s for implicit Euler) of Experiment I
        {"sheet_256x256", 256, 10, 2}, // 65,536 particles: a few steps are enough to time
    };
    const IntegratorKind integrators[] = {
        IntegratorKind::VelocityVerlet, IntegratorKind::ExplicitEuler,
        IntegratorKind::SymplecticEuler, IntegratorKind::RungeKutta4,
        IntegratorKind::ImplicitEuler};
    const LimiterKind limiters[] = {LimiterKind::None, LimiterKind::StressOrdered,
                                    LimiterKind::Provot};
    for (const SceneSpec& scene : scenes) {
        for (IntegratorKind integrator : integrators) {
            for (LimiterKind limiter : limiters) {
                const std::string name =
                    std::string(scene.name) + "/" + toString(integrator) + "/" + toString(limiter);
                benchmark::RegisterBenchmark(name.c_str(), runSteps, scene, integrator, limiter,
                                             false)
                    ->Iterations(integrator == IntegratorKind::ImplicitEuler ? scene.stepsImplicit
                                                                             : scene.steps)
                    ->Unit(benchmark::kMillisecond);
            }
        }
        // The stress-ordered worklist without warm start and long-range attachments.
        const std::string name = std::string(scene.name) + "/velocity_verlet/stress_ordered_plain";
        benchmark::RegisterBenchmark(name.c_str(), runSteps, scene, IntegratorKind::VelocityVerlet,
                                     LimiterKind::StressOrdered, true)
            ->Iterations(scene.steps)
            ->Unit(benchmark::kMillisecond);
    }

    // A cloth at rest: awake against asleep.
    for (bool asleep : {false, true}) {
        benchmark::RegisterBenchmark(asleep ? "rest_35x35/asleep" : "rest_35x35/awake", runRest,
                                     asleep)
            ->Iterations(1000)
            ->Unit(benchmark::kMicrosecond);
    }

    // Scaling family: steps per repetition give roughly 0.2 to 1 s per repetition on one
    // thread (at the 2026-11-22 costs of ~50 to 100 ns per particle per step).
    const ScalingSpec sizes[] = {{32, 4000}, {100, 400}, {316, 40}, {1000, 10}};
    std::map<std::string, ScalingCase> scaling;
    for (const ScalingSpec& size : sizes) {
        for (LimiterKind limiter : {LimiterKind::StressOrdered, LimiterKind::None}) {
            for (int threads : {1, 2}) {
                const ScalingCase c{size, limiter, threads};
                const std::string name = "scaling/" + std::to_string(size.size) + "x" +
                                         std::to_string(size.size) + "/velocity_verlet/" +
                                         toString(limiter) + "/threads:" + std::to_string(threads);
                scaling.emplace(name, c);
                benchmark::RegisterBenchmark(name.c_str(), runScaling, name, c)
                    ->Iterations(size.steps)
                    ->MeasureProcessCPUTime()
                    ->Unit(benchmark::kMillisecond);
            }
        }
    }

    // Defaults first, so that flags given on the command line (parsed later) win.
    std::vector<char*> args{argv[0]};
    std::string reps = "--benchmark_repetitions=5",
                aggregates = "--benchmark_report_aggregates_only=true";
    args.push_back(reps.data());
    args.push_back(aggregates.data());
    for (int i = 1; i < argc; ++i)
        args.push_back(argv[i]);
    int n = static_cast<int>(args.size());

    benchmark::AddCustomContext("cpu_model", cpuModel());
    benchmark::AddCustomContext("load_average_at_start", loadAverage());
    benchmark::AddCustomContext(
        "scene", "samples/scenes/experiment1_suspended_sheet.json (mass 0.5, spacing 10, k 20, "
                 "C_d 0.05, g 9.8, two top corners pinned, dt 0.01), resized per case");
    benchmark::AddCustomContext("time_per_step",
                                "the Time/CPU columns are per step (one iteration = one step)");
    benchmark::Initialize(&n, args.data());
    if (benchmark::ReportUnrecognizedArguments(n, args.data())) return 1;
    MedianReporter reporter(std::move(scaling));
    benchmark::RunSpecifiedBenchmarks(&reporter);
    benchmark::Shutdown();
    return 0;
}
