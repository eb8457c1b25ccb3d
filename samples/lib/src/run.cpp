// run.cpp: the headless run loop behind drape-run.
#include "drape_samples/run.hpp"

#include "drape/snapshot.hpp"

#include "drape_samples/check.hpp"
#include "drape_samples/mesh_io.hpp"
#include "drape_samples/render.hpp"
#include "drape_samples/simulation.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iomanip>
#include <memory>
#include <ostream>
#include <sstream>

namespace drape::samples {

namespace {

using Clock = std::chrono::steady_clock;

std::string num(double x) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%g", x);
    return buf;
}

double seconds(Clock::time_point a, Clock::time_point b) {
    return std::chrono::duration<double>(b - a).count();
}

/// Finds an executable on the PATH without running a shell.
bool onPath(const std::string& program) {
    const char* path = std::getenv("PATH");
    if (!path) return false;
    std::stringstream ss(path);
    std::string dir;
    while (std::getline(ss, dir, ':')) {
        if (dir.empty()) continue;
        std::error_code ec;
        const auto p = std::filesystem::path(dir) / program;
        if (std::filesystem::is_regular_file(p, ec)) return true;
    }
    return false;
}

class Progress {
  public:
    Progress(bool on, std::size_t total) : on_(on), total_(total), last_(Clock::now()) {}
    void update(std::size_t done, double t, bool force = false) {
        if (!on_) return;
        const auto now = Clock::now();
        if (!force && seconds(last_, now) < 0.1) return;
        last_ = now;
        const int width = 30;
        const double frac = total_ ? static_cast<double>(done) / static_cast<double>(total_) : 1.0;
        const int fill = static_cast<int>(frac * width);
        std::fprintf(stderr, "\r[%s%s] %3d%%  step %zu/%zu  t = %.2f s",
                     std::string(static_cast<std::size_t>(fill), '#').c_str(),
                     std::string(static_cast<std::size_t>(width - fill), ' ').c_str(),
                     static_cast<int>(frac * 100.0), done, total_, t);
        std::fflush(stderr);
    }
    void finish() {
        if (on_) std::fprintf(stderr, "\n");
    }

  private:
    bool on_;
    std::size_t total_;
    Clock::time_point last_;
};

} // namespace

void applyOverrides(SceneDesc& scene, const RunOptions& o) {
    const std::string org = scene.sourceFile.string();
    if (o.integrator) {
        try {
            scene.cloth.integrator = integratorFromString(*o.integrator);
        } catch (const std::exception& e) {
            throw SceneError("--integrator: " + std::string(e.what()));
        }
    }
    if (o.timeStep) {
        if (!(*o.timeStep > 0.0) || !std::isfinite(*o.timeStep))
            throw SceneError("--dt: the time step must be a positive number of seconds");
        if (!(*o.timeStep >= kMinTimeStep && *o.timeStep <= kMaxTimeStep))
            throw SceneError("--dt: must be in [1e-09, 10] s, got " + num(*o.timeStep));
        scene.timeStep = *o.timeStep;
    }
    if (o.steps && o.seconds) throw SceneError("--steps and --seconds: give one, not both");
    if (o.steps) {
        if (*o.steps == 0 || *o.steps > kMaxSceneSteps)
            throw SceneError("--steps: must be in [1, " + std::to_string(kMaxSceneSteps) + "]");
        scene.duration = static_cast<double>(*o.steps) * scene.timeStep;
    }
    if (o.seconds) {
        if (!(*o.seconds > 0.0) || !std::isfinite(*o.seconds))
            throw SceneError("--seconds: must be a positive number of seconds");
        if (*o.seconds > kMaxDuration)
            throw SceneError("--seconds: must be in (0, 1e+06] s, got " + num(*o.seconds));
        scene.duration = *o.seconds;
    }
    if (scene.duration / scene.timeStep > static_cast<double>(kMaxSceneSteps))
        throw SceneError(org + ": the run would take more than " + std::to_string(kMaxSceneSteps) +
                         " steps");
    if (scene.stepCount() == 0) throw SceneError(org + ": the run is shorter than one time step");
    if (o.fps) {
        if (!(*o.fps > 0.0) || !std::isfinite(*o.fps)) throw SceneError("--fps: must be positive");
        if (!(*o.fps >= kMinFps && *o.fps <= kMaxFps))
            throw SceneError("--fps: must be in [1e-06, 1e+06] 1/s, got " + num(*o.fps));
        scene.output.fps = *o.fps;
    }
    if (scene.output.fps * scene.duration > static_cast<double>(kMaxSceneFrames)) {
        // Name what set each (review 16: the file's fields were named when --fps and
        // --seconds had set them), and the frames asked for.
        const std::string fps = o.fps ? "--fps" : "output.fps";
        const std::string length = o.seconds ? "--seconds"
                                   : o.steps ? "--steps"
                                             : "simulation.duration";
        char frames[64];
        std::snprintf(frames, sizeof frames, "%.12g", scene.output.fps * scene.duration);
        throw SceneError(org + ": the run would write " + frames + " frames (" +
                         num(scene.output.fps) + " a second for " + num(scene.duration) +
                         " s), more than " + std::to_string(kMaxSceneFrames) + ": lower " + fps +
                         " or " + length);
    }
    if (o.width) {
        if (*o.width < 16 || *o.width > kMaxImageSide)
            throw SceneError("--width: must be in [16, 8192]");
        scene.camera.width = *o.width;
    }
    if (o.height) {
        if (*o.height < 16 || *o.height > kMaxImageSide)
            throw SceneError("--height: must be in [16, 8192]");
        scene.camera.height = *o.height;
    }
}

RunResult runScene(const RunOptions& options, std::ostream& log) {
    const auto start = Clock::now();
    SceneDesc scene = loadScene(options.scene);
    applyOverrides(scene, options);
    const bool render = options.render && scene.output.png;
    if (render && !renderingAvailable())
        throw SceneError("this build has no renderer (configure with -DDRAPE_WITH_RENDERING=ON) "
                         "or pass --no-render");

    std::error_code ec;
    std::filesystem::create_directories(options.outDir, ec);
    if (ec || !std::filesystem::is_directory(options.outDir))
        throw SceneError(options.outDir.string() + ": cannot create the output folder" +
                         (ec ? ": " + ec.message() : std::string()));
    const auto framesDir = options.outDir / "frames";
    if (render) {
        std::filesystem::create_directories(framesDir, ec);
        if (ec) throw SceneError(framesDir.string() + ": cannot create: " + ec.message());
        // Frames of an earlier, longer run would otherwise end up in the video.
        for (const auto& entry : std::filesystem::directory_iterator(framesDir, ec))
            if (entry.path().extension() == ".png") std::filesystem::remove(entry.path(), ec);
    }

    Simulation sim(scene);
    const Cloth& cloth = sim.cloth();
    RunResult r;
    r.warnings = sim.warnings();
    for (const std::string& w : r.warnings) {
        if (options.warn)
            options.warn(w);
        else
            log << "warning: " << w << "\n";
    }
    r.particles = cloth.particleCount();
    r.springs = cloth.topology().springCount();
    log << "scene    " << scene.name << (scene.description.empty() ? "" : ": " + scene.description)
        << "\n"
        << "cloth    " << r.particles << " particles, " << r.springs << " springs, "
        << cloth.topology().triangleCount() << " triangles; " << sim.worldDescription() << "\n"
        << "pipeline";
    for (const auto& phase : cloth.pipeline())
        log << " " << phase;
    log << "\n"
        << "run      " << toString(scene.cloth.integrator) << ", dt " << scene.timeStep << " s, "
        << scene.stepCount() << " steps (" << scene.duration << " s)"
        << ", stable dt limit " << springsTimeStep(cloth, scene.cloth.integrator) << " s";
    if (sim.substeps() > 1 || scene.autoSubsteps)
        log << ", " << sim.substeps() << " cloth sub-step" << (sim.substeps() == 1 ? "" : "s")
            << " per step" << (scene.autoSubsteps ? " (auto)" : "");
    log << std::endl; // what the run will do, shown before it starts even when redirected

    std::unique_ptr<OffscreenRenderer> renderer;
    if (render)
        renderer = std::make_unique<OffscreenRenderer>(scene.camera.width, scene.camera.height);

    std::ofstream csv;
    if (scene.output.csv) {
        csv.open(options.outDir / "stats.csv");
        if (!csv) throw SceneError((options.outDir / "stats.csv").string() + ": cannot write");
        csv << "frame,time_s,steps,max_strain,mean_strain,kinetic_energy_J,lowest_point_m,contacts,"
               "wall_ms_per_step\n";
        csv << std::setprecision(9);
    }

    const std::size_t totalSteps = scene.stepCount();
    const double frameInterval = 1.0 / scene.output.fps;
    Progress progress(options.progress, totalSteps);
    double stepWallSinceFrame = 0.0;
    std::size_t stepsSinceFrame = 0;
    double nextFrameTime = 0.0;

    auto emitFrame = [&]() {
        const FrameStats s = sim.stats();
        r.peakMaxStrain = std::max(r.peakMaxStrain, s.maxStrain);
        if (csv.is_open()) {
            const double ms =
                stepsSinceFrame ? 1000.0 * stepWallSinceFrame / static_cast<double>(stepsSinceFrame)
                                : 0.0;
            // In SI whatever the scene's length unit (units_per_metre u: energies over u^2).
            const double u = scene.unitsPerMetre;
            csv << r.frames << ',' << s.time << ',' << s.steps << ',' << s.maxStrain << ','
                << s.meanStrain << ',' << s.kineticEnergy / (u * u) << ',' << s.lowestPoint / u
                << ',' << s.contacts << ',' << ms << '\n';
        }
        if (renderer) {
            const auto t0 = Clock::now();
            const Image img =
                renderer->render(scene.camera, sim.drawMeshes(), scene.output.background);
            char name[32];
            std::snprintf(name, sizeof name, "frame_%05zu.png", r.frames);
            writePng(framesDir / name, img);
            r.renderWallSeconds += seconds(t0, Clock::now());
        }
        ++r.frames;
        stepWallSinceFrame = 0.0;
        stepsSinceFrame = 0;
        nextFrameTime = static_cast<double>(r.frames) * frameInterval;
    };

    const bool limited = scene.cloth.limiter.kind != LimiterKind::None;
    const double bound = scene.cloth.limiter.maxStrain + scene.cloth.limiter.tolerance + 1e-12;
    emitFrame();
    for (std::size_t k = 0; k < totalSteps; ++k) {
        const auto t0 = Clock::now();
        sim.step();
        const double w = seconds(t0, Clock::now());
        // The bound is checked after every step, not only at frames (outside the timing).
        const double strain = cloth.maxStrain();
        if (strain > r.peakStepStrain || k == 0) {
            r.peakStepStrain = strain;
            r.peakStepTime = sim.time();
            // Where: the most stretched spring (looked for again only when the peak rises).
            const auto& x = cloth.positions();
            double worst = -1.0;
            for (const Spring& sp : cloth.topology().springs()) {
                const double e = (x[sp.b] - x[sp.a]).norm() / sp.restLength - 1.0;
                if (e > worst) {
                    worst = e;
                    r.peakStepSpring = {sp.a, sp.b};
                    r.peakStepWhere = 0.5 * (x[sp.a] + x[sp.b]);
                }
            }
        }
        if (limited && strain > bound) ++r.stepsOverBound;
        r.stepWallSeconds += w;
        stepWallSinceFrame += w;
        ++stepsSinceFrame;
        // Half a step of slack so that rounding never skips or doubles a frame.
        if (sim.time() + 0.5 * scene.timeStep >= nextFrameTime || k + 1 == totalSteps) emitFrame();
        progress.update(k + 1, sim.time());
    }
    progress.update(totalSteps, sim.time(), true);
    progress.finish();
    r.steps = totalSteps;
    r.simulatedSeconds = sim.time();
    r.finalMaxStrain = cloth.maxStrain();
    if (csv.is_open()) {
        csv.close();
        if (!csv) throw SceneError((options.outDir / "stats.csv").string() + ": write failed");
    }

    const bool writeObj = scene.output.obj && meshIoAvailable();
    (void)sim.stats(); // the final state (throws StepError if anything is non-finite)
    if (writeObj) exportMesh(sim.clothMesh(), options.outDir / "cloth_final.obj");

    if (render && options.video && scene.output.video) {
        if (!onPath("ffmpeg")) {
            r.video = "none (ffmpeg is not installed)";
        } else {
            const auto mp4 = options.outDir / "frames.mp4";
            std::ostringstream cmd;
            // Paths are quoted for the shell; scene-controlled text never reaches the command.
            cmd << "ffmpeg -y -loglevel error -framerate "
                << std::max(1.0, std::round(scene.output.fps)) << " -i '"
                << (framesDir / "frame_%05d.png").string() << "' -pix_fmt yuv420p "
                << "-vf 'scale=trunc(iw/2)*2:trunc(ih/2)*2' '" << mp4.string() << "'";
            const int rc = std::system(cmd.str().c_str());
            r.video = rc == 0 ? mp4.string()
                              : "none (ffmpeg failed with status " + std::to_string(rc) + ")";
        }
    } else {
        r.video = "none (rendering or video off)";
    }
    r.wallSeconds = seconds(start, Clock::now());
    r.stateHash = drape::stateHash(cloth);

    // The summary's numbers: the state was checked at the last frame, these are checked
    // again here so that no inf or nan reaches summary.txt whatever their source.
    const double meanStepMs = 1000.0 * r.stepWallSeconds / static_cast<double>(r.steps);
    const double realTimeFactor = r.simulatedSeconds / std::max(r.stepWallSeconds, 1e-12);
    const double finalEnergy = // [J], whatever the scene's length unit
        cloth.kineticEnergy() / (scene.unitsPerMetre * scene.unitsPerMetre);
    const std::pair<const char*, double> summaryValues[] = {
        {"the simulated time", r.simulatedSeconds},
        {"the largest strain (final)", r.finalMaxStrain},
        {"the largest strain (peak)", r.peakMaxStrain},
        {"the final kinetic energy", finalEnergy},
        {"the mean step time", meanStepMs},
        {"the real-time factor", realTimeFactor}};
    for (const auto& [name, value] : summaryValues)
        if (!std::isfinite(value))
            throw StepError(scene.sourceFile.string() + ": " + name + " is " +
                            std::to_string(value) +
                            "; the simulation overflowed, and nothing non-finite is written");

    // The bound's line: measured after every step, so a broken bound is never reported as held.
    std::string boundLine = "none (no strain limiter)";
    if (scene.cloth.limiter.kind != LimiterKind::None) {
        const double promise = scene.cloth.limiter.maxStrain + scene.cloth.limiter.tolerance;
        std::ostringstream b;
        b << std::setprecision(6) << promise << " (max strain + tolerance): ";
        if (r.stepsOverBound == 0)
            b << "held after every step";
        else
            b << "BROKEN after " << r.stepsOverBound << " of " << totalSteps << " steps (peak "
              << r.peakStepStrain << " at t = " << r.peakStepTime << " s, spring "
              << r.peakStepSpring.first << "-" << r.peakStepSpring.second << " at ("
              << r.peakStepWhere.x() << ", " << r.peakStepWhere.y() << ", " << r.peakStepWhere.z()
              << "))";
        boundLine = b.str();
    }
    std::ostringstream sum;
    sum << std::setprecision(6);
    sum << "scene               " << scene.name << "\n"
        << "scene file          " << scene.sourceFile.string() << "\n"
        << "particles           " << r.particles << "\n"
        << "springs             " << r.springs << "\n"
        << "world               " << sim.worldDescription() << "\n"
        << "integrator          " << toString(scene.cloth.integrator) << "\n"
        << "strain limiter      " << toString(scene.cloth.limiter.kind);
    if (scene.cloth.limiter.kind != LimiterKind::None)
        sum << " (max strain " << scene.cloth.limiter.maxStrain << ")";
    sum << "\n"
        << "time step           " << scene.timeStep << " s\n"
        << "cloth sub-steps     " << sim.substeps() << " per step"
        << (scene.autoSubsteps ? " (auto, from the stable limit " : " (stable limit ")
        << springsTimeStep(cloth, scene.cloth.integrator) << " s)\n"
        << "steps               " << r.steps << "\n"
        << "simulated time      " << r.simulatedSeconds << " s\n"
        << "wall time           " << r.wallSeconds << " s (stepping " << r.stepWallSeconds
        << " s, rendering " << r.renderWallSeconds << " s)\n"
        << "mean step           " << meanStepMs << " ms\n"
        << "real-time factor    " << realTimeFactor << "x (stepping only)\n"
        << "max strain (final)  " << r.finalMaxStrain << "\n"
        << "max strain (peak)   " << r.peakStepStrain
        << " (after any step, at t = " << r.peakStepTime << " s)\n"
        << "strain bound        " << boundLine << "\n"
        << "limiter cap hits    " << cloth.limiterCapHits()
        << (cloth.limiterCapHits() == 0 ? std::string(" (the limiter finished every step)")
                                        : " steps stopped at the safety cap (limiter.maxRounds = " +
                                              std::to_string(cloth.settings().limiter.maxRounds) +
                                              ") or early because held particles were farther "
                                              "apart than the springs between them reach: the "
                                              "strain bound was not promised in them")
        << "\n"
        << "kinetic energy      " << finalEnergy << " J (final)\n"
        << "state hash          " <<
        [&] {
            char buf[32];
            std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(r.stateHash));
            return std::string(buf);
        }()
        << " (drape::stateHash of the final state)\n"
        << "frames              " << r.frames
        << (render ? " PNG in " + framesDir.string() : std::string(" (not rendered)")) << "\n"
        << "video               " << r.video << "\n";
    if (writeObj)
        sum << "final mesh          " << (options.outDir / "cloth_final.obj").string() << "\n";
    else if (scene.output.obj)
        sum << "final mesh          none (built without assimp)\n";
    if (scene.output.csv)
        sum << "statistics          " << (options.outDir / "stats.csv").string() << "\n";
    for (const std::string& w : r.warnings)
        sum << "warning             " << w << "\n";
    sum << "phases (wall time):\n";
    for (const auto& t : cloth.timers().all())
        if (t.calls)
            sum << "  " << std::left << std::setw(24) << t.name << " " << std::right << t.calls
                << " calls, " << t.seconds << " s\n";
    std::ofstream sf(options.outDir / "summary.txt");
    sf << sum.str();
    if (!sf) throw SceneError((options.outDir / "summary.txt").string() + ": cannot write");
    log << sum.str();
    return r;
}

} // namespace drape::samples
