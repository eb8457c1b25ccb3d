// Scene files: every shipped scene parses, the paper's experiments behave as the paper's
// (their files drive the physics), and broken scenes are refused with the path of the
// offending field.
#include "drape_samples/check.hpp"
#include "drape_samples/scene.hpp"
#include "drape_samples/simulation.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>

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

SceneDesc parse(const std::string& text) {
    return parseScene(text, "test.json", kScenes);
}

/// The message parseScene throws for `text` (fails the test if it does not throw).
std::string errorOf(const std::string& text) {
    try {
        parse(text);
    } catch (const SceneError& e) {
        return e.what();
    }
    FAIL("scene was accepted: " << text);
    return {};
}

const char* kCloth = R"("cloth": {"sheet": {"rows": 4, "cols": 5, "spacing": 0.1},
                                  "particle_mass": 0.01, "stiffness": 50.0})";

std::string withCloth(const std::string& rest) {
    return std::string("{") + kCloth + (rest.empty() ? "" : ", " + rest) + "}";
}

} // namespace

TEST_CASE("every shipped scene parses, has a description and a unique name", "[scene]") {
    const auto scenes = shippedScenes();
    REQUIRE(scenes.size() >= 6);
    std::set<std::string> names;
    for (const auto& file : scenes) {
        INFO(file);
        const SceneDesc s = loadScene(file);
        CHECK_FALSE(s.description.empty());
        CHECK(names.insert(s.name).second);
        CHECK(s.stepCount() > 0);
    }
}

TEST_CASE("Experiment I's file is the paper's sheet: its first step is free fall", "[scene]") {
    // The springs start at rest, so in the first step only gravity and the damping act: every
    // free particle drops g dt^2 / 2 and moves at g dt (Velocity-Verlet, damping C_d dt / m =
    // 0.1 % of that), and the two pins stay. Particle mass m = 0.5 and g = 9.8 (the paper's)
    // give the kinetic energy (n - 2) m (g dt)^2 / 2.
    Simulation sim(loadScene(kScenes / "experiment1_suspended_sheet.json"));
    const Cloth& cloth = sim.cloth();
    REQUIRE(cloth.particleCount() == 35 * 35);
    const Vec3List x0 = cloth.positions();
    sim.step();
    const double g = 9.8, dt = 0.01, m = 0.5;
    std::size_t fixed = 0;
    for (std::size_t i = 0; i < x0.size(); ++i) {
        const Vec3 d = cloth.positions()[i] - x0[i];
        if (d.isZero()) {
            ++fixed;
            continue;
        }
        INFO("particle " << i);
        CHECK(-d.y() == Approx(0.5 * g * dt * dt).epsilon(2e-3));
    }
    CHECK(fixed == 2);
    const double n = static_cast<double>(cloth.particleCount());
    CHECK(cloth.kineticEnergy() == Approx((n - 2.0) * 0.5 * m * (g * dt) * (g * dt)).epsilon(1e-2));
}

TEST_CASE("Experiment II's file drops the tablecloth freely onto a desk", "[scene]") {
    const SceneDesc scene = loadScene(kScenes / "experiment2_tablecloth.json");
    if (!rigidBodiesAvailable()) {
        WARN("skipped: no Bullet integration in this build");
        return;
    }
    // Nothing holds the cloth: for its first second it falls as one piece, as a particle of
    // mass m under gravity and the drag C_d v falls: y(t) = -(g / c)(t - (1 - e^{-ct}) / c),
    // c = C_d / m (Velocity-Verlet's error is O(dt^2)).
    Simulation sim(scene);
    const Cloth& cloth = sim.cloth();
    const Vec3List x0 = cloth.positions();
    for (int k = 0; k < 100; ++k)
        sim.step();
    const double g = 9.8, t = sim.time();
    const double c = scene.cloth.damping / cloth.masses()[0];
    const double drop = (g / c) * (t - (1.0 - std::exp(-c * t)) / c);
    double lo = 1e300, hi = -1e300;
    for (std::size_t i = 0; i < x0.size(); ++i) {
        const double d = x0[i].y() - cloth.positions()[i].y();
        lo = std::min(lo, d);
        hi = std::max(hi, d);
    }
    CHECK(hi - lo <= 1e-9 * drop); // one piece: no pin, no spring stretched
    CHECK(lo == Approx(drop).epsilon(1e-3));
    CHECK(sim.contactCount() == 0);
    // The desk is below it, smaller than the cloth: within 5 s the cloth touches it, and its
    // overhang hangs below the desk top.
    double lowest = 1e300;
    for (int k = 0; k < 400; ++k) {
        sim.step();
        if (sim.contactCount() > 0) break;
    }
    CHECK(sim.contactCount() > 0);
    for (int k = 0; k < 100; ++k)
        sim.step();
    for (const Vec3& x : cloth.positions())
        lowest = std::min(lowest, x.y());
    CHECK(lowest < sim.bodyPosition("desk_top").y() - 10.0);
}

TEST_CASE("a minimal scene gets the documented defaults", "[scene]") {
    const SceneDesc s = parse(withCloth(""));
    // One set of defaults: a scene leaves out what ClothSettings leaves out (samples/SCENES.md,
    // "Defaults"): stress-ordered limiting at 10 %, automatic sub-steps.
    const ClothSettings cpp;
    CHECK(s.cloth.limiter.kind == cpp.limiter.kind);
    CHECK(s.cloth.limiter.kind == LimiterKind::StressOrdered);
    CHECK(s.cloth.limiter.maxStrain == cpp.limiter.maxStrain);
    CHECK(s.cloth.limiter.warmStart == cpp.limiter.warmStart);
    CHECK(s.cloth.relativeDamping == cpp.relativeDamping);
    CHECK(s.cloth.damping == cpp.damping);
    CHECK(s.autoSubsteps);
    CHECK(parse(withCloth(R"("strain_limit": {"method": "none"})")).cloth.limiter.kind ==
          LimiterKind::None);
    CHECK(s.timeStep == 0.01);
    CHECK(s.duration == 5.0);
    CHECK(s.cloth.gravity.isApprox(Vec3(0.0, -9.81, 0.0)));
    CHECK(s.cloth.aero.airDensity == 0.0);
    CHECK_FALSE(s.wind);
    CHECK(s.camera.width == 640);
    CHECK(s.output.fps == 25.0);
    CHECK(s.stepCount() == 500);
}

TEST_CASE("broken scenes are refused with the path of the field", "[scene][errors]") {
    using Catch::Matchers::Contains;
    CHECK_THAT(errorOf("{\"cloth\": "), Contains("test.json: not valid JSON"));
    CHECK_THAT(errorOf(R"({"cloth": {"sheet": {"rows": 4, "cols": 5, "spacing": 1e999}}})"),
               Contains("test.json: not usable JSON: "));
    CHECK_THAT(errorOf("[1, 2]"), Contains("(top level): expected an object, got array"));
    CHECK_THAT(errorOf("{}"), Contains("cloth: required field is missing"));
    CHECK_THAT(errorOf(withCloth(R"("camera": {"fov": 40})")),
               Contains("camera.fov: unknown field"));
    CHECK_THAT(errorOf(withCloth(R"("simulatoin": {})")), Contains("simulatoin: unknown field"));
    CHECK_THAT(errorOf(R"({"cloth": {"sheet": {"rows": 4.5, "cols": 5, "spacing": 0.1},
                           "particle_mass": 0.01, "stiffness": 50.0}})"),
               Contains("cloth.sheet.rows: expected an integer, got 4.5"));
    CHECK_THAT(errorOf(R"({"cloth": {"sheet": {"rows": 1, "cols": 5, "spacing": 0.1},
                           "particle_mass": 0.01, "stiffness": 50.0}})"),
               Contains("cloth.sheet.rows: must be in [2,"));
    CHECK_THAT(errorOf(R"({"cloth": {"sheet": {"rows": 4000, "cols": 4000, "spacing": 0.1},
                           "particle_mass": 0.01, "stiffness": 50.0}})"),
               Contains("exceeds the limit"));
    CHECK_THAT(errorOf(R"({"cloth": {"sheet": {"rows": 4, "cols": 5, "spacing": 0.1},
                           "particle_mass": -0.01, "stiffness": 50.0}})"),
               Contains("cloth.particle_mass: must be in [1e-12, 1e+06] kg, got -0.01"));
    CHECK_THAT(errorOf(R"({"cloth": {"sheet": {"rows": 4, "cols": 5, "spacing": 0.1},
                           "stiffness": 50.0, "material": {"density": -3}}})"),
               Contains("cloth.material.density: must be in"));
    CHECK_THAT(errorOf(R"({"cloth": {"sheet": {"rows": 4, "cols": 5, "spacing": 0.1},
                           "mesh": {"file": "x.obj"}, "particle_mass": 0.01, "stiffness": 5}})"),
               Contains("exactly one of cloth.sheet"));
    CHECK_THAT(errorOf(withCloth(R"("simulation": {"time_step": 0})")),
               Contains("simulation.time_step: must be in [1e-09, 10] s, got 0"));
    CHECK_THAT(errorOf(withCloth(R"("simulation": {"integrator": "leapfrog"})")),
               Contains("simulation.integrator: unknown value \"leapfrog\""));
    CHECK_THAT(errorOf(withCloth(R"("simulation": {"gravity": [0, -9.8]})")),
               Contains("simulation.gravity: expected an array of 3 numbers"));
    CHECK_THAT(errorOf(withCloth(R"("simulation": {"time_step": 1e-9, "duration": 1000})")),
               Contains("steps exceeds the limit"));
    CHECK_THAT(errorOf(withCloth(R"("output": {"fps": 1000}, "simulation": {"duration": 1000})")),
               Contains("frames exceeds the limit"));
    CHECK_THAT(errorOf(withCloth(R"("wind": {"velocity": [5, 0, 0]})")),
               Contains("wind: wind acts through the air: add \"air\": {} to cloth (air's "
                        "density, 1.2 kg per cubic metre)"));
    // In a centimetre scene the advice is air's density in its units (review 16: "1.2 kg/m^3"
    // copied into such a scene was a million airs), and what it names works.
    CHECK_THAT(errorOf(R"({"units_per_metre": 100,
                           "cloth": {"sheet": {"rows": 4, "cols": 4, "spacing": 10}},
                           "wind": {"velocity": [500, 0, 0]}})"),
               Contains("1.2e-06 kg per cubic scene unit at units_per_metre 100"));
    const SceneDesc windy = parse(R"({"units_per_metre": 100,
                                      "cloth": {"sheet": {"rows": 4, "cols": 4, "spacing": 10},
                                                "air": {}},
                                      "wind": {"velocity": [500, 0, 0]}})");
    CHECK(windy.cloth.aero.airDensity == Approx(1.2e-6));
    // In kilometres air is 1.2e9 kg per cubic unit: the advice's value is accepted (review 17:
    // the range was in metres).
    const SceneDesc km = parse(R"({"units_per_metre": 0.001,
                                   "cloth": {"sheet": {"rows": 4, "cols": 4, "spacing": 0.001},
                                             "air": {"density": 1.2e9}},
                                   "wind": {"velocity": [0.005, 0, 0]}})");
    CHECK(km.cloth.aero.airDensity == Approx(1.2e9));
    CHECK_THAT(errorOf(R"({"units_per_metre": 0.001,
                           "cloth": {"sheet": {"rows": 4, "cols": 4, "spacing": 0.001},
                                     "air": {"density": 1e14}}})"),
               Contains("kg per cubic scene unit"));
    CHECK_THAT(errorOf(withCloth(R"("pins": [{"velocity": [0, 1, 0]}])")),
               Contains("pins[0]: selects nothing"));
    CHECK_THAT(errorOf(withCloth(R"("pins": [{"groups": ["rail"]}])")),
               Contains("pins[0].groups: named groups come from a mesh file"));
    CHECK_THAT(errorOf(withCloth(R"("pins": [{"box": {"min": [1, 0, 0], "max": [0, 1, 1]}}])")),
               Contains("pins[0].box.min: min must not exceed max"));
    CHECK_THAT(
        errorOf(withCloth(R"("rigid_bodies": [{"shape": {"type": "box", "half_extents": [1, 1, 1]}},
                                                      {"shape": {"type": "sphere", "radius": "big"}}])")),
        Contains("rigid_bodies[1].shape.radius: expected a number, got string"));
    CHECK_THAT(errorOf(withCloth(R"("rigid_bodies": [{"shape": {"type": "cone"}}])")),
               Contains("rigid_bodies[0].shape.type: unknown value \"cone\""));
    CHECK_THAT(errorOf(withCloth(R"("rigid_bodies": [{"shape": {"type": "sphere", "radius": 1},
                                                       "mass": 2}])")),
               Contains("rigid_bodies[0].mass: only dynamic bodies have a mass"));
    CHECK_THAT(errorOf(withCloth(
                   R"("rigid_bodies": [{"name": "a", "shape": {"type": "sphere", "radius": 1}},
                                                      {"name": "a", "shape": {"type": "sphere", "radius": 1}}])")),
               Contains("rigid_bodies[1].name: \"a\" is used by rigid_bodies[0] already"));
    CHECK_THAT(errorOf(withCloth(R"("attachments": [{"body": "pole", "indices": [0]}])")),
               Contains("attachments[0].body: no rigid body named \"pole\""));
    CHECK_THAT(errorOf(withCloth(R"("camera": {"position": [0, 0, 1], "target": [0, 0, 1]})")),
               Contains("camera.target: must differ from position"));
    CHECK_THAT(errorOf(withCloth(R"("camera": {"width": 100000})")),
               Contains("camera.width: must be in [16, 8192]"));
    CHECK_THAT(errorOf(withCloth(R"("cloth2": 1)")), Contains("cloth2: unknown field"));
    CHECK_THAT(
        errorOf(R"({"cloth": {"sheet": {"rows": 4, "colls": 5, "spacing": 0.1},
                           "particle_mass": 0.01, "stiffness": 50.0}})"),
        Contains("cloth.sheet.colls: unknown field (did you mean \"cols\"? fields allowed here: "));
    CHECK_THAT(errorOf(R"({"cloth": {"sheet": {"rows": 4, "cols": 5, "spacing": 0.1},
                           "particle_mass": 0.01, "stiffness": 50.0, "front_color": [2, 0, 0]}})"),
               Contains("cloth.front_color[0]: colour components are in [0, 1], got 2"));
}

TEST_CASE("a key given twice in one object is refused, named with its path", "[scene][errors]") {
    using Catch::Matchers::Contains;
    CHECK_THAT(errorOf(R"({"cloth": {"sheet": {"rows": 4, "cols": 5, "spacing": 0.1, "rows": 6},
                           "particle_mass": 0.01, "stiffness": 50.0}})"),
               Contains("test.json: cloth.sheet.rows: duplicate key (the object sets \"rows\" more "
                        "than once"));
    CHECK_THAT(errorOf(withCloth(R"("name": "a", "name": "b")")),
               Contains("test.json: name: duplicate key"));
    CHECK_THAT(errorOf(withCloth(R"("cloth": 1)")), Contains("test.json: cloth: duplicate key"));
    // Inside arrays: the element's index is part of the path.
    CHECK_THAT(errorOf(withCloth(R"("pins": [{"indices": [0]},
                                             {"box": {"min": [0, 0, 0], "max": [1, 1, 1],
                                                      "min": [-1, -1, -1]}}])")),
               Contains("test.json: pins[1].box.min: duplicate key"));
    CHECK_THAT(errorOf(withCloth(R"("rigid_bodies": [{"shape": {"type": "sphere", "radius": 1}},
                                   {"shape": {"type": "sphere", "radius": 1, "radius": 2}}])")),
               Contains("test.json: rigid_bodies[1].shape.radius: duplicate key"));
    CHECK_THAT(errorOf(withCloth(R"("pins": [{"grid": [[0, 0], [0, 1]], "grid": [[1, 1]]}])")),
               Contains("test.json: pins[0].grid: duplicate key"));
    // The same key in two different objects is fine.
    CHECK_NOTHROW(parse(withCloth(R"("pins": [{"indices": [0]}, {"indices": [1]}])")));
}

TEST_CASE("nesting beyond 64 levels and strings holding NUL are refused before any work",
          "[scene][errors]") {
    using Catch::Matchers::Contains;
    // 100,000 nested arrays: refused at the 65th level, not parsed into memory first.
    const std::string deep =
        withCloth(R"("description": )" + std::string(100000, '[') + std::string(100000, ']'));
    CHECK_THAT(errorOf(deep), Contains("nested deeper than 64"));
    // 64 levels are fine as JSON (the scene then says the field is of the wrong type).
    const std::string ok =
        withCloth(R"("description": )" + std::string(63, '[') + std::string(63, ']'));
    CHECK_THAT(errorOf(ok), !Contains("nested deeper"));
    // A NUL inside a string would cut a file name there and name another file.
    CHECK_THAT(errorOf(R"({"cloth": {"mesh": "curtain.obj\u0000.junk"}})"),
               Contains("test.json: cloth.mesh: holds a NUL character"));
    CHECK_THAT(errorOf(withCloth(R"("name": "a\u0000b")")),
               Contains("test.json: name: holds a NUL character"));
}

TEST_CASE("an unknown key is reported, with the key it resembles, before any missing field",
          "[scene][errors]") {
    using Catch::Matchers::Contains;
    // "stifness" leaves the cloth without a stiffness: the typo is named, not "no stiffness".
    const std::string stiff = errorOf(R"({"cloth": {"sheet": {"rows": 4, "cols": 5, "spacing": 0.1},
                                          "particle_mass": 0.01, "stifness": 50.0}})");
    CHECK_THAT(stiff, Contains("cloth.stifness: unknown field (did you mean \"stiffness\"?"));
    CHECK_THAT(stiff, !Contains("no stiffness"));
    const std::string mass = errorOf(R"({"cloth": {"sheet": {"rows": 4, "cols": 5, "spacing": 0.1},
                                         "particle_mas": 0.01, "stiffness": 50.0}})");
    CHECK_THAT(mass,
               Contains("cloth.particle_mas: unknown field (did you mean \"particle_mass\"?"));
    CHECK_THAT(mass, !Contains("no mass"));
    // A misspelt required field: the typo, not "required field is missing".
    CHECK_THAT(errorOf(R"({"cloth": {"sheet": {"rows": 4, "cols": 5, "spacng": 0.1},
                           "particle_mass": 0.01, "stiffness": 50.0}})"),
               Contains("cloth.sheet.spacng: unknown field (did you mean \"spacing\"?"));
    CHECK_THAT(errorOf(R"({"clth": {"sheet": {"rows": 4, "cols": 5, "spacing": 0.1}}})"),
               Contains("test.json: clth: unknown field (did you mean \"cloth\"?"));
    CHECK_THAT(errorOf(withCloth(R"("simulation": {"Time_Step": 0.01})")),
               Contains("simulation.Time_Step: unknown field (did you mean \"time_step\"?"));
    CHECK_THAT(
        errorOf(withCloth(R"("rigid_bodies": [{"shape": {"type": "sphere", "raduis": 1}}])")),
        Contains("rigid_bodies[0].shape.raduis: unknown field (did you mean \"radius\"?"));
    // Nothing close: no suggestion, the list of allowed fields.
    CHECK_THAT(errorOf(withCloth(R"("camera": {"zoom": 2})")),
               Contains("camera.zoom: unknown field (fields allowed here: fov_deg, height, "
                        "position, target, up, width)"));
    // A field of another shape type is still refused, after the type is known.
    CHECK_THAT(errorOf(withCloth(R"("rigid_bodies": [{"shape": {"type": "box", "radius": 1,
                                                               "half_extents": [1, 1, 1]}}])")),
               Contains("rigid_bodies[0].shape.radius: unknown field"));
}

TEST_CASE("every number is checked against its physical range, named in the message",
          "[scene][errors][ranges]") {
    using Catch::Matchers::Contains;
    // Absurd but finite values that used to run and write inf or nan.
    CHECK_THAT(errorOf(withCloth(R"("simulation": {"gravity": [0, -1e45, 0]})")),
               Contains("simulation.gravity[1]: must be in [-10000, 10000] m/s^2, got -1e+45"));
    CHECK_THAT(errorOf(withCloth(R"("simulation": {"gravity": [1e308, 0, 0]})")),
               Contains("simulation.gravity[0]: must be in [-10000, 10000] m/s^2, got 1e+308"));
    CHECK_THAT(errorOf(withCloth(R"("rigid_bodies": [{"shape": {"type": "plane"}}],
                             "collision": {"thickness": 1e300})")),
               Contains("collision.thickness: must be in [1e-06, 100000] m, got 1e+300"));
    CHECK_THAT(errorOf(R"({"cloth": {"sheet": {"rows": 4, "cols": 5, "spacing": 1e300},
                           "particle_mass": 0.01, "stiffness": 50.0}})"),
               Contains("cloth.sheet.spacing: must be in [1e-06, 100000] m, got 1e+300"));
    CHECK_THAT(errorOf(R"({"cloth": {"mesh": {"file": "x.obj", "scale": 1e300},
                           "particle_mass": 0.01, "stiffness": 50.0}})"),
               Contains("cloth.mesh.scale: must be in [1e-06, 1e+06], got 1e+300"));
    CHECK_THAT(errorOf(R"({"cloth": {"mesh": {"file": "x.obj", "scale": [1, 0, 1]},
                           "particle_mass": 0.01, "stiffness": 50.0}})"),
               Contains("cloth.mesh.scale[1]: must be in [1e-06, 1e+06], got 0"));
    CHECK_THAT(errorOf(R"({"cloth": {"sheet": {"rows": 4, "cols": 5, "spacing": 0.1},
                           "particle_mass": 0.01, "stiffness": 1e300}})"),
               Contains("cloth.stiffness: must be in [1e-09, 1e+12] N/m, got 1e+300"));
    CHECK_THAT(errorOf(R"({"cloth": {"sheet": {"rows": 4, "cols": 5, "spacing": 0.1},
                           "particle_mass": 1e-300, "stiffness": 5}})"),
               Contains("cloth.particle_mass: must be in [1e-12, 1e+06] kg, got 1e-300"));
    CHECK_THAT(errorOf(withCloth(R"("pins": [{"indices": [0], "velocity": [0, 1e20, 0]}])")),
               Contains("pins[0].velocity[1]: must be in [-10000, 10000] m/s, got 1e+20"));
    CHECK_THAT(errorOf(withCloth(R"("rigid_bodies": [{"shape": {"type": "sphere", "radius": 1},
                                     "motion": "dynamic", "linear_velocity": [1e9, 0, 0]}])")),
               Contains("rigid_bodies[0].linear_velocity[0]: must be in [-10000, 10000] m/s"));
    CHECK_THAT(errorOf(withCloth(R"("rigid_bodies": [{"shape": {"type": "box",
                                     "half_extents": [1, 1e200, 1]}}])")),
               Contains("rigid_bodies[0].shape.half_extents[1]: must be in [1e-06, 100000] m"));
    CHECK_THAT(errorOf(withCloth(R"("rigid_bodies": [{"shape": {"type": "sphere", "radius": 1},
                                     "position": [0, 0, 1e12]}])")),
               Contains("rigid_bodies[0].position[2]: must be in [-1e+06, 1e+06] m, got 1e+12"));
    CHECK_THAT(errorOf(withCloth(R"("camera": {"fov_deg": 179})")),
               Contains("camera.fov_deg: must be in (0, 179) degrees, got 179"));
    CHECK_THAT(errorOf(withCloth(R"("simulation": {"duration": 1e30})")),
               Contains("simulation.duration: must be in [1e-09, 1e+06] s, got 1e+30"));
    CHECK_THAT(errorOf(withCloth(R"("output": {"fps": 1e-300})")),
               Contains("output.fps: must be in [1e-06, 1e+06] 1/s, got 1e-300"));
    CHECK_THAT(errorOf(withCloth(R"("wind": {"velocity": [1e300, 0, 0]})")),
               Contains("wind.velocity[0]: must be in [-10000, 10000] m/s"));
    // Each number in range, the product out of it: the sheet would leave the world.
    CHECK_THAT(errorOf(R"({"cloth": {"sheet": {"rows": 4, "cols": 500, "spacing": 10000},
                           "particle_mass": 0.01, "stiffness": 50.0}})"),
               Contains("cloth.sheet: the sheet reaches (4.99e+06, 0, 0), outside the [-1e+06, "
                        "1e+06] m coordinate range"));
    // Values at the ends of their ranges are accepted.
    CHECK_NOTHROW(parse(withCloth(R"("simulation": {"gravity": [0, -10000, 0], "time_step": 10,
                                                    "duration": 10})")));
    CHECK_NOTHROW(parse(withCloth(R"("rigid_bodies": [{"shape": {"type": "plane"}}],
                                     "collision": {"thickness": 1e-6})")));
}

TEST_CASE("simulation.substeps: an integer or \"auto\", given once", "[scene][substeps]") {
    using Catch::Matchers::Contains;
    CHECK(parse(withCloth("")).autoSubsteps); // the default, as Cloth::step's
    CHECK(parse(withCloth(R"("simulation": {"substeps": 7})")).substeps == 7);
    CHECK_FALSE(parse(withCloth(R"("simulation": {"substeps": 7})")).autoSubsteps);
    CHECK(parse(withCloth(R"("simulation": {"substeps": "auto"})")).autoSubsteps);
    CHECK(parse(withCloth(R"("rigid_bodies": [{"shape": {"type": "plane"}}],
                            "collision": {"substeps": 3})"))
              .substeps == 3);
    CHECK_FALSE(parse(withCloth(R"("rigid_bodies": [{"shape": {"type": "plane"}}],
                                  "collision": {"substeps": 3})"))
                    .autoSubsteps);
    CHECK_THAT(errorOf(withCloth(R"("simulation": {"substeps": "automatic"})")),
               Contains("simulation.substeps: expected an integer in [1, 10000] or \"auto\", got "
                        "\"automatic\""));
    CHECK_THAT(errorOf(withCloth(R"("simulation": {"substeps": 0})")),
               Contains("simulation.substeps: must be in [1, 10000], got 0"));
    CHECK_THAT(errorOf(withCloth(R"("simulation": {"substeps": "auto"},
                                    "rigid_bodies": [{"shape": {"type": "plane"}}],
                                    "collision": {"substeps": 3})")),
               Contains("collision.substeps: give the sub-steps once, as simulation.substeps"));
}

TEST_CASE("a run that cannot end within an hour is named before it starts", "[scene][limits]") {
    using Catch::Matchers::Contains;
    // 10,000 particles for 4e7 steps: each factor within its limit, 4e11 particle-steps in
    // all, more than 1.1 hours even at drape's cheapest step.
    auto scene = [](double duration) {
        return parse(R"({"cloth": {"sheet": {"rows": 100, "cols": 100, "spacing": 0.01},
                                    "particle_mass": 0.001, "stiffness": 1.0},
                         "simulation": {"time_step": 0.001, "substeps": 1, "duration": )" +
                     std::to_string(duration) + R"(}, "output": {"fps": 2}})");
    };
    const Simulation longRun(scene(40000.0));
    REQUIRE(longRun.warnings().size() == 1);
    CHECK_THAT(longRun.warnings()[0],
               Contains("4e+11 particle-steps (10000 particles x 40000000 steps x 1 cloth "
                        "sub-steps): at least 1.1") &&
                   Contains("hours"));
    // An hour's worth at that bound is fine.
    CHECK(Simulation(scene(36000.0)).warnings().empty());
}

TEST_CASE("collision.triangle_contacts: off by default, a boolean", "[scene][contacts]") {
    using Catch::Matchers::Contains;
    const std::string body =
        R"("rigid_bodies": [{"shape": {"type": "capsule", "radius": 0.01, "height": 0.5}}], )";
    CHECK_FALSE(parse(withCloth(body + R"("collision": {})")).collision->triangleContacts);
    CHECK(parse(withCloth(body + R"("collision": {"triangle_contacts": true})"))
              .collision->triangleContacts);
    CHECK_THAT(errorOf(withCloth(body + R"("collision": {"triangle_contacts": "yes"})")),
               Contains("collision.triangle_contacts"));
}

TEST_CASE("mesh.degenerate_triangles: drop (the default) or refuse", "[scene][mesh]") {
    using Catch::Matchers::Contains;
    const auto mesh = [](const std::string& extra) {
        return R"({"cloth": {"mesh": {"file": "x.obj")" + extra +
               R"(}, "particle_mass": 0.01, "stiffness": 50.0}})";
    };
    CHECK_FALSE(parse(mesh("")).mesh->refuseDegenerate);
    CHECK_FALSE(parse(mesh(R"(, "degenerate_triangles": "drop")")).mesh->refuseDegenerate);
    CHECK(parse(mesh(R"(, "degenerate_triangles": "refuse")")).mesh->refuseDegenerate);
    CHECK_THAT(errorOf(mesh(R"(, "degenerate_triangles": "fix")")),
               Contains("cloth.mesh.degenerate_triangles: unknown value \"fix\" (expected one of "
                        "\"drop\", \"refuse\")"));
}

TEST_CASE("a missing or unreadable scene file is named", "[scene][errors]") {
    using Catch::Matchers::Contains;
    CHECK_THROWS_WITH(loadScene("/nonexistent/scene.json"),
                      Contains("scene.json: scene file not found"));
    CHECK_THROWS_WITH(loadScene(kScenes), Contains("is a folder"));
}

TEST_CASE("the JSON examples in SCENES.md parse", "[scene][docs]") {
    std::ifstream in(fs::path(DRAPE_SAMPLES_DIR) / "SCENES.md");
    REQUIRE(in);
    std::stringstream ss;
    ss << in.rdbuf();
    const std::string doc = ss.str();
    std::size_t pos = 0, blocks = 0;
    while ((pos = doc.find("```json\n", pos)) != std::string::npos) {
        const std::size_t start = pos + 8;
        const std::size_t end = doc.find("```", start);
        REQUIRE(end != std::string::npos);
        const std::string block = doc.substr(start, end - start);
        INFO(block);
        // Whole scenes parse as they are; fragments (a field and its value) inside a scene.
        const std::string text = block.front() == '{' ? block : withCloth(block);
        CHECK_NOTHROW(parse(text));
        ++blocks;
        pos = end + 3;
    }
    CHECK(blocks >= 2);
}

// units_per_metre: the file's defaults are ClothSettings::inUnits' and
// BulletClothSettings::inUnits' for its unit, so the same scene written in centimetres runs
// as in metres: a 0.9 m cloth of the default cotton (no mass, no stiffness given) falls flat
// onto the floor, lands at the 1 cm contact thickness and rests.
TEST_CASE("units_per_metre: a scene in centimetres runs as the same scene in metres",
          "[scene][units]") {
    auto scene = [](double u) {
        char text[1024];
        std::snprintf(text, sizeof text, R"({
            "units_per_metre": %g,
            "cloth": {"sheet": {"rows": 10, "cols": 10, "spacing": %g, "origin": [%g, %g, %g],
                                "u_axis": [1, 0, 0], "v_axis": [0, 0, 1]}},
            "simulation": {"time_step": 0.016666666666666666, "duration": 1.5,
                           "gravity": [0, %g, 0]},
            "rigid_bodies": [{"name": "floor",
                              "shape": {"type": "plane", "normal": [0, 1, 0], "offset": 0}}]})",
                      u, 0.1 * u, -0.45 * u, 0.3 * u, -0.45 * u, -10.0 * u);
        return parse(text);
    };
    const SceneDesc m = scene(1.0), cm = scene(100.0);
    CHECK(cm.unitsPerMetre == 100.0);
    CHECK(cm.cloth.sleep.distance == Approx(100.0 * m.cloth.sleep.distance));
    CHECK(cm.cloth.stretchWaveSpeed == Approx(100.0 * m.cloth.stretchWaveSpeed));
    Simulation a(m), b(cm);
    CHECK(b.substeps() == a.substeps());
    double worst = 0.0, lowest = 1.0;
    while (a.steps() < m.stepCount()) {
        a.step();
        b.step();
        for (std::size_t i = 0; i < a.cloth().particleCount(); ++i) {
            worst = std::max(worst,
                             (b.cloth().positions()[i] / 100.0 - a.cloth().positions()[i]).norm());
            lowest = std::min(lowest, b.cloth().positions()[i].y() / 100.0);
        }
    }
    UNSCOPED_INFO("largest difference " << worst << " m, lowest particle " << lowest << " m");
    CHECK(a.cloth().totalMass() == Approx(0.2 * 0.81).epsilon(1e-12)); // 200 g/m^2 cotton
    CHECK(b.cloth().totalMass() == Approx(a.cloth().totalMass()).epsilon(1e-12));
    CHECK(lowest == Approx(0.01).margin(1e-6)); // the contact thickness, in metres
    CHECK(worst < 1e-9);
}

TEST_CASE("units_per_metre converts the defaults a file leaves out", "[scene][units]") {
    const SceneDesc cm = parse(R"({"units_per_metre": 100,
                                   "cloth": {"sheet": {"rows": 4, "cols": 5, "spacing": 10},
                                             "air": {}}})");
    CHECK(cm.cloth.gravity.isApprox(Vec3(0.0, -981.0, 0.0)));
    CHECK(cm.cloth.aero.airDensity == Approx(1.2e-6).epsilon(1e-12));
    CHECK(cm.camera.position.isApprox(Vec3(0.0, 0.0, 1000.0)));
    CHECK(cm.cloth.material.thickness == Approx(0.05).epsilon(1e-12));
    CHECK(cm.cloth.material.density == Approx(4e-4).epsilon(1e-12));
    CHECK(cm.cloth.selfCollision.thickness == Approx(1.0).epsilon(1e-12));
}

TEST_CASE("units_per_metre must be a positive number in range", "[scene][units][errors]") {
    CHECK_THAT(errorOf(withCloth(R"("units_per_metre": 0)")),
               Catch::Matchers::Contains("units_per_metre"));
    CHECK_THAT(errorOf(withCloth(R"("units_per_metre": 1e4)")),
               Catch::Matchers::Contains("units_per_metre"));
    CHECK_THAT(errorOf(withCloth(R"("units_per_metre": "cm")")),
               Catch::Matchers::Contains("units_per_metre"));
}

TEST_CASE("a fixed simulation.substeps beyond the limit is refused with the count the file needs",
          "[scene][substeps]") {
    using Catch::Matchers::Contains;
    // The default cotton on a 5 cm sheet needs 10 cloth steps of 1/60 s. A file with 3 was
    // told "use 4 sub-steps" (of its cloth step of 1/180 s) and with 4 "3" (review 16); with or
    // without a world (a floor makes one), the refusal names simulation.substeps and 10, and
    // 10 runs.
    for (const bool world : {false, true}) {
        auto scene = [world](int substeps) {
            return parse(R"({"cloth": {"sheet": {"rows": 21, "cols": 21, "spacing": 0.05}},
                             "pins": [{"grid": [[0, 0], [0, 20]]}],)" +
                         std::string(world ? R"("rigid_bodies": [{"shape": {"type": "plane"},
                                                                  "position": [0, -3, 0]}],)"
                                           : "") +
                         R"("simulation": {"time_step": 0.0166666666666667, "duration": 0.1,
                                            "substeps": )" +
                         std::to_string(substeps) + "}}");
        };
        for (const int bad : {3, 4, 9}) {
            Simulation sim(scene(bad));
            INFO((world ? "world, " : "no world, ") << bad << " sub-steps");
            CHECK_THROWS_WITH(sim.step(), Contains("set simulation.substeps to at least 10"));
        }
        Simulation good(scene(10));
        for (int k = 0; k < 6; ++k)
            CHECK_NOTHROW(good.step());
    }
}

TEST_CASE("a cloth in water keeps within its drag's stability limit as it speeds up",
          "[scene][aero][substeps]") {
    // "auto" chose the count once, at t = 0 (80 for this sheet in a 1 m/s current); the drag's
    // limit falls as the sheet speeds up, it needed 333 by its 20th frame and the state went
    // non-finite after about 725 cloth steps (review 16). With air the cloth's own automatic
    // sub-steps now split the steps further as it needs. In a steady current the sheet, held
    // by its two top corners, streams downstream and comes to rest relative to the water.
    Simulation sim(parse(R"({"cloth": {"sheet": {"rows": 21, "cols": 21, "spacing": 0.05},
                                       "air": {"density": 1000}},
                             "pins": [{"grid": [[0, 0], [0, 20]]}],
                             "wind": {"velocity": [0, 0, 1]},
                             "simulation": {"time_step": 0.0166666666666667, "duration": 0.5}})"));
    for (int k = 0; k < 30; ++k)
        REQUIRE_NOTHROW(sim.step());
    double meanZ = 0.0;
    for (std::size_t i = 0; i < sim.cloth().particleCount(); ++i) {
        REQUIRE(sim.cloth().positions()[i].allFinite());
        meanZ += sim.cloth().positions()[i].z();
    }
    meanZ /= static_cast<double>(sim.cloth().particleCount());
    // The drag carries the sheet at most at the current's speed on the whole (gravity's share
    // is its terminal speed falling broadside through water, sqrt(2 rho_A g / (rho C_d)),
    // 6 cm/s); its free corners may whip faster.
    const Vec3 mean = sim.cloth().momentum() / sim.cloth().totalMass();
    INFO("mean z " << meanZ << " m, mean velocity " << mean.transpose() << " m/s");
    CHECK(meanZ > 0.1); // carried downstream
    CHECK(mean.norm() <= 1.0 + 0.06);
}

TEST_CASE("auto sub-steps count explicit Euler's own limit, and refuse it undamped",
          "[scene][substeps]") {
    using Catch::Matchers::Contains;
    // Explicit Euler is stable only as far as damping reaches (dt < C_d / (m omega^2) + c_s /
    // k): "auto" took Velocity-Verlet's count for it (2 / omega), and the sheet blew up
    // (review 17). It now takes drape-check's limit, and an undamped cloth is refused by name.
    auto scene = [](const std::string& damping) {
        return parse(R"({"cloth": {"sheet": {"rows": 11, "cols": 11, "spacing": 0.1})" + damping +
                     R"(},
                         "pins": [{"grid": [[0, 0], [0, 10]]}],
                         "simulation": {"time_step": 0.01, "duration": 1,
                                        "integrator": "explicit_euler"}})");
    };
    Simulation damped(scene(R"(, "damping": 0.002)"));
    const double limit = springsTimeStep(damped.cloth(), IntegratorKind::ExplicitEuler);
    REQUIRE(limit < 0.5 * damped.cloth().stableTimeStep()); // below Velocity-Verlet's
    INFO("explicit Euler's limit " << limit << " s, " << damped.substeps() << " sub-steps");
    CHECK(0.01 / damped.substeps() <= limit);
    double highest = 0.0;
    for (int k = 0; k < 100; ++k) {
        REQUIRE_NOTHROW(damped.step());
        for (const Vec3& v : damped.cloth().velocities())
            highest = std::max(highest, v.norm());
    }
    CHECK(highest < 10.0); // a sheet falling 1 s from its corners, not a blow-up
    std::string message;
    try {
        Simulation undamped(scene(""));
    } catch (const SceneError& e) {
        message = e.what();
    }
    CHECK_THAT(message, Contains("explicit_euler") && Contains("damping"));
    // Heavy damping: the damping alone flips the velocity's sign beyond 2 m / C_d (4e-4 s
    // for 10 g particles and C_d 50). "auto" took a count the cloth refused at its first step,
    // and a fixed count called stable overflowed (review 19); the count now keeps within it.
    Simulation heavy(parse(R"({"cloth": {"sheet": {"rows": 11, "cols": 11, "spacing": 0.05},
                                         "particle_mass": 0.01, "stiffness": 100,
                                         "damping": 50},
                               "pins": [{"grid": [[0, 0], [0, 10]]}],
                               "simulation": {"time_step": 0.01, "duration": 1,
                                              "integrator": "explicit_euler"}})"));
    CHECK(0.01 / heavy.substeps() <= 2.0 * 0.01 / 50.0);
    for (int k = 0; k < 50; ++k)
        REQUIRE_NOTHROW(heavy.step());
    for (const Vec3& v : heavy.cloth().velocities())
        CHECK(v.norm() < 1.0); // a sheet sagging through a thick fluid
}

TEST_CASE("a fixed count that the sinking cloth outruns is refused with the scene's advice",
          "[scene][aero][substeps]") {
    using Catch::Matchers::Contains;
    // A 0.5 m sheet of 50 g in water, 3 ms cloth steps: within the drag's limit at rest,
    // beyond it as the sheet sinks; it reached 1e63 m unchecked (review 17). The run is
    // refused at the step that would leave the limit, in the file's terms, and "auto" runs.
    const std::string sheet = R"("cloth": {"sheet": {"rows": 6, "cols": 6, "spacing": 0.1,
                                            "v_axis": [0, 0, -1]},
                                  "total_mass": 0.05, "stiffness": 20,
                                  "air": {"density": 1000}},)";
    Simulation fixed(parse("{" + sheet + R"("simulation": {"time_step": 0.03, "substeps": 10,
                                                           "duration": 3}})"));
    REQUIRE(fixed.cloth().aeroTimeStep(0.003) > 0.003);
    std::string message;
    int steps = 0;
    try {
        for (; steps < 100; ++steps)
            fixed.step();
    } catch (const StepError& e) {
        message = e.what();
    }
    INFO(message);
    CHECK(steps < 100);
    CHECK_THAT(message, Contains("simulation.substeps to \"auto\"") && Contains("drag"));
    for (const Vec3& x : fixed.cloth().positions())
        CHECK(x.norm() < 1.0);
    Simulation automatic(parse("{" + sheet + R"("simulation": {"time_step": 0.03,
                                                               "substeps": "auto",
                                                               "duration": 3}})"));
    for (int k = 0; k < 100; ++k)
        REQUIRE_NOTHROW(automatic.step());
}

TEST_CASE("when the drag's limit binds, \"auto\" advises a time step and a thinner fluid",
          "[scene][aero][substeps]") {
    using Catch::Matchers::Contains;
    // Water at 200 m/s: implicit Euler was advised, and refused in turn (every integrator
    // takes drag and lift explicitly; review 16). The time step it names is accepted.
    auto scene = [](const std::string& dt) {
        return parse(R"({"cloth": {"sheet": {"rows": 21, "cols": 21, "spacing": 0.05},
                                   "air": {"density": 1000}},
                         "pins": [{"grid": [[0, 0], [0, 20]]}],
                         "wind": {"velocity": [0, 0, 200]},
                         "simulation": {"time_step": )" +
                     dt + R"(, "duration": 0.01}})");
    };
    std::string message;
    try {
        Simulation sim(scene("0.0166666666666667"));
    } catch (const SceneError& e) {
        message = e.what();
    }
    INFO(message);
    CHECK_THAT(message,
               Contains("thinner fluid (cloth.air.density)") && !Contains("implicit_euler"));
    const std::string key = "lower simulation.time_step to ";
    const auto at = message.find(key);
    REQUIRE(at != std::string::npos);
    const std::string advised =
        message.substr(at + key.size(), message.find(' ', at + key.size()) - at - key.size());
    CHECK_NOTHROW(Simulation(scene(advised)));
}
