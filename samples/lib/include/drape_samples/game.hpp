// drape_samples/game.hpp: pieces the headless sample games share (samples/games/): a seeded
// stand-in for the player and the fixed-time-step loop that turns rendered frames into
// physics steps of exactly the scene's time step.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>

namespace drape::samples {

/// Deterministic stand-in for a player (a 64-bit linear congruential generator): every run
/// with the same seed plays the same game.
class ScriptedPlayer {
  public:
    explicit ScriptedPlayer(std::uint64_t seed)
        : state_(seed * 2862933555777941757ull + 3037000493ull) {}
    /// A number drawn uniformly from [lo, hi).
    double uniform(double lo, double hi) {
        state_ = state_ * 6364136223846793005ull + 1442695040888963407ull;
        const double u = static_cast<double>(state_ >> 11) / 9007199254740992.0; // [0, 1)
        return lo + (hi - lo) * u;
    }

  private:
    std::uint64_t state_;
};

/// "Fix your time step": each rendered frame adds 1/fps of simulated time to an accumulator,
/// which is spent in physics steps of exactly `stepDt`, so results never depend on the frame
/// rate. A frame adds at most kMaxFrameTime (the usual guard against a frame that owes more
/// steps than it can take: with fps = 1e-6 the first frame would owe 1e6 s of steps); longer
/// frames are cut to it, so the game's clock falls behind the frames', never the physics.
///
///   FixedStepLoop loop(scene.timeStep, 1.0 / scene.output.fps);
///   for (;;) { loop.beginFrame(); while (loop.nextStep()) sim.step(); render(); }
class FixedStepLoop {
  public:
    /// The most simulated time one frame adds [s].
    static constexpr double kMaxFrameTime = 0.25;
    /// Throws std::invalid_argument unless both are positive and finite.
    FixedStepLoop(double stepDt, double frameDt);
    /// Starts a frame: adds its duration (at most kMaxFrameTime) to the accumulator.
    void beginFrame() { accumulator_ += frameDt_ < kMaxFrameTime ? frameDt_ : kMaxFrameTime; }
    /// Whether another step of this frame is due (and takes it from the accumulator).
    bool nextStep() {
        if (accumulator_ < stepDt_) return false;
        accumulator_ -= stepDt_;
        return true;
    }
    double stepDt() const { return stepDt_; }
    double frameDt() const { return frameDt_; }

  private:
    double stepDt_;
    double frameDt_;
    double accumulator_ = 0.0;
};

/// Path of frame `index` in `folder`: folder/frame_NNNNN.png (as drape-run names them).
std::filesystem::path framePath(const std::filesystem::path& folder, std::size_t index);

} // namespace drape::samples
