// drape-bench: time per step of the cloth core (module/ only) on the paper's Experiment I
// (35 x 35) and on a 256 x 256 sheet with the same material, for every integrator and every
// strain limiter. Google Benchmark runs each case as a fixed number of steps of one fresh
// cloth per repetition and reports the median over repetitions (aggregates only).
//
//   drape-bench                                   all cases, 5 repetitions
//   drape-bench --benchmark_filter=exp1           only Experiment I
//   drape-bench --benchmark_repetitions=9         more repetitions (later flags win)
//
// The scene: particle mass 0.5, spacing 10, spring stiffness 20, gravity (0, -9.8, 0), the two
// top corners pinned, dt 0.01 (Experiment I of the paper). Explicit Euler is unstable on an
// undamped spring network for any dt, but within the 200 steps measured here it stays finite
// (its energy grows by a bounded factor), so all integrators share dt = 0.01.
#include "drape/cloth.hpp"
#include "drape/error.hpp"

#include <benchmark/benchmark.h>

#include <cstdio>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

namespace {

using namespace drape;

struct SceneSpec {
    const char* name;
    Index size;        ///< particles per side
    int steps;         ///< measured steps per repetition (explicit integrators)
    int stepsImplicit; ///< measured steps per repetition for implicit Euler (much slower)
};

std::unique_ptr<Cloth> makeScene(const SceneSpec& scene, IntegratorKind integrator,
                                 LimiterKind limiter) {
    SheetSpec spec;
    spec.rows = scene.size;
    spec.cols = scene.size;
    spec.spacing = 10.0;
    ClothSettings s;
    s.integrator = integrator;
    s.particleMass = 0.5;
    s.springStiffness = 20.0;
    s.gravity = Vec3(0.0, -9.8, 0.0);
    s.limiter.kind = limiter;
    auto cloth = std::make_unique<Cloth>(ClothTopology::build(makeSheet(spec)), s);
    cloth->pin(sheetIndex(spec, 0, 0));
    cloth->pin(sheetIndex(spec, 0, scene.size - 1));
    return cloth;
}

/// Milliseconds per step spent in one phase of the pipeline (0 if the phase never ran).
double phaseMsPerStep(const Cloth& cloth, const char* phase, double steps) {
    const PhaseTimer* t = cloth.timers().find(phase);
    return t && steps > 0 ? 1e3 * t->seconds / steps : 0.0;
}

void runSteps(benchmark::State& state, SceneSpec scene, IntegratorKind integrator,
              LimiterKind limiter) {
    constexpr double dt = 0.01;
    auto cloth = makeScene(scene, integrator, limiter);
    // Untimed warm-up step: the first step evaluates the initial forces and estimates the
    // stability limit (a power iteration), which a running simulation pays once.
    cloth->step(dt);
    cloth->timers().reset();
    const std::uint64_t before = cloth->stepCount();
    try {
        for (auto _ : state)
            cloth->step(dt);
    } catch (const Error& e) {
        state.SkipWithError(e.what());
        return;
    }
    const auto steps = static_cast<double>(cloth->stepCount() - before);
    state.counters["particles"] = static_cast<double>(cloth->particleCount());
    state.counters["max_strain"] = cloth->maxStrain();
    // Where the time goes, per step [ms] (timers were reset after the warm-up step).
    state.counters["integrate_ms"] = phaseMsPerStep(*cloth, "integrate", steps);
    state.counters["limit_ms"] = phaseMsPerStep(*cloth, "strain_limit", steps);
    state.counters["limit_rounds"] = cloth->lastLimiterStats().rounds;
    if (integrator == IntegratorKind::ImplicitEuler)
        state.counters["cg_iters"] = cloth->integrator().lastIterations();
    state.SetItemsProcessed(static_cast<std::int64_t>(steps) *
                            static_cast<std::int64_t>(cloth->particleCount()));
}

std::string cpuModel() {
    std::ifstream in("/proc/cpuinfo");
    std::string line;
    while (std::getline(in, line)) {
        if (line.rfind("model name", 0) == 0) {
            const auto colon = line.find(':');
            if (colon != std::string::npos) return line.substr(colon + 2);
        }
    }
    return "unknown";
}

/// Shows only the median of the repetitions (or the single run) of each case on the console,
/// and at the end prints all medians again as one Markdown table.
class MedianReporter : public benchmark::ConsoleReporter {
  public:
    MedianReporter() : ConsoleReporter(OO_Tabular) {} // plain text: the output is meant for files
    void ReportRuns(const std::vector<Run>& runs) override {
        std::vector<Run> keep;
        for (const Run& r : runs) {
            const bool single = r.run_type == Run::RT_Iteration && r.repetitions <= 1;
            const bool median = r.run_type == Run::RT_Aggregate && r.aggregate_name == "median";
            if (single || median || r.error_occurred) keep.push_back(r);
        }
        if (keep.empty()) return;
        ConsoleReporter::ReportRuns(keep);
        for (const Run& r : keep)
            rows_.push_back(r);
    }
    void Finalize() override {
        ConsoleReporter::Finalize();
        auto& out = GetOutputStream();
        out << "\n| case (scene/integrator/limiter) | median wall ms/step | median CPU ms/step | "
               "limiter ms/step | max strain at end | limiter rounds (last step) |\n"
               "|---|---:|---:|---:|---:|---:|\n";
        for (const Run& r : rows_) {
            std::string name = r.run_name.function_name;
            if (r.error_occurred) {
                out << "| " << name << " | failed: " << r.error_message << " | | | | |\n";
                continue;
            }
            auto counter = [&](const char* key) {
                const auto it = r.counters.find(key);
                return it == r.counters.end() ? 0.0 : it->second.value;
            };
            char line[512];
            std::snprintf(line, sizeof line, "| %s | %.3f | %.3f | %.3f | %.4f | %.0f |\n",
                          name.c_str(), r.GetAdjustedRealTime(), r.GetAdjustedCPUTime(),
                          counter("limit_ms"), counter("max_strain"), counter("limit_rounds"));
            out << line;
        }
    }

  private:
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
                benchmark::RegisterBenchmark(name.c_str(), runSteps, scene, integrator, limiter)
                    ->Iterations(integrator == IntegratorKind::ImplicitEuler ? scene.stepsImplicit
                                                                             : scene.steps)
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
    benchmark::AddCustomContext(
        "scene", "mass 0.5, spacing 10, k 20, g 9.8, two top corners pinned, dt 0.01");
    benchmark::AddCustomContext("time_per_step",
                                "the Time/CPU columns are per step (one iteration = one step)");
    benchmark::Initialize(&n, args.data());
    if (benchmark::ReportUnrecognizedArguments(n, args.data())) return 1;
    MedianReporter reporter;
    benchmark::RunSpecifiedBenchmarks(&reporter);
    benchmark::Shutdown();
    return 0;
}
