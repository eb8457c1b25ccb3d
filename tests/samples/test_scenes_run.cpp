// Shipped scenes run headless: a few steps of each stay finite; pins and groups resolve to
// the right particles; drape-run's outputs agree with the simulation (the OBJ is in particle
// order, the CSV has one row per frame); runs are deterministic.
#include "drape_samples/mesh_io.hpp"
#include "drape_samples/run.hpp"
#include "drape_samples/simulation.hpp"

#include <catch2/catch.hpp>

#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

using namespace drape;
using namespace drape::samples;
namespace fs = std::filesystem;

namespace {

const fs::path kScenes = fs::path(DRAPE_SAMPLES_DIR) / "scenes";

std::vector<fs::path> shippedScenes() {
    std::vector<fs::path> out;
    for (const auto& e : fs::directory_iterator(kScenes))
        if (e.path().extension() == ".json") out.push_back(e.path());
    std::sort(out.begin(), out.end());
    return out;
}

bool allFinite(const Vec3List& xs) {
    for (const Vec3& x : xs)
        if (!x.allFinite()) return false;
    return true;
}

} // namespace

TEST_CASE("every shipped scene builds and runs a few steps", "[scenes]") {
    for (const auto& file : shippedScenes()) {
        INFO(file);
        const SceneDesc scene = loadScene(file);
        if (scene.needsBullet() && !rigidBodiesAvailable()) {
            WARN("skipped (no Bullet integration in this build): " << file);
            continue;
        }
        bool usesMeshFiles = scene.mesh.has_value();
        for (const auto& b : scene.rigidBodies)
            usesMeshFiles = usesMeshFiles || b.shape.kind == ShapeKind::Mesh;
        if (usesMeshFiles && !meshIoAvailable()) {
            WARN("skipped (no assimp in this build): " << file);
            continue;
        }
        Simulation sim(scene);
        const Vec3List start = sim.cloth().positions();
        for (int k = 0; k < 5; ++k)
            sim.step();
        CHECK(sim.steps() == 5);
        CHECK(sim.time() == Approx(5 * scene.timeStep));
        CHECK(allFinite(sim.cloth().positions()));
        CHECK(allFinite(sim.cloth().velocities()));
        // Something moved (every scene has gravity): the scene is actually running.
        double moved = 0.0;
        for (std::size_t i = 0; i < start.size(); ++i)
            moved = std::max(moved, (sim.cloth().positions()[i] - start[i]).norm());
        CHECK(moved > 0.0);
        const FrameStats s = sim.stats();
        CHECK(std::isfinite(s.maxStrain));
        CHECK(std::isfinite(s.kineticEnergy));
        CHECK(s.kineticEnergy > 0.0);
    }
}

TEST_CASE("Experiment I pins exactly the two top corners, which never move", "[scenes]") {
    Simulation sim(loadScene(kScenes / "experiment1_suspended_sheet.json"));
    REQUIRE(sim.pinnedParticles().size() == 1);
    CHECK(sim.pinnedParticles()[0] == std::vector<Index>{0, 34});
    const Vec3 a = sim.cloth().positions()[0], b = sim.cloth().positions()[34];
    for (int k = 0; k < 20; ++k)
        sim.step();
    CHECK(sim.cloth().positions()[0] == a);
    CHECK(sim.cloth().positions()[34] == b);
    CHECK(sim.cloth().positions()[35].y() < -10.0); // the row below fell
    // Free fall for 0.2 s moves a free particle by g t^2 / 2 = 0.196 at most.
    CHECK(sim.cloth().positions()[35 * 34 + 17].y() == Approx(-340.0 - 0.196).margin(0.02));
}

TEST_CASE("pins by named group and by region box select the right particles", "[scenes]") {
    if (!meshIoAvailable()) {
        WARN("skipped: built without assimp");
        return;
    }
    SceneDesc curtain = loadScene(kScenes / "curtain_ball.json");
    curtain.rigidBodies.clear(); // only the cloth matters here
    curtain.collision.reset();
    Simulation sim(curtain);
    REQUIRE(sim.pinnedParticles().size() == 1);
    CHECK(sim.pinnedParticles()[0].size() == 52); // the top two rows of 26
    for (Index i : sim.pinnedParticles()[0])
        CHECK(sim.cloth().isPinned(i));

    SceneDesc flag = loadScene(kScenes / "flag_in_wind.json");
    flag.rigidBodies.clear();
    flag.collision.reset();
    Simulation f(flag);
    REQUIRE(f.pinnedParticles().size() == 1);
    CHECK(f.pinnedParticles()[0].size() == 21); // the column at the pole
    for (Index i : f.pinnedParticles()[0])
        CHECK(i % 31 == 0);
}

TEST_CASE("runScene writes frames, a CSV row per frame and the final mesh in particle order",
          "[scenes][runner]") {
    RunOptions o;
    o.scene = kScenes / "experiment1_suspended_sheet.json";
    o.outDir = fs::path(DRAPE_TEST_OUT_DIR) / "run_experiment1";
    o.steps = 30;
    o.fps = 50.0; // a frame every 2 steps of 0.01 s
    o.width = 64;
    o.height = 48;
    o.render = renderingAvailable();
    o.video = false;
    std::ostringstream log;
    const RunResult r = runScene(o, log);
    CHECK(r.steps == 30);
    CHECK(r.frames == 16); // t = 0, 0.02, ..., 0.30
    CHECK(r.simulatedSeconds == Approx(0.30));
    CHECK(log.str().find("particles") != std::string::npos);

    std::ifstream csv(o.outDir / "stats.csv");
    std::string line;
    std::getline(csv, line);
    CHECK(line.rfind("frame,time_s,steps,max_strain,mean_strain,kinetic_energy_J,lowest_point_m,"
                     "contacts,wall_ms_per_step",
                     0) == 0);
    std::size_t rows = 0;
    double lastTime = -1.0;
    while (std::getline(csv, line)) {
        std::stringstream ss(line);
        std::string frame, time;
        std::getline(ss, frame, ',');
        std::getline(ss, time, ',');
        CHECK(std::stod(time) > lastTime);
        lastTime = std::stod(time);
        ++rows;
    }
    CHECK(rows == r.frames);
    CHECK(lastTime == Approx(0.30));
    if (o.render) {
        CHECK(fs::exists(o.outDir / "frames" / "frame_00000.png"));
        CHECK(fs::exists(o.outDir / "frames" / "frame_00015.png"));
        CHECK_FALSE(fs::exists(o.outDir / "frames" / "frame_00016.png"));
    }
    CHECK(fs::exists(o.outDir / "summary.txt"));

    if (meshIoAvailable()) {
        // The exported mesh is the cloth after 30 steps, vertex i = particle i.
        Simulation sim(loadScene(o.scene));
        for (int k = 0; k < 30; ++k)
            sim.step();
        const ImportedMesh m = importMesh(o.outDir / "cloth_final.obj");
        REQUIRE(m.mesh.vertices.size() == sim.cloth().particleCount());
        REQUIRE(m.mesh.triangles.size() == sim.cloth().topology().triangleCount());
        double worst = 0.0;
        for (std::size_t i = 0; i < m.mesh.vertices.size(); ++i)
            worst = std::max(worst, (m.mesh.vertices[i] - sim.cloth().positions()[i]).norm());
        CHECK(worst < 1e-3); // float storage of coordinates of order 100
    }
}

TEST_CASE("the same scene run twice gives bit-identical cloth", "[scenes]") {
    for (const char* name : {"experiment1_suspended_sheet.json", "trampoline.json"}) {
        INFO(name);
        const SceneDesc scene = loadScene(kScenes / name);
        if (scene.needsBullet() && !rigidBodiesAvailable()) continue;
        Simulation a(scene), b(scene);
        for (int k = 0; k < 25; ++k) {
            a.step();
            b.step();
        }
        CHECK(a.cloth().positions() == b.cloth().positions());
        CHECK(a.cloth().velocities() == b.cloth().velocities());
    }
}

TEST_CASE("overrides replace the scene's integrator, time step and length", "[scenes][runner]") {
    SceneDesc s = loadScene(kScenes / "experiment1_suspended_sheet.json");
    RunOptions o;
    o.integrator = "rk4";
    o.timeStep = 0.005;
    o.seconds = 0.5;
    applyOverrides(s, o);
    CHECK(s.cloth.integrator == IntegratorKind::RungeKutta4);
    CHECK(s.timeStep == 0.005);
    CHECK(s.stepCount() == 100);
    RunOptions bad;
    bad.steps = 0;
    CHECK_THROWS_AS(applyOverrides(s, bad), SceneError);
    // The command line's numbers have the scene file's ranges.
    RunOptions hugeDt;
    hugeDt.timeStep = 1e300;
    CHECK_THROWS_WITH(applyOverrides(s, hugeDt),
                      Catch::Matchers::Contains("--dt: must be in [1e-09, 10] s"));
    RunOptions hugeSeconds;
    hugeSeconds.seconds = 1e300;
    CHECK_THROWS_WITH(applyOverrides(s, hugeSeconds),
                      Catch::Matchers::Contains("--seconds: must be in (0, 1e+06] s"));
    RunOptions tinyFps;
    tinyFps.fps = 1e-300;
    CHECK_THROWS_WITH(applyOverrides(s, tinyFps), Catch::Matchers::Contains("--fps: must be in"));
}

TEST_CASE("Experiment I: no spring at the suspension points stretches beyond the limit",
          "[scenes][physics]") {
    // The paper's claim for its limiter: no overstretch where the sheet hangs. The scene
    // limits strain to 10 % with the stress-ordered limiter, whose rounds stop once every
    // spring is within max_strain + tolerance.
    const SceneDesc scene = loadScene(kScenes / "experiment1_suspended_sheet.json");
    Simulation sim(scene);
    const double bound = scene.cloth.limiter.maxStrain + scene.cloth.limiter.tolerance + 1e-9;
    double worstAtPins = 0.0;
    for (int k = 0; k < 120; ++k) {
        sim.step();
        const auto& topo = sim.cloth().topology();
        const auto& x = sim.cloth().positions();
        for (const Spring& s : topo.springs()) {
            if (s.a != 0 && s.a != 34 && s.b != 0 && s.b != 34) continue;
            worstAtPins = std::max(worstAtPins, (x[s.b] - x[s.a]).norm() / s.restLength - 1.0);
        }
    }
    CHECK(worstAtPins <= bound);
    CHECK(worstAtPins > 0.05); // the corners do carry the sheet (the check is not vacuous)
}

TEST_CASE("Experiment II: the tablecloth lands on the desk top and rests there",
          "[scenes][physics]") {
    if (!rigidBodiesAvailable()) {
        WARN("skipped: no Bullet integration");
        return;
    }
    SceneDesc scene = loadScene(kScenes / "experiment2_tablecloth.json");
    Simulation sim(scene);
    // Centre particle (row 15, col 30) starts 60 above the desk's centre; the desk top is at
    // y = 5 and the contact thickness is h. Falling 60 - 5 - h (about 52) takes
    // sqrt(2 * 52 / 9.8) = 3.3 s without damping; with the scene's C_d / m = 0.3 1/s,
    // x(t) = (g m / C_d) (t - (1 - exp(-0.3 t)) / 0.3) reaches 52 at t = 3.9 s. By 5 s it
    // has landed and rests within the contact band above the desk.
    REQUIRE(scene.collision);
    const double h = scene.collision->thickness.value();
    const Index centre = sheetIndex(scene.sheet->spec, 15, 30);
    const double x0 = sim.cloth().positions()[centre].x();
    std::size_t maxContacts = 0;
    while (sim.time() < 5.0 - 1e-9) {
        sim.step();
        maxContacts = std::max(maxContacts, sim.contactCount());
    }
    const Vec3 c = sim.cloth().positions()[centre];
    CHECK(c.y() > 5.0);                 // on top of the desk, not through it
    CHECK(c.y() < 5.0 + 2.0 * h);       // resting on it: within the thickness and the penalty band
    CHECK(std::abs(c.x() - x0) < 20.0); // it fell straight down, did not slide off
    CHECK(maxContacts > 100);           // a good part of the cloth touches the desk
    CHECK(sim.stats().lowestPoint > -150.0 - 1e-6); // nothing fell through the floor
}

TEST_CASE("cloth_on_sphere: the sheet drapes over the ball without entering it",
          "[scenes][physics]") {
    if (!rigidBodiesAvailable()) {
        WARN("skipped: no Bullet integration");
        return;
    }
    const SceneDesc scene = loadScene(kScenes / "cloth_on_sphere.json");
    Simulation sim(scene);
    const Vec3 ball = sim.bodyPosition("ball");
    REQUIRE(scene.rigidBodies.size() == 2);
    const double radius = scene.rigidBodies[0].shape.radius;
    const double h = scene.collision->thickness.value();
    // The sheet starts 20 above the ball's top and falls (C_d / m = 0.1 1/s: about 2 s to the
    // ball); by 7 s its middle lies on the ball at the contact distance and its sides hang
    // down past the ball's equator, and no particle ever gets inside radius + h.
    double closest = 1e300;
    while (sim.time() < 7.0 - 1e-9) {
        sim.step();
        for (const Vec3& x : sim.cloth().positions())
            closest = std::min(closest, (x - ball).norm());
    }
    CHECK(closest >= radius + h - 1e-3);
    double top = -1e300, lowest = 1e300;
    for (const Vec3& x : sim.cloth().positions()) {
        top = std::max(top, x.y() - ball.y());
        lowest = std::min(lowest, x.y() - ball.y());
    }
    CHECK(top == Approx(radius + h).margin(0.05 * h + 0.5)); // resting on the ball's top
    CHECK(lowest < 0.0);                                     // the sides hang past its equator
    CHECK(sim.contactCount() > 0);
    CHECK(sim.stats().maxStrain <= 0.10 + 1e-2); // the limiter with contacts (compare report)
}

TEST_CASE("curtain_ball: at 60 Hz the curtain stops a 20 m/s ball and is pushed back by it",
          "[scenes][physics][fast]") {
    if (!rigidBodiesAvailable() || !meshIoAvailable()) {
        WARN("skipped: no Bullet or assimp");
        return;
    }
    Simulation sim(loadScene(kScenes / "curtain_ball.json"));
    // The ball (r = 6 cm) leaves z = 2.5 at 20 m/s towards the curtain (z = 0) at t = 0.5 s,
    // at a 60 Hz world step: 33 cm a step, more than its diameter plus the thickness.
    REQUIRE(sim.scene().timeStep == Approx(1.0 / 60.0));
    double deepestCloth = 0.0, deepestBall = 1e9, peakStrain = 0.0, speedAfter = 0.0;
    while (sim.time() < 2.0 - 1e-9) {
        sim.step();
        for (const Vec3& x : sim.cloth().positions())
            deepestCloth = std::min(deepestCloth, x.z());
        deepestBall = std::min(deepestBall, sim.bodyPosition("ball").z());
        peakStrain = std::max(peakStrain, sim.cloth().maxStrain());
        if (std::abs(sim.time() - 0.8) < 1e-9) speedAfter = std::abs(sim.bodyVelocity("ball").z());
    }
    INFO("ball deepest at z = " << deepestBall << " m, |v_z| " << speedAfter
                                << " m/s at 0.8 s; cloth deepest " << deepestCloth
                                << " m; peak strain " << peakStrain);
    // Without the curtain the ball would be at z = 2.5 - 20 * 1.5 = -27.5 m by t = 2 s. The
    // curtain (2 m long, pinned at the top) catches it within its reach, and 0.3 s after the
    // launch the ball moves at less than a quarter of its speed.
    CHECK(deepestBall > -2.5);
    CHECK(speedAfter < 5.0);
    CHECK(deepestCloth < -0.2);        // the ball pushed the cloth back (two-way coupling)
    CHECK(peakStrain <= 0.101 + 1e-3); // the bound holds against the ball
}

TEST_CASE("a scene with rigid bodies beyond single precision's reach is refused, naming what",
          "[scenes][ranges]") {
    if (!rigidBodiesAvailable()) {
        WARN("skipped: no Bullet integration");
        return;
    }
    // Near 1e6 m Bullet's float positions are 6 cm apart: a 5 mm thickness cannot hold. The
    // reach for h = 5 mm is 0.1 h 2^23 = 4194 m.
    auto scene = [](const std::string& x) {
        return parseScene(R"({
          "cloth": {"sheet": {"rows": 3, "cols": 3, "spacing": 0.1, "origin": [)" +
                              x + R"(, 1, 0]}, "particle_mass": 0.01, "stiffness": 20.0},
          "simulation": {"time_step": 0.002, "duration": 0.01},
          "rigid_bodies": [{"name": "box", "shape": {"type": "box", "half_extents": [1, 0.1, 1]},
                            "position": [)" +
                              x + R"(, 0, 0]}],
          "collision": {"thickness": 0.005}
        })",
                          "far.json", kScenes);
    };
    using Catch::Matchers::Contains;
    CHECK_THROWS_WITH(Simulation(scene("999000")),
                      Contains("the cloth's particle 0 lies 999000 m from the origin") &&
                          Contains("within 4194.3 m") && Contains("single precision"));
    CHECK_NOTHROW(Simulation(scene("4000")));
}

TEST_CASE("rigid bodies piled into each other at the start are refused before Bullet pairs them",
          "[scenes][ranges]") {
    if (!rigidBodiesAvailable()) {
        WARN("skipped: no Bullet integration");
        return;
    }
    // 2,000 dynamic spheres at one point: 2 million pairs for Bullet. A row of 2,000 touching
    // ones (a pair each) is a scene.
    auto scene = [](bool piled) {
        std::string bodies;
        for (int i = 0; i < 2000; ++i)
            bodies += std::string(i ? "," : "") + R"({"name": "b)" + std::to_string(i) +
                      R"(", "shape": {"type": "sphere", "radius": 0.05}, "motion": "dynamic",
                         "mass": 0.1, "position": [)" +
                      (piled ? std::string("0") : std::to_string(0.1 * i)) + ", 3, 0]}";
        return parseScene(R"({"cloth": {"sheet": {"rows": 3, "cols": 3, "spacing": 0.1},
                                         "particle_mass": 0.01, "stiffness": 20.0},
                              "simulation": {"time_step": 0.002, "duration": 0.01},
                              "rigid_bodies": [)" +
                              bodies + "]}",
                          "pile.json", kScenes);
    };
    using Catch::Matchers::Contains;
    CHECK_THROWS_WITH(Simulation(scene(true)),
                      Contains("rigid_bodies: more than 33000 pairs of bodies overlap"));
    CHECK_NOTHROW(Simulation(scene(false)));
}

TEST_CASE("pins times particles beyond the selection limit are refused before any is resolved",
          "[scenes][ranges]") {
    // 100,000 pin entries (the array limit) on a 64 x 64 sheet: 4e8 particle looks, more than
    // kMaxSelectionWork; the same entries on a 16 x 16 sheet (2.6e7) are a scene.
    auto scene = [](int side, int pins) {
        std::string list;
        for (int i = 0; i < pins; ++i)
            list += std::string(i ? "," : "") + R"({"grid": [[0, 0]]})";
        return parseScene(R"({"cloth": {"sheet": {"rows": )" + std::to_string(side) +
                              R"(, "cols": )" + std::to_string(side) +
                              R"(, "spacing": 0.1}, "particle_mass": 0.01, "stiffness": 20.0},
                              "simulation": {"time_step": 0.002, "duration": 0.01},
                              "pins": [)" +
                              list + "]}",
                          "pins.json", kScenes);
    };
    using Catch::Matchers::Contains;
    CHECK(std::size_t(100000) * 64 * 64 > kMaxSelectionWork);
    CHECK_THROWS_WITH(Simulation(scene(64, 100000)),
                      Contains("pins: 100000 pins and 0 attachments on 4096 particles") &&
                          Contains("exceeds the limit of 268435456"));
    CHECK_NOTHROW(Simulation(scene(16, 100000)));
}

TEST_CASE("attachments follow a kinematic body along its keyframes and index pins stay put",
          "[scenes]") {
    if (!rigidBodiesAvailable()) {
        WARN("skipped: no Bullet integration");
        return;
    }
    // A 5 x 5 sheet hangs from a bar that moves 1 m along +x during the first second; its
    // bottom-left corner is pinned by index.
    const SceneDesc scene = parseScene(R"({
      "cloth": {"sheet": {"rows": 5, "cols": 5, "spacing": 0.1, "origin": [0, 1, 0]},
                "particle_mass": 0.01, "stiffness": 20.0, "damping": 0.01},
      "simulation": {"time_step": 0.002, "duration": 1.5},
      "pins": [{"indices": [20]}],
      "rigid_bodies": [{"name": "bar", "shape": {"type": "box", "half_extents": [0.3, 0.02, 0.02]},
                        "motion": "kinematic",
                        "keyframes": [{"time": 0, "position": [0.2, 1.03, 0]},
                                      {"time": 1, "position": [1.2, 1.03, 0]}]}],
      "attachments": [{"body": "bar", "grid": [[0, 0], [0, 2], [0, 4]]}],
      "collision": {"thickness": 0.005}
    })",
                                       "attach.json", kScenes);
    Simulation sim(scene);
    REQUIRE(sim.attachedParticles().size() == 1);
    CHECK(sim.attachedParticles()[0] == std::vector<Index>{0, 2, 4});
    CHECK(sim.pinnedParticles()[0] == std::vector<Index>{20});
    const Vec3 a0 = sim.cloth().positions()[0], a4 = sim.cloth().positions()[4];
    const Vec3 p20 = sim.cloth().positions()[20];
    while (sim.time() < 1.2 - 1e-9)
        sim.step();
    // The bar moved by (1, 0, 0); attached particles move with it (to float precision of
    // Bullet's transforms), and the bar holds still after its last keyframe.
    CHECK((sim.cloth().positions()[0] - (a0 + Vec3(1, 0, 0))).norm() < 1e-4);
    CHECK((sim.cloth().positions()[4] - (a4 + Vec3(1, 0, 0))).norm() < 1e-4);
    CHECK(sim.bodyPosition("bar").isApprox(Vec3(1.2, 1.03, 0.0), 1e-5));
    CHECK(sim.cloth().positions()[20] == p20);
}

TEST_CASE("two runs of a scene end in the same state hash (printed in the summary)",
          "[scenes][runner][determinism]") {
    // The tablecloth drop exercises the Bullet world (contacts with the desk) as well.
    std::uint64_t hashes[2] = {0, 0};
    for (int run = 0; run < 2; ++run) {
        RunOptions o;
        o.scene = kScenes / "experiment2_tablecloth.json";
        o.outDir = fs::path(DRAPE_TEST_OUT_DIR) / ("hash_run" + std::to_string(run));
        o.steps = 40;
        o.render = false;
        o.video = false;
        std::ostringstream log;
        hashes[run] = runScene(o, log).stateHash;
        CHECK(log.str().find("state hash") != std::string::npos);
    }
    CHECK(hashes[0] != 0);
    CHECK(hashes[0] == hashes[1]);
}

namespace {

/// True when a text file holds "inf" or "nan" as a word (any case).
bool holdsNonFinite(const fs::path& file) {
    std::ifstream in(file);
    std::string word;
    while (in >> word) {
        for (char& c : word)
            c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
        for (const char* bad : {"inf", "nan"}) {
            std::size_t at = 0;
            while ((at = word.find(bad, at)) != std::string::npos) {
                const bool leftOk =
                    at == 0 || !std::isalpha(static_cast<unsigned char>(word[at - 1]));
                const std::size_t end = at + 3;
                const bool rightOk = end >= word.size() ||
                                     !std::isalpha(static_cast<unsigned char>(word[end])) ||
                                     word.compare(at, 8, "infinity") == 0;
                if (leftOk && rightOk) return true;
                ++at;
            }
        }
    }
    return false;
}

} // namespace

TEST_CASE("statistics that are not finite stop the run with the value named",
          "[scenes][overflow]") {
    using Catch::Matchers::Contains;
    const SceneDesc scene = parseScene(R"({
      "cloth": {"sheet": {"rows": 3, "cols": 3, "spacing": 0.1}, "particle_mass": 0.01,
                "stiffness": 20.0}})",
                                       "overflow.json", kScenes);
    {
        Simulation sim(scene);
        sim.cloth().setVelocity(4, Vec3(1e200, 0.0, 0.0)); // finite, but m v^2 / 2 is not
        CHECK_THROWS_AS(sim.stats(), StepError);
        CHECK_THROWS_WITH(sim.stats(), Contains("step 0 (t = 0 s): the velocity of particle 4 is "
                                                "(1e+200, 0, 0) m/s, beyond the range of the "
                                                "single-precision output; the simulation "
                                                "overflowed"));
    }
    {
        // Finite energy (5e75 J), but a speed no float holds: a limiter keeps the positions of
        // a cloth whose velocities run away (review 19: 1e81 m/s, every position in place).
        Simulation sim(scene);
        sim.cloth().setVelocity(4, Vec3(0.0, 1e39, 0.0));
        CHECK(std::isfinite(sim.cloth().kineticEnergy()));
        CHECK_THROWS_WITH(sim.stats(), Contains("the velocity of particle 4 is (0, 1e+39, 0) m/s"));
    }
    {
        Simulation sim(scene);
        sim.cloth().setPosition(2, Vec3(0.0, -1e39, 0.0)); // a double, not a float
        CHECK_THROWS_WITH(sim.stats(),
                          Contains("particle 2 is at (0, -1e+39, 0) m, beyond the range of the "
                                   "single-precision output"));
    }
    {
        Simulation sim(scene);
        sim.cloth().mutableVelocities()[1].y() = std::numeric_limits<double>::infinity();
        CHECK_THROWS_WITH(sim.stats(), Contains("the velocity of particle 1 is (0, inf, 0) m/s"));
    }
    Simulation sim(scene);
    CHECK_NOTHROW(sim.stats());
}

TEST_CASE("a run whose state overflows fails (StepError) and writes no inf or nan",
          "[scenes][runner][overflow]") {
    RunOptions o;
    o.scene = fs::path(DRAPE_TEST_DATA_DIR) / "bad_blow_up.json";
    o.outDir = fs::path(DRAPE_TEST_OUT_DIR) / "run_blow_up";
    fs::remove_all(o.outDir);
    o.render = false;
    o.video = false;
    for (const double fps : {25.0, 100.0}) {
        INFO("fps " << fps);
        o.fps = fps;
        std::ostringstream log;
        CHECK_THROWS_AS(runScene(o, log), StepError);
        REQUIRE(fs::exists(o.outDir / "stats.csv")); // the rows before the failure
        for (const auto& e : fs::recursive_directory_iterator(o.outDir)) {
            INFO(e.path());
            CHECK_FALSE(holdsNonFinite(e.path()));
        }
        CHECK_FALSE(fs::exists(o.outDir / "summary.txt"));
        CHECK_FALSE(fs::exists(o.outDir / "cloth_final.obj"));
    }
}

TEST_CASE("export refuses vertices beyond single precision", "[mesh][overflow]") {
    if (!meshIoAvailable()) return;
    TriangleMesh m;
    m.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1e300, 0)};
    m.triangles = {Triangle{0, 1, 2}};
    const fs::path file = fs::path(DRAPE_TEST_OUT_DIR) / "overflow.obj";
    fs::remove(file);
    CHECK_THROWS_WITH(exportMesh(m, file), Catch::Matchers::Contains(
                                               "overflow.obj: vertex 2 is not finite or beyond the "
                                               "single-precision range"));
    CHECK_FALSE(fs::exists(file));
}

TEST_CASE("simulation.substeps \"auto\" picks the sub-steps from the stability estimate",
          "[scenes][substeps]") {
    using Catch::Matchers::Contains;
    // bad_unstable.json: k = 1e6 N/m on 1 g particles, dt = 0.01 s, far beyond the limit.
    const std::string cloth = R"({"cloth": {"sheet": {"rows": 4, "cols": 4, "spacing": 0.1},
                                            "particle_mass": 0.001, "stiffness": 1e6},
                                  "pins": [{"grid": [[0, 0]]}],
                                  "simulation": {"time_step": 0.01, "duration": 1.0)";
    {
        Simulation refused(parseScene(cloth + R"(, "substeps": 1}})", "stiff.json", kScenes));
        CHECK(refused.substeps() == 1);
        CHECK_THROWS_WITH(refused.step(), Contains("exceed the stability limit") &&
                                              Contains("set simulation.substeps to at least ") &&
                                              Contains("or to \"auto\""));
    }
    Simulation sim(parseScene(cloth + R"(, "substeps": "auto"}})", "stiff.json", kScenes));
    // "auto" is the default: the same count without the key.
    CHECK(Simulation(parseScene(cloth + "}}", "stiff.json", kScenes)).substeps() == sim.substeps());
    const double limit = sim.cloth().stableTimeStep();
    const int n = sim.substeps();
    CHECK(n == static_cast<int>(std::ceil(0.01 / (kAutoSubstepMargin * limit))));
    CHECK(0.01 / n <= kAutoSubstepMargin * limit);      // each sub-step is stable, with margin
    CHECK(0.01 / (n - 1) > kAutoSubstepMargin * limit); // and no more of them than needed
    CHECK(n > 100);
    for (int k = 0; k < 3; ++k)
        sim.step();
    CHECK(sim.cloth().stepCount() == 3u * static_cast<unsigned>(n));
    CHECK(sim.time() == Approx(0.03));
    CHECK(allFinite(sim.cloth().positions()));
    CHECK_NOTHROW(sim.stats());

    // A scene that is stable already keeps one step.
    Simulation easy(parseScene(R"({"cloth": {"sheet": {"rows": 4, "cols": 4, "spacing": 0.1},
                                             "particle_mass": 0.01, "stiffness": 5},
                                   "simulation": {"substeps": "auto"}})",
                               "easy.json", kScenes));
    CHECK(easy.substeps() == 1);
    // implicit Euler has no limit: one step.
    Simulation implicit(
        parseScene(cloth + R"(, "substeps": "auto", "integrator": "implicit_euler"}})",
                   "implicit.json", kScenes));
    CHECK(implicit.substeps() == 1);

    // More than kMaxSubsteps needed: refused before the run, naming the field and the numbers.
    CHECK_THROWS_WITH(
        Simulation(parseScene(R"({"cloth": {"sheet": {"rows": 4, "cols": 4, "spacing": 0.1},
                                            "particle_mass": 1e-9, "stiffness": 1e9},
                                  "simulation": {"time_step": 1, "duration": 1, "substeps": "auto"}})",
                              "hopeless.json", kScenes)),
        Contains("simulation.substeps: \"auto\" would need 1.7") &&
            Contains("more than the limit of 10000: lower simulation.time_step"));
}

TEST_CASE("an integer simulation.substeps steps the cloth that many times per step",
          "[scenes][substeps]") {
    const SceneDesc scene =
        parseScene(R"({"cloth": {"sheet": {"rows": 4, "cols": 4, "spacing": 0.1},
                                                     "particle_mass": 0.01, "stiffness": 5},
                                           "simulation": {"time_step": 0.01, "substeps": 4}})",
                   "four.json", kScenes);
    Simulation sim(scene);
    CHECK(sim.substeps() == 4);
    sim.step();
    CHECK(sim.cloth().stepCount() == 4);
    CHECK(sim.cloth().time() == Approx(0.01));
    // The same as stepping a cloth four times by dt / 4.
    Simulation ref(parseScene(R"({"cloth": {"sheet": {"rows": 4, "cols": 4, "spacing": 0.1},
                                            "particle_mass": 0.01, "stiffness": 5},
                                  "simulation": {"time_step": 0.0025}})",
                              "ref.json", kScenes));
    for (int k = 0; k < 4; ++k)
        ref.step();
    CHECK(sim.cloth().positions() == ref.cloth().positions());
}

TEST_CASE("auto sub-steps in a scene with rigid bodies sub-step the cloth in the world",
          "[scenes][substeps]") {
    if (!rigidBodiesAvailable()) {
        WARN("skipped: no Bullet integration");
        return;
    }
    Simulation sim(parseScene(R"({"cloth": {"sheet": {"rows": 4, "cols": 4, "spacing": 0.1},
                                            "particle_mass": 0.001, "stiffness": 1e5},
                                  "simulation": {"time_step": 0.01, "duration": 1, "substeps": "auto"},
                                  "rigid_bodies": [{"shape": {"type": "plane", "offset": -1}}]})",
                              "world.json", kScenes));
    const int n = sim.substeps();
    CHECK(n > 1);
    sim.step();
    sim.step();
    CHECK(sim.cloth().stepCount() == 2u * static_cast<unsigned>(n));
    CHECK(allFinite(sim.cloth().positions()));
}

TEST_CASE("the summary says BROKEN, with where, when the strain bound was broken",
          "[scenes][runner][limiter]") {
    // Experiment I with a limiter allowed one sweep per step (and no attachments or warm start
    // to help it): it stops at its cap and the sheet stretches beyond 0.1 + 0.001. The summary
    // must say so, with the peak measured after every step; the unchanged scene holds it.
    const fs::path dir = fs::path(DRAPE_TEST_OUT_DIR) / "broken_bound";
    fs::create_directories(dir);
    std::ifstream in(kScenes / "experiment1_suspended_sheet.json");
    std::stringstream text;
    text << in.rdbuf();
    std::string json = text.str();
    const std::string limiter =
        R"("strain_limit": {"method": "stress_ordered", "max_strain": 0.10})";
    const auto at = json.find(limiter);
    REQUIRE(at != std::string::npos);
    json.replace(at, limiter.size(),
                 R"("strain_limit": {"method": "stress_ordered", "max_strain": 0.10, )"
                 R"("max_rounds": 1, "warm_start": 0, "long_range_attachments": false})");
    std::ofstream(dir / "capped.json") << json;
    auto summaryOf = [&](const fs::path& scene, const std::string& name) {
        RunOptions o;
        o.scene = scene;
        o.outDir = dir / name;
        o.steps = 100;
        o.render = false;
        o.video = false;
        std::ostringstream log;
        const RunResult r = runScene(o, log);
        std::ifstream s(o.outDir / "summary.txt");
        std::stringstream all;
        all << s.rdbuf();
        return std::make_pair(r, all.str());
    };
    const auto [capped, cappedText] = summaryOf(dir / "capped.json", "capped");
    INFO(cappedText);
    CHECK(capped.peakStepStrain > 0.101);
    CHECK(capped.stepsOverBound > 0);
    CHECK(cappedText.find("BROKEN after") != std::string::npos);
    CHECK(cappedText.find("held after every step") == std::string::npos);
    const auto [held, heldText] = summaryOf(kScenes / "experiment1_suspended_sheet.json", "held");
    CHECK(held.peakStepStrain <= 0.101);
    CHECK(held.stepsOverBound == 0u);
    CHECK(heldText.find("held after every step") != std::string::npos);
}
