// tablecloth_trick: the game's rules, its scripted player and its checks (see the header).
#include "tablecloth_trick.hpp"

#include "drape_samples/render.hpp"
#include "drape_samples/simulation.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <ostream>

namespace drape::samples::tablecloth {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kStandingTiltDeg = 15.0; ///< a dish tilted more is not standing
constexpr double kTippedTiltDeg = 30.0;   ///< "tipped" event
constexpr double kFellDrop = 0.1;         ///< centre this far below the top: "fell" [m]
constexpr double kAfterAllFell = 0.3;     ///< [s] a round goes on once every dish has fallen

std::string origin(const SceneDesc& s) {
    return s.sourceFile.empty() ? std::string("scene") : s.sourceFile.string();
}

[[noreturn]] void refuse(const SceneDesc& s, const std::string& what) {
    throw SceneError(origin(s) + ": not a tablecloth_trick world: " + what);
}

TableTop findTable(const SceneDesc& scene) {
    for (const RigidBodyDesc& b : scene.rigidBodies) {
        if (b.name != "table_top") continue;
        if (b.shape.kind != ShapeKind::Box || b.motion != MotionKind::Static ||
            !b.rotationDeg.isZero())
            refuse(scene, b.path + " (\"table_top\") must be a static box without rotation");
        const Vec3 h = b.shape.halfExtents;
        TableTop t;
        t.top = b.position.y() + h.y();
        t.min = {b.position.x() - h.x(), b.position.z() - h.z()};
        t.max = {b.position.x() + h.x(), b.position.z() + h.z()};
        return t;
    }
    refuse(scene, "it needs a static box called \"table_top\"");
}

struct Dish {
    std::string name;
    Vec3 half = Vec3::Zero();
    std::size_t view = 0; ///< index in Simulation::bodies()
    DishReport report;
    bool leftTable = false, tipped = false, fell = false;
};

Eigen::Matrix4d poseOf(const BodyView& v) {
    return v.transform.cast<double>();
}

double tiltDeg(const Eigen::Matrix4d& pose) {
    return std::acos(std::clamp(pose(1, 1), -1.0, 1.0)) * 180.0 / kPi;
}

/// Height of the lowest corner of a box posed by `pose` [m].
double lowestCorner(const Eigen::Matrix4d& pose, const Vec3& half) {
    double reach = 0.0;
    for (int k = 0; k < 3; ++k)
        reach += std::abs(pose(1, k)) * half[k];
    return pose(1, 3) - reach;
}

/// Height above the table top of the lowest corner of the box that lies over the table
/// (+infinity if none does) [m].
double clearanceOver(const TableTop& table, const Eigen::Matrix4d& pose, const Vec3& half) {
    double least = std::numeric_limits<double>::infinity();
    for (int corner = 0; corner < 8; ++corner) {
        const Vec3 local((corner & 1 ? 1 : -1) * half.x(), (corner & 2 ? 1 : -1) * half.y(),
                         (corner & 4 ? 1 : -1) * half.z());
        const Vec3 p = pose.topLeftCorner<3, 3>() * local + pose.topRightCorner<3, 1>();
        if (table.over(p)) least = std::min(least, p.y() - table.top);
    }
    return least;
}

} // namespace

const char* toString(YankKind kind) {
    return kind == YankKind::Fast ? "fast" : "slow";
}

double Yank::displacement(double t) const {
    const double tau = t - startTime;
    if (tau <= 0.0) return 0.0;
    const double rampDistance = 0.5 * speed * rampTime;
    const double d = tau < rampTime ? 0.5 * speed / rampTime * tau * tau
                                    : rampDistance + speed * (tau - rampTime);
    return std::min(d, distance);
}

double Yank::endTime() const {
    const double rampDistance = 0.5 * speed * rampTime;
    if (distance <= rampDistance) return startTime + std::sqrt(2.0 * distance * rampTime / speed);
    return startTime + rampTime + (distance - rampDistance) / speed;
}

Yank scriptYank(YankKind kind, ScriptedPlayer& player) {
    Yank y;
    y.startTime = player.uniform(0.25, 0.35);       // the dishes have settled on the cloth by then
    const double slope = player.uniform(0.15, 0.3); // down per metre toward the player
    y.direction = Vec3(0.0, -slope, 1.0).normalized();
    if (kind == YankKind::Fast) {
        y.speed = player.uniform(7.0, 9.0);
        y.rampTime = 0.06;
        y.distance = 1.0; // the whole cloth comes off the table
    } else {
        y.speed = player.uniform(0.7, 0.8);
        y.rampTime = 0.25; // at most 3.2 m/s^2: below mu g, static friction carries the dishes
        y.distance = 0.75;
    }
    return y;
}

double depthInsideBox(const Vec3& p, const Vec3& halfExtents, const Eigen::Matrix4d& pose) {
    const Eigen::Matrix3d r = pose.topLeftCorner<3, 3>();
    const Vec3 local = r.transpose() * (p - pose.topRightCorner<3, 1>());
    return (halfExtents - local.cwiseAbs()).minCoeff();
}

RoundResult playRound(const SceneDesc& scene, const RoundOptions& options) {
    const TableTop table = findTable(scene);
    if (scene.pins.empty() || !scene.pins[0].velocity.isZero())
        refuse(scene, "pins[0] (the edge the player holds) must be a fixed pin");

    Simulation sim(scene);
    std::vector<Dish> dishes;
    const std::vector<BodyView> views = sim.bodies();
    for (const RigidBodyDesc& b : scene.rigidBodies) {
        if (b.motion != MotionKind::Dynamic) continue;
        if (b.shape.kind != ShapeKind::Box)
            refuse(scene, b.path + " (dish \"" + b.name + "\") must be a box");
        Dish d;
        d.name = b.name;
        d.half = b.shape.halfExtents;
        d.report.name = b.name;
        for (std::size_t k = 0; k < views.size(); ++k)
            if (views[k].name == b.name) d.view = k;
        dishes.push_back(d);
    }
    if (dishes.empty()) refuse(scene, "it needs dynamic boxes (the dishes)");

    ScriptedPlayer player(options.seed + (options.kind == YankKind::Fast ? 0u : 1u));
    RoundResult result;
    result.kind = options.kind;
    result.yank = scriptYank(options.kind, player);
    const Yank yank = result.yank;
    Cloth& cloth = sim.cloth();
    for (Index i : sim.pinnedParticles()[0]) {
        const Vec3 x0 = cloth.positions()[i];
        cloth.setKinematic(
            i, [x0, yank](double t) { return Vec3(x0 + yank.direction * yank.displacement(t)); });
    }

    const char* round = toString(options.kind);
    auto event = [&](const char* what, const std::string& dish, const std::string& detail) {
        if (options.events)
            *options.events << round << ',' << sim.time() << ',' << what << ',' << dish << ','
                            << detail << '\n';
    };

    std::unique_ptr<OffscreenRenderer> renderer;
    if (options.frames) {
        std::filesystem::create_directories(*options.frames);
        renderer = std::make_unique<OffscreenRenderer>(options.width, options.height);
    }
    auto drawFrame = [&]() {
        if (!renderer) return;
        std::vector<DrawMesh> meshes;
        meshes.push_back(toDrawMesh(cloth.positions(), cloth.topology().triangles(),
                                    scene.frontColor, scene.backColor));
        for (const BodyView& bv : sim.bodies()) {
            bool lost = false;
            for (const Dish& d : dishes)
                if (d.name == bv.name) lost = d.leftTable || d.tipped;
            for (const DrawMesh& m : *bv.meshes) {
                meshes.push_back(m);
                meshes.back().model = bv.transform;
                if (lost) meshes.back().front = meshes.back().back = {0.30f, 0.30f, 0.32f};
            }
        }
        writePng(framePath(*options.frames, result.frames++),
                 renderer->render(scene.camera, meshes, scene.output.background));
    };

    // One step and the checks after it: penetration of the table and of the cloth, the events.
    bool started = false, stopped = false;
    auto step = [&]() {
        sim.step();
        ++result.steps;
        const double t = sim.time();
        if (!started && t >= yank.startTime) {
            started = true;
            event("yank_start", "", std::string("speed ") + std::to_string(yank.speed) + " m/s");
        }
        if (!stopped && t >= yank.endTime()) {
            stopped = true;
            event("yank_end", "", "hand stopped");
        }
        const std::vector<BodyView> now = sim.bodies();
        for (Dish& d : dishes) {
            const Eigen::Matrix4d pose = poseOf(now[d.view]);
            const Vec3 c = pose.topRightCorner<3, 1>();
            if (!started) d.report.start = c; // the last pose before the yank
            d.report.maxDisplacement =
                std::max(d.report.maxDisplacement, (c - d.report.start).norm());
            result.minTableClearance =
                std::min(result.minTableClearance, clearanceOver(table, pose, d.half));
            for (const Vec3& x : cloth.positions())
                result.maxClothDepth =
                    std::max(result.maxClothDepth, depthInsideBox(x, d.half, pose));
            if (!d.leftTable && !table.over(c)) {
                d.leftTable = true;
                event("left_table", d.name, "");
            }
            if (!d.tipped && tiltDeg(pose) > kTippedTiltDeg) {
                d.tipped = true;
                event("tipped", d.name, "");
            }
            if (!d.fell && c.y() < table.top - kFellDrop) {
                d.fell = true;
                event("fell", d.name, "");
            }
        }
    };

    const double end = yank.endTime() + options.settleAfterYank;
    FixedStepLoop loop(scene.timeStep, 1.0 / scene.output.fps);
    drawFrame();
    // The round ends `settleAfterYank` after the hand stopped, or kAfterAllFell after every
    // dish has fallen off (nothing is left to score).
    auto allFell = [&]() {
        return std::all_of(dishes.begin(), dishes.end(), [](const Dish& d) { return d.fell; });
    };
    double fellAt = 1e300;
    while (sim.time() < end && sim.time() < fellAt + kAfterAllFell) {
        if (fellAt > 1e299 && allFell()) fellAt = sim.time();
        loop.beginFrame();
        while (loop.nextStep())
            step();
        drawFrame();
    }

    const std::vector<BodyView> last = sim.bodies();
    for (Dish& d : dishes) {
        const Eigen::Matrix4d pose = poseOf(last[d.view]);
        DishReport& r = d.report;
        r.end = pose.topRightCorner<3, 1>();
        r.endTiltDeg = tiltDeg(pose);
        const double bottom = lowestCorner(pose, d.half) - table.top;
        r.standing = table.over(r.end) && r.endTiltDeg < kStandingTiltDeg && bottom > -0.005 &&
                     bottom < 0.03;
        if (r.standing) ++result.standing;
        event(r.standing ? "standing" : "lost", d.name,
              "moved " + std::to_string((r.end - r.start).norm()) + " m");
        result.dishes.push_back(r);
    }
    result.seconds = sim.time();
    result.clothSubsteps = sim.substeps();
    return result;
}

} // namespace drape::samples::tablecloth
