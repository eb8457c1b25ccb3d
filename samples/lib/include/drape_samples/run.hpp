// drape_samples/run.hpp: running a scene headless and writing its outputs (what drape-run
// does): PNG frames, the final cloth as OBJ, a CSV of per-frame statistics, a summary and,
// when ffmpeg is installed, an MP4 of the frames.
#pragma once

#include "drape_samples/scene.hpp"

#include <cstdint>
#include <filesystem>
#include <functional>
#include <iosfwd>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace drape::samples {

/// Command-line overrides of the scene.
struct RunOptions {
    std::filesystem::path scene;
    std::filesystem::path outDir;
    std::optional<std::size_t> steps; ///< run this many steps instead of the duration
    std::optional<double> seconds;    ///< run this long [s] instead of the duration
    std::optional<std::string> integrator;
    std::optional<double> timeStep;   ///< [s]
    std::optional<double> fps;        ///< frames per simulated second
    std::optional<int> width, height; ///< image size [px]
    bool render = true;               ///< PNG frames (and the MP4)
    bool video = true;                ///< MP4 through ffmpeg when it is on the PATH
    bool progress = false;            ///< progress bar on stderr
    /// Called once per warning, as soon as the scene is built (before the first step).
    std::function<void(const std::string&)> warn;
};

/// What a run did, for the summary.
struct RunResult {
    std::size_t steps = 0;
    std::size_t frames = 0;
    double simulatedSeconds = 0.0;
    double wallSeconds = 0.0;     ///< whole run, rendering included
    double stepWallSeconds = 0.0; ///< time spent stepping only
    double renderWallSeconds = 0.0;
    double finalMaxStrain = 0.0;
    double peakMaxStrain = 0.0; ///< largest strain over the frames
    /// Largest strain after any step, the time it was seen [s], and the steps that ended
    /// beyond the strain limiter's bound (max strain + tolerance; 0 without a limiter).
    double peakStepStrain = 0.0;
    double peakStepTime = 0.0;
    std::pair<Index, Index> peakStepSpring{0, 0}; ///< the most stretched spring then
    Vec3 peakStepWhere = Vec3::Zero();            ///< its midpoint then [m]
    std::size_t stepsOverBound = 0;
    std::size_t particles = 0;
    std::size_t springs = 0;
    std::string video;                 ///< path of the MP4, or why there is none
    std::vector<std::string> warnings; ///< Simulation::warnings() of the run
    /// drape::stateHash of the final cloth state: equal for two runs of the same scene with
    /// the same build (and any thread count), printed in the summary.
    std::uint64_t stateHash = 0;
};

/// Applies the overrides to a loaded scene (throws SceneError on impossible values).
void applyOverrides(SceneDesc& scene, const RunOptions& options);

/// Loads, runs and writes everything. Messages go to `log`; warnings (what the scene's meshes
/// had that was dropped or not read) go to options.warn, or to `log` as "warning: ..." lines
/// without it, and into summary.txt. Throws SceneError on any error.
RunResult runScene(const RunOptions& options, std::ostream& log);

} // namespace drape::samples
