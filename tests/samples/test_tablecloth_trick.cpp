// samples/games/tablecloth_trick: the tablecloth trick needs real two-way friction coupling.
// Both yanks are played in the game's own world (its scene file) and checked against
// Coulomb's law, not against numbers the game printed:
//   - fast yank: kinetic friction (mu g) acts on a dish only while the cloth slides under it,
//     at most the time T the hand takes to pull the whole cloth's length. So a dish gains at
//     most mu g T of speed and moves at most mu g T^2 / 2 on the cloth plus v^2 / (2 mu_t g)
//     sliding on the table (mu_t: Bullet's dish-table friction, the product of the two).
//     Every dish must stay within that bound and stand upright on the table at the end;
//   - slow yank: the hand's acceleration is below mu g, so static friction carries the dishes
//     along: each must move more than its own size, and fewer dishes may be left standing;
//   - neither: no dish corner over the table sinks more than kTableSlack into the table top,
//     and no cloth particle is ever more than kClothSlack inside a dish (the contacts keep
//     particles collision.thickness = 5 mm outside). Checked after every step (2 ms): a dish
//     sinking through the cloth would have to pass its bottom (24 mm plates, a 60 mm bowl)
//     across a particle, which at a few mm per step leaves the particle inside for a step.
// The rounds use the game's default seed. Not every seed passes the fast-yank bound: over seeds
// 1-20 (Provot limiting, this scene) a plate was thrown off the table in 2 (5 and 17) and moved
// 0.15-0.28 m in 3 more. A thrown plate (seed 5) goes from 0.04 to 2.4 m/s in 10 ms (about
// 200 m/s^2, forty times mu g) with upward kicks of 0.3 m/s: the coupling's friction at slip
// speeds of ~8 m/s is not yet what Coulomb's law would give every time.
#include "tablecloth_trick.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>

using namespace drape;
using namespace drape::samples;
using namespace drape::samples::tablecloth;

namespace {

constexpr double kTableSlack = 0.003; // m: Bullet's resting box-box penetration is ~1 mm
constexpr double kClothSlack = 0.001; // m: a fifth of the contact thickness

const RigidBodyDesc& body(const SceneDesc& scene, const std::string& name) {
    for (const RigidBodyDesc& b : scene.rigidBodies)
        if (b.name == name) return b;
    FAIL("no body " << name);
    throw; // not reached
}

// Time for the hand to pull `length` metres.
double timeToPull(const Yank& y, double length) {
    double lo = y.startTime, hi = y.endTime();
    for (int i = 0; i < 60; ++i) {
        const double mid = 0.5 * (lo + hi);
        (y.displacement(mid) < length ? lo : hi) = mid;
    }
    return hi - y.startTime;
}

void checkNoPenetration(const RoundResult& r) {
    INFO(toString(r.kind) << " yank: lowest dish corner over the table "
                          << r.minTableClearance * 1000.0 << " mm, deepest particle in a dish "
                          << r.maxClothDepth * 1000.0 << " mm");
    CHECK(r.minTableClearance > -kTableSlack);
    CHECK(r.maxClothDepth < kClothSlack);
}

} // namespace

struct Played {
    SceneDesc scene = loadScene(DRAPE_TABLECLOTH_TRICK_SCENE);
    std::ostringstream events;
    RoundResult round;
    explicit Played(YankKind kind) {
        RoundOptions options;
        options.kind = kind;
        options.events = &events;
        round = playRound(scene, options);
    }
    // Coulomb coefficient between the cloth and the dish; the dish's size across.
    double mu(const RigidBodyDesc& dish) const {
        return dish.friction * scene.collision->frictionScale;
    }
    // Rows of events.csv that say a dish was lost (left the table or fell).
    int lostEvents() const {
        std::istringstream rows(events.str());
        int lost = 0;
        for (std::string row; std::getline(rows, row);)
            lost += row.find(",left_table,") != std::string::npos ||
                    row.find(",fell,") != std::string::npos;
        return lost;
    }
};

double across(const RigidBodyDesc& dish) {
    return 2.0 * std::max(dish.shape.halfExtents.x(), dish.shape.halfExtents.z());
}

TEST_CASE("tablecloth_trick: a fast yank leaves every dish standing where it was",
          "[samples][game]") {
    const Played p(YankKind::Fast);
    const RoundResult& r = p.round;
    REQUIRE(r.dishes.size() == 3);
    const double g = 9.81;
    const double clothLength = (p.scene.sheet->spec.rows - 1) * p.scene.sheet->spec.spacing;
    const double tableMu = body(p.scene, "table_top").friction;
    // Kinetic friction acts at most while the hand pulls the cloth's whole length.
    const double T = timeToPull(r.yank, clothLength);
    for (const DishReport& d : r.dishes) {
        const RigidBodyDesc& desc = body(p.scene, d.name);
        const double vMax = p.mu(desc) * g * T;
        const double bound =
            0.5 * p.mu(desc) * g * T * T + vMax * vMax / (2.0 * desc.friction * tableMu * g);
        INFO(d.name << " moved at most " << d.maxDisplacement << " m (Coulomb bound " << bound
                    << " m, T = " << T << " s)");
        CHECK(d.maxDisplacement < bound);
        CHECK(d.standing);
    }
    CHECK(r.standing == 3);
    CHECK(p.lostEvents() == 0);
    checkNoPenetration(r);
}

TEST_CASE("tablecloth_trick: a slow yank drags the dishes off the table", "[samples][game]") {
    const Played p(YankKind::Slow);
    const RoundResult& r = p.round;
    REQUIRE(r.dishes.size() == 3);
    for (const DishReport& d : r.dishes) {
        const RigidBodyDesc& desc = body(p.scene, d.name);
        INFO(d.name << " moved " << d.maxDisplacement << " m, its size " << across(desc) << " m");
        // The hand accelerates below mu g: static friction can carry the dish along...
        CHECK(r.yank.speed / r.yank.rampTime < p.mu(desc) * 9.81);
        // ...and does: it goes further than its own size.
        CHECK(d.maxDisplacement > across(desc));
    }
    CHECK(r.standing < 3);
    CHECK(p.lostEvents() > 0);
    checkNoPenetration(r);
}

TEST_CASE("tablecloth_trick: the penetration measure sees a particle inside a dish",
          "[samples][game]") {
    Eigen::Matrix4d pose = Eigen::Matrix4d::Identity();
    pose.topLeftCorner<3, 3>() = Eigen::AngleAxisd(0.3, Vec3::UnitY()).toRotationMatrix();
    pose.topRightCorner<3, 1>() = Vec3(1.0, 0.8, -0.5);
    const Vec3 half(0.09, 0.008, 0.09);
    // 3 mm above the bottom face, inside: depth 3 mm (the nearest face).
    CHECK(depthInsideBox(Vec3(1.0, 0.8 - 0.005, -0.5), half, pose) == Approx(0.003));
    // 5 mm below it (where the contact thickness keeps particles): outside.
    CHECK(depthInsideBox(Vec3(1.0, 0.8 - 0.013, -0.5), half, pose) == Approx(-0.005));
    CHECK(depthInsideBox(Vec3(1.2, 0.8, -0.5), half, pose) < 0.0);
}

TEST_CASE("tablecloth_trick: the yank accelerates uniformly, then pulls at speed, then holds",
          "[samples][game]") {
    ScriptedPlayer player(3);
    const Yank y = scriptYank(YankKind::Fast, player);
    CHECK(y.direction.norm() == Approx(1.0));
    CHECK(y.direction.z() > 0.0); // toward the player
    CHECK(y.direction.y() < 0.0); // a little down over the edge
    CHECK(y.displacement(y.startTime - 0.1) == 0.0);
    const double h = 1e-6;
    const double tRamp = y.startTime + y.rampTime;
    CHECK((y.displacement(tRamp + h) - y.displacement(tRamp - h)) / (2 * h) ==
          Approx(y.speed).epsilon(1e-4));
    CHECK(y.displacement(y.endTime()) == Approx(y.distance));
    CHECK(y.displacement(y.endTime() + 1.0) == Approx(y.distance));
    // Same seed, same yank; a slow yank is slower.
    ScriptedPlayer again(3);
    CHECK(scriptYank(YankKind::Fast, again).speed == y.speed);
    CHECK(scriptYank(YankKind::Slow, player).speed < y.speed / 5);
}

TEST_CASE("the games' fixed-step loop: exact steps per frame, and a frame owes at most 0.25 s",
          "[samples][game]") {
    // 60 frames of 1/60 s at 1/240 s steps: 4 steps each, 240 in all.
    FixedStepLoop loop(1.0 / 240.0, 1.0 / 60.0);
    int steps = 0;
    for (int f = 0; f < 60; ++f) {
        loop.beginFrame();
        while (loop.nextStep())
            ++steps;
    }
    CHECK(steps == 240);
    // output.fps = 1e-6 (inside the scene format's range): a frame of 1e6 s would owe 1e8
    // steps; it is cut to kMaxFrameTime, 25 steps of 0.01 s, and the next frame the same.
    FixedStepLoop slow(0.01, 1e6);
    int total = 0;
    for (int f = 0; f < 4; ++f) {
        slow.beginFrame();
        int n = 0;
        while (slow.nextStep())
            ++n;
        CHECK(n <= 25); // 0.25 s of 0.01 s steps (24 when rounding leaves a hair less)
        total += n;
    }
    CHECK(total >= 99); // the hair carries over: 1 s of frames, 100 steps
    CHECK_THROWS_AS(FixedStepLoop(0.01, 0.0), std::invalid_argument);
}

TEST_CASE("tablecloth_trick: a world without a table, handle or box dishes is refused",
          "[samples][game]") {
    const std::string cloth =
        R"("cloth": {"sheet": {"rows": 3, "cols": 3, "spacing": 0.1, "origin": [0, 1, 0],
            "u_axis": [1, 0, 0], "v_axis": [0, 0, 1]}, "total_mass": 0.1, "stiffness": 10},)";
    const std::string table =
        R"({"name": "table_top", "shape": {"type": "box", "half_extents": [0.5, 0.02, 0.4]}})";
    auto play = [](const std::string& text) {
        playRound(parseScene(text, "bad.json", "."), RoundOptions{});
    };
    CHECK_THROWS_WITH(play("{" + cloth + R"("pins": [{"grid": [[2, 0]]}], "rigid_bodies": [
        {"name": "floor", "shape": {"type": "plane"}}]})"),
                      Catch::Contains(": not a tablecloth_trick world") &&
                          Catch::Contains("\"table_top\""));
    CHECK_THROWS_WITH(play("{" + cloth + R"("rigid_bodies": [)" + table + "]}"),
                      Catch::Contains("pins[0]"));
    CHECK_THROWS_WITH(play("{" + cloth + R"("pins": [{"grid": [[2, 0]]}], "rigid_bodies": [)" +
                           table +
                           R"(, {"name": "ball", "shape": {"type": "sphere", "radius": 0.05},
                           "motion": "dynamic", "position": [0, 1.2, 0]}]})"),
                      Catch::Contains("dish \"ball\"") && Catch::Contains("must be a box"));
}
