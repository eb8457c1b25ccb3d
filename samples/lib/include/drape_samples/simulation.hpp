// drape_samples/simulation.hpp: a running scene: the cloth, its pins and wind, and (with the
// Bullet integration) the rigid bodies it touches, stepped at the scene's fixed time step.
//
// Scene files, the runner, the sample games and the tests all build their worlds here, so
// a scene behaves the same wherever it runs.
#pragma once

#include "drape_samples/render.hpp"
#include "drape_samples/scene.hpp"

#include <drape/cloth.hpp>

#include <map>
#include <memory>
#include <string>
#include <vector>

namespace drape::samples {

/// What the runner writes per frame (one CSV row).
struct FrameStats {
    double time = 0.0;          ///< simulated time [s]
    std::uint64_t steps = 0;    ///< steps taken so far
    double maxStrain = 0.0;     ///< largest spring strain [-]
    double meanStrain = 0.0;    ///< mean spring strain [-]
    double kineticEnergy = 0.0; ///< cloth kinetic energy [J]
    double lowestPoint = 0.0;   ///< lowest particle height along -gravity (y if g = 0) [m]
    std::size_t contacts = 0;   ///< cloth-rigid contacts of the last step
};

/// Pose and drawable of one rigid body, for renderers.
struct BodyView {
    std::string name;
    Eigen::Matrix4f transform = Eigen::Matrix4f::Identity(); ///< local -> world
    const std::vector<DrawMesh>* meshes = nullptr;           ///< in the local frame
};

/// simulation.substeps = "auto" keeps each cloth step at most this fraction of the
/// stability estimate (the estimate is an upper bound on omega_max; the margin covers the
/// contact and damping forces it leaves out).
inline constexpr double kAutoSubstepMargin = 0.9;
/// The cheapest a cloth step gets per particle on one core (Experiment I without a limiter
/// or contacts: 14 us for 1,225 particles on the 2-core Xeon VM, PERF.md) [s]: a lower bound
/// of a run's time.
inline constexpr double kLeastSecondsPerParticleStep = 1e-8;
/// The automatic sub-steps are said to be set by a few particles when the rest of the cloth
/// (all but the 1 % of its free particles with the highest own bounds,
/// drape::localAngularFrequencies) would take 1 / kStiffSpotRatio of them or fewer.
inline constexpr double kStiffSpotRatio = 1.25;
/// A run whose lower bound (particles x steps x sub-steps x kLeastSecondsPerParticleStep)
/// exceeds this gets a warning before it starts [s].
inline constexpr double kLongRunSeconds = 3600.0;

/// Whether this build can run scenes with rigid bodies (drape::bullet was available).
bool rigidBodiesAvailable();

class Simulation {
  public:
    /// Builds everything the scene describes. Throws SceneError naming the scene file and
    /// the field at fault (also for errors the core reports, such as a degenerate triangle).
    explicit Simulation(const SceneDesc& scene);
    ~Simulation();
    Simulation(const Simulation&) = delete;
    Simulation& operator=(const Simulation&) = delete;

    /// Advances the whole scene by the scene's time step. Throws SceneError on a failed step.
    void step();

    const SceneDesc& scene() const { return scene_; }
    Cloth& cloth() { return *cloth_; }
    const Cloth& cloth() const { return *cloth_; }
    double time() const;
    std::uint64_t steps() const { return steps_; }
    /// Cloth steps per scene step (simulation.substeps, or what "auto" chose: the fewest
    /// that keep each at most kAutoSubstepMargin of the cloth's stable time step).
    int substeps() const { return scene_.substeps; }

    /// Particles each pin and attachment entry selected (resolved from the scene).
    const std::vector<std::vector<Index>>& pinnedParticles() const { return pinSets_; }
    const std::vector<std::vector<Index>>& attachedParticles() const { return attachSets_; }

    /// The statistics of the current state. Throws StepError (naming the value, the step and
    /// the time) when a statistic is not finite, a velocity is not finite or a particle lies
    /// beyond single-precision range: nothing a run writes can then be inf or nan.
    FrameStats stats() const;
    std::size_t contactCount() const;

    /// Everything to draw this frame: the cloth and every rigid body.
    std::vector<DrawMesh> drawMeshes() const;

    /// The cloth as a mesh in particle order (for export).
    TriangleMesh clothMesh() const;

    /// Rigid bodies (empty without the Bullet integration).
    std::vector<BodyView> bodies() const;
    /// Position [m] and linear velocity [m/s] of the rigid body called `name`.
    /// Throws SceneError if there is no such body.
    Vec3 bodyPosition(const std::string& name) const;
    Vec3 bodyVelocity(const std::string& name) const;
    /// Places a dynamic body and gives it a velocity (a throw). Throws if not dynamic.
    void launchBody(const std::string& name, const Vec3& position, const Vec3& velocity);

    /// Per-phase timing of the cloth (see drape::PhaseTimers).
    const PhaseTimers& timers() const { return cloth_->timers(); }

    /// What building the scene noticed but did not refuse (mesh files: dropped degenerate
    /// triangles, files a mesh names that were not opened...), one sentence each.
    const std::vector<std::string>& warnings() const { return warnings_; }

    /// A one-line name of what runs besides the cloth (e.g. "bullet: 2 bodies").
    std::string worldDescription() const;

    struct RigidWorld; ///< implemented with drape::bullet

  private:
    [[noreturn]] void fail(const std::string& path, const std::string& what) const;
    [[noreturn]] void overflow(const std::string& what) const;
    void chooseSubsteps();
    void warnLongRun(); ///< a warning when the run cannot take under kLongRunSeconds
    /// A warning when a few particles set the automatic sub-steps (kStiffSpotRatio).
    void warnStiffSpot();
    std::vector<Index> resolve(const ParticleSelector& sel,
                               const std::vector<Index>& vertexToParticle,
                               const std::map<std::string, std::vector<Index>>& groups) const;
    void applyWind();

    SceneDesc scene_;
    std::unique_ptr<Cloth> cloth_;
    std::vector<std::vector<Index>> pinSets_;
    std::vector<std::vector<Index>> attachSets_;
    std::unique_ptr<RigidWorld> world_;
    std::vector<std::vector<DrawMesh>> bodyMeshes_;
    std::uint64_t steps_ = 0;
    Vec3 up_ = Vec3::UnitY();
    std::vector<std::string> warnings_;
};

} // namespace drape::samples
