// laundry_line: a small headless game built on drape. A towel lies on a table; the player picks
// it with the mouse and hangs it over a clothesline, scoring every towel that stays on the
// line. It shows how a game picks and drags a cloth:
//   - the mouse ray: from the camera through the point on the screen the player clicks,
//     Cloth::rayCast finds the towel's triangle it meets and the particle nearest the hit;
//   - the drag: Cloth::setGrab pulls that particle toward where the mouse points, a spring
//     (the automatic stiffness: the towel's weight per 5 cm) solved exactly each step, so the
//     towel follows a fast mouse without a costly frame and lags where it cannot follow;
//     Cloth::releaseGrab lets go;
//   - the world (table, line, posts, floor) comes from a scene file, built by Simulation, and
//     a fixed-time-step loop (FixedStepLoop) steps it at 60 Hz with default cloth settings;
//   - input is scripted: a seeded player varies where it clicks, how far past the line it
//     carries the towel and how low it lets go, so some towels slide off;
//   - each round's cost is measured (thread CPU per 60 Hz step) and reported with the strain.
//
//   laundry_line [-o OUT] [--rounds N] [--seed S] [--scene FILE] [--no-render]
//                [--width W --height H]
#include "drape_samples/game.hpp"
#include "drape_samples/render.hpp"
#include "drape_samples/simulation.hpp"
#include "game_cli.hpp"

#include "drape/timers.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <string>

using namespace drape;
using namespace drape::samples;

namespace {

// The clothesline, as the scene places it (a capsule along x).
constexpr double kLineHeight = 1.45; // [m]
constexpr double kLineZ = -0.7;      // [m]
constexpr double kLineRadius = 0.012;
// How high the hand carries the towel over to the line: low enough that the towel hanging
// from its grab meets the line halfway down and is drawn over it [m].
constexpr double kCarryHeight = 1.65;
constexpr double kTableTop = 0.75; // [m]
// After letting go the towel has this long to come to rest (fall asleep) [s].
constexpr double kMostSettle = 8.0;

// Where the player's hand goes: eased from one point to the next over each leg's duration.
struct Leg {
    Vec3 to;
    double duration; // [s]
};

Vec3 handAt(const Vec3& start, const std::vector<Leg>& legs, double t) {
    Vec3 from = start;
    for (const Leg& leg : legs) {
        if (t < leg.duration) {
            const double s = t / leg.duration;
            const double eased = s * s * (3.0 - 2.0 * s); // smoothstep: no jerk at the ends
            return from + eased * (leg.to - from);
        }
        t -= leg.duration;
        from = leg.to;
    }
    return from;
}

enum class Outcome { Hung, OnTheFloor, OnTheTable, StillMoving, Missed };

const char* toString(Outcome o) {
    switch (o) {
    case Outcome::Hung:
        return "hung";
    case Outcome::OnTheFloor:
        return "on the floor";
    case Outcome::OnTheTable:
        return "on the table";
    case Outcome::StillMoving:
        return "still moving";
    case Outcome::Missed:
        return "missed the towel";
    }
    return "?";
}

// Judged once the towel has come to rest (asleep) or the round's time is up. On the floor:
// a particle lies on it. Hung: at rest, its highest particle on the line (within a few
// centimetres above its axis) and some of it hanging on each side. On the table: at rest with
// no particle below the table's top. Anything else is still moving (sliding off the line,
// falling) and does not score.
Outcome judge(const Cloth& towel) {
    double lowest = 1e300, highest = -1e300;
    bool front = false, back = false;
    for (const Vec3& p : towel.positions()) {
        lowest = std::min(lowest, p.y());
        highest = std::max(highest, p.y());
        front = front || p.z() > kLineZ + kLineRadius;
        back = back || p.z() < kLineZ - kLineRadius;
    }
    if (lowest < 0.05) return Outcome::OnTheFloor;
    if (!towel.isAsleep()) return Outcome::StillMoving;
    if (highest > kLineHeight - 0.05 && highest < kLineHeight + 0.06 && front && back)
        return Outcome::Hung;
    if (lowest > kTableTop) return Outcome::OnTheTable;
    return Outcome::StillMoving;
}

struct Round {
    Outcome outcome = Outcome::Missed;
    Index particle = 0;
    double farOffset = 0.0, releaseHeight = 0.0;
    double medianMs = 0.0, worstMs = 0.0; // thread CPU per 60 Hz step
    double peakStrain = 0.0;
    std::uint64_t capHits = 0;
    double grabStiffness = 0.0; // [N/m]
    double worstLag = 0.0;      // largest distance from the particle to the hand while held [m]
    double restAfter = -1.0;    // asleep this long after letting go [s] (-1: not at rest)
};

} // namespace

int main(int argc, char** argv) {
    CLI::App app{"laundry_line: pick a towel with the mouse and hang it on a clothesline "
                 "(headless)"};
    GameCommandLine cl{"laundry_line_out", 3, DRAPE_LAUNDRY_LINE_SCENE};
    int rounds = 3;
    cl.addTo(app, "Output folder for frames, rounds and the score");
    app.add_option("--rounds", rounds, "Towels to hang")->check(CLI::Range(1, 50));
    if (const int code = parseGameCommandLine(app, argc, argv); code >= 0) return code;

    try {
        const SceneDesc scene = loadScene(cl.scene);
        const std::filesystem::path outDir(cl.out);
        std::filesystem::create_directories(outDir / "frames");
        std::unique_ptr<OffscreenRenderer> renderer;
        if (!cl.noRender) renderer = std::make_unique<OffscreenRenderer>(cl.width, cl.height);
        std::ofstream log(outDir / "rounds.csv");
        log << "round,particle,far_m,release_m,outcome,median_ms,worst_ms,peak_strain,cap_hits,"
               "grab_n_per_m,worst_lag_m,rest_after_s\n";

        ScriptedPlayer player(cl.seed);
        const double frameDt = 1.0 / scene.output.fps;
        std::size_t frame = 0;
        int hung = 0;
        for (int r = 0; r < rounds; ++r) {
            Simulation sim(scene);
            Cloth& towel = sim.cloth();
            Round round;
            // The player clicks near the middle of the towel's edge toward the line: the ray
            // from the camera through that point on the screen.
            const Vec3 aim(player.uniform(-0.05, 0.05), 0.76, player.uniform(-0.23, -0.17));
            round.farOffset = player.uniform(0.0, 0.35);
            round.releaseHeight = player.uniform(1.05, 1.35);
            const Vec3 eye = scene.camera.position;
            const std::optional<ClothHit> hit = towel.rayCast(eye, eye + 10.0 * (aim - eye));
            std::vector<Leg> legs;
            Vec3 start = Vec3::Zero();
            if (hit) {
                round.particle = hit->particle;
                start = hit->point;
                const Vec3 up(start.x(), kCarryHeight, start.z());
                const Vec3 over(start.x(), kCarryHeight, kLineZ - round.farOffset);
                const Vec3 down(start.x(), round.releaseHeight, kLineZ - round.farOffset);
                legs = {{up, 0.8}, {over, 1.2}, {down, 0.8}};
            }
            double dragTime = 0.0;
            for (const Leg& leg : legs)
                dragTime += leg.duration;
            const double pickAt = 0.3;
            const double end = pickAt + dragTime + kMostSettle;
            std::vector<double> stepMs;
            bool held = false, released = false;
            FixedStepLoop loop(scene.timeStep, frameDt);
            // Until the towel rests after the drag (it sleeps), or the time is up; a click that
            // missed the towel ends the round.
            while (sim.time() < end - 1e-9 && !(released && towel.isAsleep()) &&
                   (hit || sim.time() < pickAt)) {
                loop.beginFrame();
                while (loop.nextStep() && sim.time() < end - 1e-9) {
                    const double t = sim.time() - pickAt;
                    if (hit && t >= 0.0 && !released) {
                        if (t <= dragTime) {
                            const Vec3 hand = handAt(start, legs, t);
                            towel.setGrab(hit->particle, hand);
                            held = true;
                            round.worstLag = std::max(
                                round.worstLag, (towel.positions()[hit->particle] - hand).norm());
                        } else if (held) {
                            round.grabStiffness = towel.grabs().front().stiffness;
                            towel.releaseGrab(hit->particle);
                            released = true;
                        }
                    }
                    const double cpu = threadCpuSeconds();
                    sim.step();
                    stepMs.push_back((threadCpuSeconds() - cpu) * 1e3);
                    round.peakStrain = std::max(round.peakStrain, towel.maxStrain());
                }
                if (renderer) {
                    std::vector<DrawMesh> meshes = sim.drawMeshes();
                    if (held && !released) { // the hand: a small cube where the mouse points
                        DrawMesh hand = makeBoxMesh(Vec3::Constant(0.02));
                        const Vec3 at = handAt(start, legs, sim.time() - pickAt);
                        hand.model.block<3, 1>(0, 3) = at.cast<float>();
                        hand.front = hand.back = Color{0.9f, 0.3f, 0.2f};
                        meshes.push_back(std::move(hand));
                    }
                    writePng(framePath(outDir / "frames", frame),
                             renderer->render(scene.camera, meshes, scene.output.background));
                }
                ++frame;
            }
            round.outcome = hit ? judge(towel) : Outcome::Missed;
            if (released && towel.isAsleep()) round.restAfter = sim.time() - pickAt - dragTime;
            round.capHits = towel.limiterCapHits();
            std::vector<double> sorted = stepMs;
            std::sort(sorted.begin(), sorted.end());
            round.medianMs = sorted.empty() ? 0.0 : sorted[sorted.size() / 2];
            round.worstMs = sorted.empty() ? 0.0 : sorted.back();
            hung += round.outcome == Outcome::Hung;
            std::cout << "towel " << r + 1 << ": " << toString(round.outcome) << " (carried "
                      << round.farOffset << " m past the line, let go at " << round.releaseHeight
                      << " m; particle " << round.particle << ", grab " << round.grabStiffness
                      << " N/m, lagging the hand by up to " << round.worstLag << " m; "
                      << (round.restAfter >= 0.0
                              ? "at rest " + std::to_string(round.restAfter) + " s after letting go"
                              : std::string("not at rest"))
                      << ")\n"
                      << "  cost: " << round.medianMs << " ms median, " << round.worstMs
                      << " ms worst a 60 Hz step (thread CPU); peak strain " << round.peakStrain
                      << ", limiter cap hits " << round.capHits << "\n";
            log << r + 1 << ',' << round.particle << ',' << round.farOffset << ','
                << round.releaseHeight << ',' << toString(round.outcome) << ',' << round.medianMs
                << ',' << round.worstMs << ',' << round.peakStrain << ',' << round.capHits << ','
                << round.grabStiffness << ',' << round.worstLag << ',' << round.restAfter << '\n';
        }
        std::ofstream(outDir / "score.txt") << "hung " << hung << " of " << rounds << " towels\n";
        std::cout << "final score: " << hung << " of " << rounds << " towels hung on the line ("
                  << frame << " frames)\n";
    } catch (const std::exception& e) {
        std::cerr << "laundry_line: error: " << e.what() << "\n";
        return 1;
    }
    return 0;
}
