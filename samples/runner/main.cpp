// drape-run: runs a drape scene file headless.
//
//   drape-run SCENE.json -o OUT [--steps N | --seconds S] [--integrator NAME] [--dt DT]
//             [--fps F] [--width W] [--height H] [--no-render] [--no-video] [--quiet]
//
// Writes OUT/frames/frame_NNNNN.png, OUT/cloth_final.obj, OUT/stats.csv, OUT/summary.txt
// and OUT/frames.mp4 (with ffmpeg). Exit codes: 0 done, 1 bad scene, mesh or option,
// 2 bad command line (CLI11), 3 the simulation failed.
#include "drape_samples/run.hpp"

#include <CLI/CLI.hpp>

#include <iostream>
#include <sstream>
#include <unistd.h>

int main(int argc, char** argv) {
    using namespace drape::samples;
    CLI::App app{"drape-run: runs a drape cloth scene headless and writes rendered frames, the "
                 "final mesh (OBJ), per-frame statistics (CSV) and a summary"};
    RunOptions o;
    std::string scene, out;
    std::size_t steps = 0;
    double secs = 0.0, dt = 0.0, fps = 0.0;
    int width = 0, height = 0;
    std::string integrator;
    bool noRender = false, noVideo = false, quiet = false;
    app.add_option("scene", scene, "Scene file (JSON, see samples/SCENES.md)")->required();
    app.add_option("-o,--out", out, "Output folder (created if missing)")->required();
    auto* optSteps = app.add_option("--steps", steps,
                                    "Run this many time steps instead of the scene's duration");
    auto* optSecs = app.add_option(
        "--seconds", secs, "Run this many simulated seconds instead of the scene's duration");
    optSteps->excludes(optSecs);
    auto* optInt =
        app.add_option("--integrator", integrator,
                       "velocity_verlet, explicit_euler, symplectic_euler, rk4 or implicit_euler");
    auto* optDt = app.add_option("--dt", dt, "Time step [s]");
    auto* optFps = app.add_option("--fps", fps, "Frames (and CSV rows) per simulated second");
    auto* optW = app.add_option("--width", width, "Image width [px]");
    auto* optH = app.add_option("--height", height, "Image height [px]");
    app.add_flag("--no-render", noRender, "Do not render PNG frames (nor the video)");
    app.add_flag("--no-video", noVideo, "Do not make an MP4 even if ffmpeg is installed");
    app.add_flag("-q,--quiet", quiet, "No progress bar and no summary on stdout");
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        return app.exit(e) == 0 ? 0 : 2;
    }
    o.scene = scene;
    o.outDir = out;
    if (*optSteps) o.steps = steps;
    if (*optSecs) o.seconds = secs;
    if (*optInt) o.integrator = integrator;
    if (*optDt) o.timeStep = dt;
    if (*optFps) o.fps = fps;
    if (*optW) o.width = width;
    if (*optH) o.height = height;
    o.render = !noRender;
    o.video = !noVideo;
    o.progress = !quiet && isatty(STDERR_FILENO);
    // Warnings go to stderr even with --quiet: they say what of the input was not used.
    o.warn = [](const std::string& w) { std::cerr << "drape-run: warning: " << w << "\n"; };

    std::ostringstream sink;
    std::ostream& log = quiet ? static_cast<std::ostream&>(sink) : std::cout;
    try {
        runScene(o, log);
    } catch (const StepError& e) {
        std::cerr << "drape-run: error: " << e.what() << "\n";
        return 3;
    } catch (const SceneError& e) {
        std::cerr << "drape-run: error: " << e.what() << "\n";
        return 1;
    } catch (const std::exception& e) {
        std::cerr << "drape-run: error: " << e.what() << "\n";
        return 1;
    }
    return 0;
}
