// curtain_catch: a small headless game built on drape. Balls are thrown at a curtain; the
// player scores every ball the curtain stops. It shows how a game drives the module:
//   - the world (curtain, rail, balls, floor) comes from a scene file, built by Simulation;
//   - a fixed-time-step loop: each rendered frame adds 1/fps to an accumulator, which is
//     spent in physics steps of exactly the scene's dt (so results never depend on the frame
//     rate), the classic "fix your time step" game loop;
//   - input is scripted: a seeded generator stands in for the player's throws, so every run
//     (and every test) plays the same game;
//   - game state (flying, stopped, through, missed) is read back from the rigid bodies and
//     shown in the rendered frames: by the balls' colours and by a scoreboard of cubes above
//     the rail (green: stopped, dark: got past or missed).
//
//   curtain_catch [-o OUT] [--throws N] [--seed S] [--no-render] [--width W --height H]
#include "drape_samples/game.hpp"
#include "drape_samples/render.hpp"
#include "drape_samples/simulation.hpp"
#include "game_cli.hpp"

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iostream>

using namespace drape;
using namespace drape::samples;

namespace {

enum class BallState { Idle, Flying, Stopped, Through, Missed };

struct Ball {
    std::string name;
    BallState state = BallState::Idle;
    double thrownAt = 0.0;
    bool aimedAtCurtain = false;
};

const char* toString(BallState s) {
    switch (s) {
    case BallState::Idle:
        return "idle";
    case BallState::Flying:
        return "flying";
    case BallState::Stopped:
        return "stopped";
    case BallState::Through:
        return "through";
    case BallState::Missed:
        return "missed";
    }
    return "?";
}

Color colourOf(BallState s) {
    switch (s) {
    case BallState::Stopped:
        return {0.15f, 0.75f, 0.20f};
    case BallState::Through:
    case BallState::Missed:
        return {0.30f, 0.30f, 0.32f};
    default:
        return {0.95f, 0.80f, 0.15f};
    }
}

} // namespace

int main(int argc, char** argv) {
    CLI::App app{"curtain_catch: throw balls at a curtain and score the ones it stops (headless)"};
    GameCommandLine cl{"curtain_catch_out", 7, DRAPE_CURTAIN_CATCH_SCENE};
    int throws = 8;
    cl.addTo(app, "Output folder for frames and the score");
    app.add_option("--throws", throws, "Number of balls thrown")->check(CLI::Range(1, 100));
    if (const int code = parseGameCommandLine(app, argc, argv); code >= 0) return code;

    try {
        SceneDesc scene = loadScene(cl.scene);
        Simulation sim(scene);
        const double dt = scene.timeStep;
        const double frameDt = 1.0 / scene.output.fps;
        const double throwInterval = 0.8; // [s] between throws
        const double judgeAfter = 1.4;    // [s] of flight before a throw is judged
        const double curtainZ = 0.0, halfWidth = 1.0, top = 2.4, bottom = 0.24;

        std::vector<Ball> balls;
        for (const auto& b : scene.rigidBodies)
            if (b.motion == MotionKind::Dynamic) balls.push_back(Ball{b.name});
        if (balls.empty()) throw SceneError(cl.scene + ": the game needs dynamic balls");

        std::filesystem::create_directories(std::filesystem::path(cl.out) / "frames");
        std::unique_ptr<OffscreenRenderer> renderer;
        if (!cl.noRender) renderer = std::make_unique<OffscreenRenderer>(cl.width, cl.height);

        ScriptedPlayer player(cl.seed);
        int thrown = 0, stopped = 0, scored = 0;
        double nextThrow = 0.3;
        std::size_t nextBall = 0;
        FixedStepLoop loop(dt, frameDt);
        std::size_t frame = 0;
        std::ofstream log(std::filesystem::path(cl.out) / "throws.csv");
        log << "throw,ball,time_s,aim_x_m,aim_y_m,speed_m_s,on_target,result\n";
        std::vector<std::array<double, 4>> aims(balls.size());
        std::vector<BallState> results; // per throw, in order: the scoreboard
        std::vector<int> throwIndex(balls.size(), -1);

        // Play until every throw has been judged.
        while (scored < throws) {
            loop.beginFrame();
            while (loop.nextStep()) {
                const double t = sim.time();
                // Scripted input: throw the next ball when it is time.
                if (thrown < throws && t >= nextThrow &&
                    balls[nextBall].state != BallState::Flying) {
                    Ball& b = balls[nextBall];
                    const double aimX = player.uniform(-1.5, 1.5);
                    const double aimY = player.uniform(0.5, 2.1);
                    const double speed = player.uniform(5.0, 7.0);
                    const Vec3 from(player.uniform(-0.4, 0.4), 1.2, 3.0);
                    const Vec3 aim(aimX, aimY, curtainZ);
                    // Aim above the target to make up for the drop over the flight.
                    const double flight = (aim - from).norm() / speed;
                    Vec3 v = (aim - from).normalized() * speed;
                    v.y() += 0.5 * 9.81 * flight;
                    sim.launchBody(b.name, from, v);
                    b.state = BallState::Flying;
                    b.thrownAt = t;
                    b.aimedAtCurtain = std::abs(aimX) < halfWidth && aimY > bottom && aimY < top;
                    aims[nextBall] = {aimX, aimY, speed, b.aimedAtCurtain ? 1.0 : 0.0};
                    throwIndex[nextBall] = thrown;
                    ++thrown;
                    nextThrow = t + throwInterval;
                    nextBall = (nextBall + 1) % balls.size();
                }
                sim.step();
                // Judge balls that have flown long enough: behind the curtain = through.
                for (std::size_t i = 0; i < balls.size(); ++i) {
                    Ball& b = balls[i];
                    if (b.state != BallState::Flying || sim.time() - b.thrownAt < judgeAfter)
                        continue;
                    const Vec3 p = sim.bodyPosition(b.name);
                    // A stopped ball drops at the curtain (it may roll a little way under it);
                    // one that got past is still flying or rolling fast, far behind it.
                    const Vec3 v = sim.bodyVelocity(b.name);
                    if (p.z() > curtainZ - 2.0 && v.z() > -1.5) {
                        b.state = BallState::Stopped;
                        ++stopped;
                    } else {
                        b.state = b.aimedAtCurtain ? BallState::Through : BallState::Missed;
                    }
                    ++scored;
                    results.resize(static_cast<std::size_t>(throws), BallState::Idle);
                    results[static_cast<std::size_t>(throwIndex[i])] = b.state;
                    log << throwIndex[i] << ',' << b.name << ',' << b.thrownAt << ',' << aims[i][0]
                        << ',' << aims[i][1] << ',' << aims[i][2] << ','
                        << (aims[i][3] > 0 ? "yes" : "no") << ',' << toString(b.state) << '\n';
                    std::cout << "throw " << throwIndex[i] + 1 << ": " << toString(b.state)
                              << "  (score " << stopped << "/" << scored << ")\n";
                }
            }
            if (renderer) {
                std::vector<DrawMesh> meshes;
                meshes.push_back(toDrawMesh(sim.cloth().positions(),
                                            sim.cloth().topology().triangles(), scene.frontColor,
                                            scene.backColor));
                for (const BodyView& bv : sim.bodies()) {
                    for (const DrawMesh& m : *bv.meshes) {
                        meshes.push_back(m);
                        meshes.back().model = bv.transform;
                        for (const Ball& b : balls)
                            if (b.name == bv.name)
                                meshes.back().front = meshes.back().back = colourOf(b.state);
                    }
                }
                // Scoreboard: a row of cubes above the rail, one per throw (green = stopped,
                // dark = got past or missed, light = still to come).
                for (int k = 0; k < throws; ++k) {
                    const double spacing = std::min(0.3, 2.6 / throws);
                    DrawMesh cube = makeBoxMesh(Vec3::Constant(0.35 * spacing));
                    cube.model(0, 3) =
                        static_cast<float>(-0.5 * spacing * (throws - 1) + spacing * k);
                    cube.model(1, 3) = 2.75f;
                    const BallState r = static_cast<std::size_t>(k) < results.size()
                                            ? results[static_cast<std::size_t>(k)]
                                            : BallState::Idle;
                    cube.front = cube.back =
                        r == BallState::Idle ? Color{0.85f, 0.85f, 0.85f} : colourOf(r);
                    meshes.push_back(std::move(cube));
                }
                writePng(framePath(std::filesystem::path(cl.out) / "frames", frame),
                         renderer->render(scene.camera, meshes, scene.output.background));
            }
            ++frame;
            if (sim.time() > 600.0)
                throw SceneError("the game did not finish in 600 simulated seconds");
        }
        std::ofstream(std::filesystem::path(cl.out) / "score.txt")
            << "stopped " << stopped << " of " << throws << " balls\n";
        std::cout << "final score: the curtain stopped " << stopped << " of " << throws
                  << " balls in " << sim.time() << " s (" << frame << " frames)\n";
    } catch (const std::exception& e) {
        std::cerr << "curtain_catch: error: " << e.what() << "\n";
        return 1;
    }
    return 0;
}
