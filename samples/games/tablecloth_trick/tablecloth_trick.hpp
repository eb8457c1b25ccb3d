// tablecloth_trick: the second headless sample game. A table is laid with a cloth and dishes;
// a scripted player yanks the cloth by its near edge and scores the dishes left standing on
// the table. Only real two-way friction coupling between cloth and bodies gives the two
// outcomes of the trick: a fast yank slides the cloth out under the dishes (kinetic friction
// acts only briefly, so they barely move), a slow one drags them along (static friction holds)
// and off the table's edge.
//
// The game is a library (this header) so tests/samples can play it and check the outcomes;
// main.cpp is its command line.
#pragma once

#include "drape_samples/game.hpp"
#include "drape_samples/scene.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <optional>
#include <string>
#include <vector>

namespace drape::samples::tablecloth {

enum class YankKind { Fast, Slow };
const char* toString(YankKind kind);

/// The player's hand: the handle particles (the scene's pins[0]) move by displacement(t) along
/// `direction`: at rest until `startTime`, uniformly accelerated to `speed` over `rampTime`,
/// then at `speed` until they have moved `distance`; then the hand stops and holds.
struct Yank {
    double startTime = 0.3;              ///< [s]
    double speed = 1.0;                  ///< top speed [m/s]
    double rampTime = 0.1;               ///< time to reach it [s]
    double distance = 1.0;               ///< how far the hand pulls [m]
    Vec3 direction = Vec3::UnitZ();      ///< unit; toward the player, a little down
    double displacement(double t) const; ///< [m] along direction
    double endTime() const;              ///< when the hand stops [s]
};

/// The yank a player makes: fast (a few m/s reached in a few hundredths of a second) or slow
/// (a fraction of a m/s); the seeded player varies start, speed and downward slope a little.
Yank scriptYank(YankKind kind, ScriptedPlayer& player);

/// The table top, read from the scene's static box called "table_top" (not rotated).
struct TableTop {
    double top = 0.0;                              ///< height of its upper face [m]
    Eigen::Vector2d min = Eigen::Vector2d::Zero(); ///< (x, z) corner [m]
    Eigen::Vector2d max = Eigen::Vector2d::Zero(); ///< (x, z) corner [m]
    bool over(const Vec3& p) const {
        return p.x() > min.x() && p.x() < max.x() && p.z() > min.y() && p.z() < max.y();
    }
};

/// How deep point p lies inside the box of `halfExtents` posed by `pose` (local -> world):
/// the distance to its nearest face for a point inside, 0 or less outside [m].
double depthInsideBox(const Vec3& p, const Vec3& halfExtents, const Eigen::Matrix4d& pose);

/// Outcome for one dish.
struct DishReport {
    std::string name;
    Vec3 start = Vec3::Zero();    ///< centre when the yank starts [m]
    Vec3 end = Vec3::Zero();      ///< centre at the end of the round [m]
    double maxDisplacement = 0.0; ///< largest distance from `start` during the round [m]
    double endTiltDeg = 0.0;      ///< angle of its up axis to the vertical at the end
    bool standing = false;        ///< upright on the table top at the end: it scores
};

/// The scripted player's seed unless the command line gives one.
inline constexpr std::uint64_t kDefaultSeed = 1;

struct RoundOptions {
    YankKind kind = YankKind::Fast;
    std::uint64_t seed = kDefaultSeed;
    double settleAfterYank = 0.7; ///< [s] of play after the hand stops
    /// Frames (PNG) go here when set, at the scene's output.fps.
    std::optional<std::filesystem::path> frames;
    int width = 640, height = 480; ///< frame size [px]
    /// Event rows (round,time_s,event,dish,detail) are written here when set.
    std::ostream* events = nullptr;
};

struct RoundResult {
    YankKind kind = YankKind::Fast;
    Yank yank;
    std::vector<DishReport> dishes;
    int standing = 0; ///< the score
    /// Over every step, every dish and those of its corners that are over the table top: the
    /// least height above the top [m] (negative: the dish sank into the table).
    double minTableClearance = 1e300;
    /// Over every step, every dish and every cloth particle: the largest depth of a particle
    /// inside a dish [m] (positive: the dish went through the cloth there).
    double maxClothDepth = -1e300;
    std::size_t steps = 0;
    std::size_t frames = 0;
    double seconds = 0.0;  ///< simulated
    int clothSubsteps = 1; ///< cloth steps per scene step
};

/// Plays one round in the scene's world (built anew). Throws SceneError on a scene that is not a
/// tablecloth-trick world (no "table_top" box, no handle pin, a dish that is not a box...) and
/// on a failed step.
RoundResult playRound(const SceneDesc& scene, const RoundOptions& options);

/// The header of the events CSV.
inline constexpr const char* kEventsHeader = "round,time_s,event,dish,detail";

} // namespace drape::samples::tablecloth
