// drape-bench-limiter: the strain limiter's bars on a shipped scene, one row per limiter
// variant: work (limiter spring evaluations per step / spring count), the largest strain
// after any step, the energy the limiter can inject (sum of step-to-step rises of kinetic +
// gravitational + spring energy, and the largest single rise) against the energy the run
// dissipates, the final lowest point, safety-cap hits and the time per step (median over
// --repeat runs of the whole scene; all variants of one invocation run in the same window).
//
//   drape-bench-limiter                                   Experiment I (10 s), all variants
//   drape-bench-limiter --scene samples/scenes/experiment2_tablecloth.json
//   drape-bench-limiter --reference                       adds Provot run to convergence
//   drape-bench-limiter --out samples/benchmarks/LIMITER.md
//
// The scene is built by drape::samples exactly as drape-run builds it (a Bullet world stepped
// through stepSimulation when the scene has rigid bodies).
#include "drape_samples/scene.hpp"
#include "drape_samples/simulation.hpp"

#include <drape/cloth.hpp>

#include <CLI/CLI.hpp>

#include "bench_common.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

namespace {

using namespace drape;

struct Variant {
    std::string name;
    LimiterSettings limiter;
};

struct Row {
    std::string name;
    double workMean = 0.0, workMax = 0.0;
    double peakStrain = -1.0;
    double rise = 0.0, maxRise = 0.0, dissipated = 0.0;
    double lowest = 0.0;
    std::uint64_t capHits = 0;
    double msPerStep = 0.0;
    std::size_t steps = 0;
};

double clothEnergy(const Cloth& c) {
    return c.kineticEnergy() + c.gravityEnergy() + c.springEnergy();
}

double lowestPoint(const Cloth& c) {
    const Vec3 g = c.settings().gravity;
    const Vec3 up = g.norm() > 0.0 ? Vec3(-g.normalized()) : Vec3(Vec3::UnitY());
    double low = std::numeric_limits<double>::infinity();
    for (const Vec3& x : c.positions())
        low = std::min(low, x.dot(up));
    return low;
}

Row runOnce(const samples::SceneDesc& base, const Variant& v, bool measure) {
    samples::SceneDesc scene = base;
    scene.cloth.limiter = v.limiter;
    samples::Simulation sim(scene);
    Row r;
    r.name = v.name;
    const Cloth& c = sim.cloth();
    const double springs =
        static_cast<double>(std::max<std::size_t>(c.topology().springCount(), 1));
    double e = measure ? clothEnergy(c) : 0.0;
    const std::size_t steps = scene.stepCount();
    double work = 0.0, seconds = 0.0;
    for (std::size_t s = 0; s < steps; ++s) {
        const auto t0 = std::chrono::steady_clock::now();
        sim.step();
        seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        const double w = static_cast<double>(c.lastLimiterStats().work) / springs;
        work += w;
        r.workMax = std::max(r.workMax, w);
        if (!measure) continue;
        r.peakStrain = std::max(r.peakStrain, c.maxStrain());
        const double e2 = clothEnergy(c);
        if (e2 > e) {
            r.rise += e2 - e;
            r.maxRise = std::max(r.maxRise, e2 - e);
        } else {
            r.dissipated += e - e2;
        }
        e = e2;
    }
    r.steps = steps;
    r.workMean = work / static_cast<double>(steps);
    r.lowest = lowestPoint(c);
    r.capHits = c.limiterCapHits();
    r.msPerStep = 1e3 * seconds / static_cast<double>(steps);
    return r;
}

std::string fmt(const char* f, double v) {
    char b[64];
    std::snprintf(b, sizeof b, f, v);
    return b;
}

} // namespace

int main(int argc, char** argv) {
    CLI::App app{
        "drape-bench-limiter: the strain limiter's work, strain, energy and shape on a scene"};
    std::string scenePath =
        std::string(DRAPE_BENCH_SCENES_DIR) + "/experiment1_suspended_sheet.json";
    std::string out;
    int repeat = 3;
    bool reference = false;
    app.add_option("--scene", scenePath, "scene file");
    app.add_option("--repeat", repeat, "timed runs per variant (median)")->check(CLI::Range(1, 99));
    app.add_flag("--reference", reference, "add Provot run to convergence (slow)");
    app.add_option("--out", out, "also write the Markdown table to this file");
    double warm = -1.0, slack = -1.0;
    bool onlyDefault = false;
    app.add_option("--warm-start", warm,
                   "warm start of the default row (LimiterSettings::warmStart)");
    app.add_option("--slack", slack, "long-range slack of the default row");
    app.add_flag("--default-only", onlyDefault, "run the default row only");
    CLI11_PARSE(app, argc, argv);

    samples::SceneDesc scene;
    try {
        scene = samples::loadScene(scenePath);
    } catch (const std::exception& e) {
        std::cerr << e.what() << "\n";
        return 2;
    }
    const LimiterSettings shipped = scene.cloth.limiter;
    std::vector<Variant> variants;
    {
        Variant d{"stress-ordered worklist, default (attachments + warm start " +
                      fmt("%.1f", shipped.warmStart) + ")",
                  shipped};
        d.limiter.kind = LimiterKind::StressOrdered;
        if (warm >= 0.0) d.limiter.warmStart = warm;
        if (slack >= 0.0) d.limiter.longRangeSlack = slack;
        if (warm >= 0.0 || slack >= 0.0) {
            d.name = "stress-ordered worklist, warm start " + fmt("%.2f", d.limiter.warmStart) +
                     ", slack " + fmt("%.3f", d.limiter.longRangeSlack);
        }
        variants.push_back(d);
    }
    if (!onlyDefault) {
        const Variant d = variants.front();
        Variant a = d;
        a.name = "worklist + attachments, no warm start";
        a.limiter.warmStart = 0.0;
        variants.push_back(a);
        Variant w = d;
        w.name = "worklist + warm start " + fmt("%.1f", d.limiter.warmStart) + ", no attachments";
        w.limiter.longRangeAttachments = false;
        variants.push_back(w);
        Variant p = d;
        p.name = "worklist alone";
        p.limiter.warmStart = 0.0;
        p.limiter.longRangeAttachments = false;
        variants.push_back(p);
        Variant s = d;
        s.name = "attachments at the plain geodesic (slack 1), warm start " +
                 fmt("%.1f", d.limiter.warmStart);
        s.limiter.longRangeSlack = 1.0;
        variants.push_back(s);
        Variant pv = d;
        pv.name = "Provot sweeps, cap 64";
        pv.limiter.kind = LimiterKind::Provot;
        pv.limiter.maxRounds = 64;
        variants.push_back(pv);
        if (reference) {
            Variant ref = pv;
            ref.name = "reference: Provot to convergence (tolerance 1e-7)";
            ref.limiter.tolerance = 1e-7;
            ref.limiter.maxRounds = 1000000;
            variants.push_back(ref);
        }
    }
    std::vector<Row> rows;
    for (const Variant& v : variants) {
        std::fprintf(stderr, "running: %s\n", v.name.c_str());
        Row r;
        try {
            r = runOnce(scene, v, true);
            std::vector<double> times{r.msPerStep};
            const int timed = v.limiter.maxRounds > 100000 ? 1 : repeat;
            for (int k = 1; k < timed; ++k)
                times.push_back(runOnce(scene, v, false).msPerStep);
            std::sort(times.begin(), times.end());
            r.msPerStep = times[times.size() / 2];
        } catch (const std::exception& e) {
            std::fprintf(stderr, "  failed: %s\n", e.what());
            r.name = v.name + " (failed: " + e.what() + ")";
        }
        rows.push_back(r);
    }
    std::ostringstream md;
    md << "Scene: `" << scene.name << "` (" << scene.stepCount() << " steps of " << scene.timeStep
       << " s), limit " << shipped.maxStrain << " + tolerance " << shipped.tolerance << ".  \n"
       << "Machine: " << bench::cpuModel() << ", load average at start " << bench::loadAverage()
       << ".  \n"
       << "Time per step: median of " << repeat << " whole runs, one thread.\n\n"
       << "| limiter | work mean | work max | peak strain | energy rise [J] | largest rise in "
          "one step [J] | dissipated [J] | final lowest point | cap hits | ms/step |\n"
       << "|---|---|---|---|---|---|---|---|---|---|\n";
    for (const Row& r : rows) {
        md << "| " << r.name << " | " << fmt("%.2f", r.workMean) << " | " << fmt("%.1f", r.workMax)
           << " | " << fmt("%.5f", r.peakStrain) << " | " << fmt("%.1f", r.rise) << " | "
           << fmt("%.1f", r.maxRise) << " | " << fmt("%.4g", r.dissipated) << " | "
           << fmt("%.2f", r.lowest) << " | " << r.capHits << " | " << fmt("%.3f", r.msPerStep)
           << " |\n";
    }
    std::cout << md.str();
    if (!out.empty()) {
        std::ofstream f(out, std::ios::app);
        f << "\n" << md.str();
    }
    return 0;
}
