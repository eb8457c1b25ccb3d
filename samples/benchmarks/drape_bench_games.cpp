// drape-bench-games: how drape behaves in the scenes a game is made of, with DEFAULT settings,
// as a new user would write them (games_scenes.hpp): a real btDiscreteDynamicsWorld stepped
// once per 60 Hz frame with stepSimulation(1/60) (Bullet's defaults: maxSubSteps 1, fixed step
// 1/60), one cloth added with drape::bullet::addCloth and default ClothSettings /
// BulletClothSettings.
//
// Per scene: the thread CPU time of every stepSimulation call (rigid bodies + cloth), the
// strain limiter's work and safety-cap hits, the peak strain after any frame against the
// limiter's bound, the cloth steps per frame, when the cloth fell asleep, and what the scene
// itself measures (momentum of a cape on a dynamic body, a stack's displacement and sleep).
// A scene that throws is reported with its error, never a crash.
//
//   drape-bench-games                           all scenes, Markdown tables on stdout
//   drape-bench-games --scene flag,stack        some scenes (repeatable or comma list)
//   drape-bench-games --seconds-scale 0.1       a quick smoke run (durations x 0.1)
//   drape-bench-games --max-frames 300          at most 300 frames per scene
//   drape-bench-games --out games.md            also write the tables with the machine named
#include "games_scenes.hpp"

#include <drape/error.hpp>

#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#ifndef DRAPE_BENCH_BUILD_TYPE
#define DRAPE_BENCH_BUILD_TYPE "unknown"
#endif

namespace {

using namespace drape;
using games::GameScene;
using games::SceneEntry;

/// A sub-step count setting as text: a number, or "auto" for one not given (the setting is an
/// int or a std::optional<int>, depending on the core's version).
[[maybe_unused]] std::string substepSetting(int n) {
    return std::to_string(n);
}
[[maybe_unused]] std::string substepSetting(const std::optional<int>& n) {
    return n ? std::to_string(*n) : std::string("auto");
}

/// CPU time of the calling thread [s].
double threadSeconds() {
    timespec ts{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

/// What one scene measured.
struct Row {
    std::string scene;
    std::string error; ///< empty: the scene ran to its end
    std::size_t particles = 0, springs = 0;
    std::size_t frames = 0, plannedFrames = 0;
    double wallSeconds = 0.0;
    std::vector<double> cpuMs; ///< per frame
    double work = 0.0;         ///< limiter spring evaluations, summed over the frames
    std::uint64_t capHits = 0;
    double peakStrain = 0.0, bound = 0.0;
    std::string substeps; ///< BulletClothSettings::substeps
    std::uint64_t clothSteps = 0, sleptSteps = 0;
    std::uint64_t maxStepsPerFrame = 0;
    bool stepsEstimated = false; ///< a frame took more than one awake cloth step
    double firstAsleep = -1.0;   ///< scene time the cloth first fell asleep [s]
    double asleepSince = -1.0;   ///< start of the asleep run that lasted to the end [s]
    double mass = 0.0, stiffness = 0.0, stableDt = 0.0;
    /// Limiter walks run again inside the contact stage (ContactStats::relimitWalks).
    std::uint64_t relimitWalks = 0;
    std::string notes;
};

double percentile(std::vector<double> v, double q) {
    if (v.empty()) return 0.0;
    std::sort(v.begin(), v.end());
    const double rank = std::ceil(q * static_cast<double>(v.size()));
    const std::size_t i = rank < 1.0 ? 0 : static_cast<std::size_t>(rank) - 1;
    return v[std::min(i, v.size() - 1)];
}

double mean(const std::vector<double>& v) {
    double s = 0.0;
    for (double x : v)
        s += x;
    return v.empty() ? 0.0 : s / static_cast<double>(v.size());
}

Row runScene(const SceneEntry& entry, double secondsScale, long maxFrames) {
    Row r;
    r.scene = entry.name;
    const auto wall0 = std::chrono::steady_clock::now();
    try {
        GameScene s = entry.make(); // untimed: building, pins, attachments, a stack's settling
        Cloth& cloth = *s.cloth;
        const bullet::BulletCloth& handle = *s.handle;
        r.particles = cloth.particleCount();
        r.springs = cloth.topology().springCount();
        for (double m : cloth.masses())
            r.mass += m;
        r.stiffness = mean(cloth.stiffness());
        r.stableDt = cloth.stableTimeStep();
        r.bound = cloth.settings().limiter.maxStrain + cloth.settings().limiter.tolerance;
        r.substeps = substepSetting(handle.settings().substeps);
        r.plannedFrames = static_cast<std::size_t>(std::llround(s.seconds * secondsScale * 60.0));
        if (maxFrames > 0)
            r.plannedFrames = std::min(r.plannedFrames, static_cast<std::size_t>(maxFrames));
        r.cpuMs.reserve(r.plannedFrames);
        btDiscreteDynamicsWorld* world = s.world->world();
        const std::uint64_t steps0 = handle.totalStats().steps, slept0 = cloth.sleptSteps();
        const std::uint64_t caps0 = cloth.limiterCapHits();
        const std::uint64_t relimits0 = handle.totalStats().relimitWalks;
        for (std::size_t f = 0; f < r.plannedFrames; ++f) {
            const double tEnd = static_cast<double>(f + 1) / 60.0;
            if (s.beforeFrame) s.beforeFrame(tEnd);
            const std::uint64_t steps = handle.totalStats().steps, slept = cloth.sleptSteps();
            const double c0 = threadSeconds();
            world->stepSimulation(games::kFrame);
            const double c1 = threadSeconds();
            r.cpuMs.push_back(1e3 * (c1 - c0));
            ++r.frames;
            // lastLimiterStats() is the last cloth step's; a cloth step taken asleep runs no
            // limiter (and leaves the stats of the last awake step in place).
            const std::uint64_t taken = handle.totalStats().steps - steps;
            r.maxStepsPerFrame = std::max(r.maxStepsPerFrame, taken);
            const std::uint64_t awake = taken - (cloth.sleptSteps() - slept);
            if (awake > 1) r.stepsEstimated = true;
            r.work +=
                static_cast<double>(awake) * static_cast<double>(cloth.lastLimiterStats().work);
            r.peakStrain = std::max(r.peakStrain, cloth.maxStrain());
            if (cloth.isAsleep()) {
                if (r.firstAsleep < 0.0) r.firstAsleep = tEnd;
                if (r.asleepSince < 0.0) r.asleepSince = tEnd;
            } else {
                r.asleepSince = -1.0;
            }
            if (s.afterFrame) s.afterFrame(tEnd);
        }
        r.clothSteps = handle.totalStats().steps - steps0;
        r.sleptSteps = cloth.sleptSteps() - slept0;
        r.capHits = cloth.limiterCapHits() - caps0;
        r.relimitWalks = handle.totalStats().relimitWalks - relimits0;
        if (s.notes) r.notes = s.notes();
    } catch (const drape::Error& e) {
        r.error = std::string("drape::Error (") + toString(e.code()) + "): " + e.what();
    } catch (const std::exception& e) {
        r.error = std::string("exception: ") + e.what();
    }
    r.wallSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
    return r;
}

std::string fmt(const char* f, double v) {
    char buf[64];
    std::snprintf(buf, sizeof buf, f, v);
    return buf;
}

std::string cell(std::string s) {
    for (char& c : s)
        if (c == '|' || c == '\n') c = ' ';
    return s;
}

std::string timeOrNever(double t) {
    return t < 0.0 ? "never" : fmt("%.2f s", t);
}

std::string tables(const std::vector<Row>& rows) {
    std::ostringstream o;
    o << "| scene | particles | springs | frames | wall s | CPU ms/frame median | p99 | max | "
         "mean | limiter work/frame | sweeps/frame | cap hits | peak strain | bound | "
         "peak <= 0.101 | cloth steps/frame mean, max (substeps) | status |\n"
      << "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|---|---|\n";
    for (const Row& r : rows) {
        const double frames = static_cast<double>(std::max<std::size_t>(r.frames, 1));
        const double workPerFrame = r.work / frames;
        const double sweeps = r.springs > 0 ? workPerFrame / static_cast<double>(r.springs) : 0.0;
        std::string framesCell = std::to_string(r.frames);
        if (r.frames != r.plannedFrames) framesCell += " of " + std::to_string(r.plannedFrames);
        o << "| " << r.scene << " | " << r.particles << " | " << r.springs << " | " << framesCell
          << " | " << fmt("%.1f", r.wallSeconds) << " | " << fmt("%.3f", percentile(r.cpuMs, 0.5))
          << " | " << fmt("%.3f", percentile(r.cpuMs, 0.99)) << " | "
          << fmt("%.3f", r.cpuMs.empty() ? 0.0 : *std::max_element(r.cpuMs.begin(), r.cpuMs.end()))
          << " | " << fmt("%.3f", mean(r.cpuMs)) << " | " << fmt("%.0f", workPerFrame)
          << (r.stepsEstimated ? " (est.)" : "") << " | " << fmt("%.2f", sweeps) << " | "
          << r.capHits << " | " << fmt("%.4f", r.peakStrain) << " | " << fmt("%.4f", r.bound)
          << " | " << (r.frames == 0 ? "-" : (r.peakStrain <= 0.101 ? "yes" : "**no**")) << " | "
          << fmt("%.2f", static_cast<double>(r.clothSteps) / frames) << ", " << r.maxStepsPerFrame
          << " (" << r.substeps << ") | " << (r.error.empty() ? "ok" : "**" + cell(r.error) + "**")
          << " |\n";
    }
    o << "\n| scene | cloth mass kg | mean k N/m | stable dt ms | cloth asleep (first / for good) "
         "| steps taken asleep | relimit walks/frame | scene-specific |\n"
      << "|---|---:|---:|---:|---|---:|---:|---|\n";
    for (const Row& r : rows)
        o << "| " << r.scene << " | " << fmt("%.4f", r.mass) << " | " << fmt("%.4g", r.stiffness)
          << " | " << fmt("%.2f", 1e3 * r.stableDt) << " | " << timeOrNever(r.firstAsleep) << " / "
          << timeOrNever(r.asleepSince) << " | " << r.sleptSteps << " | "
          << fmt("%.2f", static_cast<double>(r.relimitWalks) /
                             static_cast<double>(std::max<std::size_t>(r.frames, 1)))
          << " | " << (r.notes.empty() ? "-" : cell(r.notes)) << " |\n";
    return o.str();
}

std::string cpuModel() {
    std::ifstream in("/proc/cpuinfo");
    std::string line;
    while (std::getline(in, line))
        if (line.rfind("model name", 0) == 0) {
            const auto colon = line.find(':');
            if (colon != std::string::npos) return line.substr(colon + 2);
        }
    return "unknown";
}

std::string loadAverage() {
    std::ifstream in("/proc/loadavg");
    std::string one, five, fifteen;
    in >> one >> five >> fifteen;
    return one + " " + five + " " + fifteen;
}

std::string utcNow() {
    const std::time_t now = std::time(nullptr);
    std::tm tm{};
    gmtime_r(&now, &tm);
    char buf[64];
    std::strftime(buf, sizeof buf, "%Y-%m-%d %H:%M:%S UTC", &tm);
    return buf;
}

std::string commandLine(int argc, char** argv) {
    std::string s;
    for (int i = 0; i < argc; ++i) {
        std::string a = argv[i];
        if (a.find_first_of(" \t'\"") != std::string::npos) a = "'" + a + "'";
        s += (i ? " " : "") + a;
    }
    return s;
}

} // namespace

int main(int argc, char** argv) {
    CLI::App app{"drape-bench-games: game scenes in a Bullet world with drape's default settings"};
    std::vector<std::string> names;
    double secondsScale = 1.0;
    long maxFrames = 0;
    std::string out;
    std::string known;
    for (const SceneEntry& e : games::allScenes())
        known += (known.empty() ? "" : ", ") + std::string(e.name);
    app.add_option("--scene", names,
                   "scenes to run (repeatable or comma list; default all): " + known)
        ->delimiter(',');
    app.add_option("--seconds-scale", secondsScale, "scale every scene's duration")
        ->check(CLI::PositiveNumber);
    app.add_option("--max-frames", maxFrames, "at most this many frames per scene (0: no cap)")
        ->check(CLI::NonNegativeNumber);
    app.add_option("--out", out, "also write the tables, with the machine named, to this file");
    CLI11_PARSE(app, argc, argv);

    std::vector<SceneEntry> chosen;
    if (names.empty()) chosen = games::allScenes();
    for (const std::string& n : names) {
        auto it = std::find_if(games::allScenes().begin(), games::allScenes().end(),
                               [&](const SceneEntry& e) { return n == e.name; });
        if (it == games::allScenes().end()) {
            std::cerr << "unknown scene '" << n << "'; scenes: " << known << "\n";
            return 2;
        }
        chosen.push_back(*it);
    }

    const std::string started = utcNow();
    const std::string loadBefore = loadAverage();
    std::vector<Row> rows;
    for (const SceneEntry& e : chosen) {
        rows.push_back(runScene(e, secondsScale, maxFrames));
        const Row& r = rows.back();
        std::fprintf(stderr,
                     "[games] %-15s %4zu frames  wall %6.1f s  CPU ms/frame median %7.3f p99 "
                     "%7.3f max %7.3f  peak strain %.4f  cap hits %llu%s%s\n",
                     r.scene.c_str(), r.frames, r.wallSeconds, percentile(r.cpuMs, 0.5),
                     percentile(r.cpuMs, 0.99),
                     r.cpuMs.empty() ? 0.0 : *std::max_element(r.cpuMs.begin(), r.cpuMs.end()),
                     r.peakStrain, static_cast<unsigned long long>(r.capHits),
                     r.error.empty() ? "" : "  ERROR: ", r.error.c_str());
        if (!r.notes.empty())
            std::fprintf(stderr, "[games] %-15s %s\n", r.scene.c_str(), r.notes.c_str());
    }

    const std::string body = tables(rows);
    std::cout << body;
    if (!out.empty()) {
        const ClothSettings cs;
        const bullet::BulletClothSettings bs;
        std::ofstream f(out);
        f << "# drape-bench-games\n\n"
          << "Game scenes in a btDiscreteDynamicsWorld stepped with stepSimulation(1/60) once "
             "per frame, drape's default ClothSettings and BulletClothSettings "
             "(samples/benchmarks/README.md, \"Game scenes\").\n\n"
          << "- machine: " << cpuModel() << ", " << std::thread::hardware_concurrency()
          << " cores\n"
          << "- date: " << started << " (load average " << loadBefore << " at the start, "
          << loadAverage() << " at the end)\n"
          << "- build type: " << DRAPE_BENCH_BUILD_TYPE << "\n"
          << "- command: `" << commandLine(argc, argv) << "`\n"
          << "- defaults measured: limiter " << toString(cs.limiter.kind) << " maxStrain "
          << cs.limiter.maxStrain << " tolerance " << cs.limiter.tolerance << ", substeps "
          << substepSetting(bs.substeps) << ", contact thickness " << bs.contact.thickness
          << " m, sleep " << (bs.sleep ? "on" : "off") << "\n\n"
          << body;
        if (!f) {
            std::cerr << "could not write " << out << "\n";
            return 1;
        }
    }
    for (const Row& r : rows)
        if (!r.error.empty()) return 1;
    return 0;
}
