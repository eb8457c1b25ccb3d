// tablecloth_trick: a small headless game built on drape. A table is laid with a cloth, two
// plates and a bowl; the player yanks the cloth by its near edge and scores the dishes left
// standing on the table. By default it plays two rounds, a slow yank (the dishes ride along
// and go over the edge) and a fast one (the cloth comes out from under them). It shows:
//   - the world (table, cloth, dishes) comes from a scene file, built by Simulation;
//   - a fixed-time-step loop (FixedStepLoop: frames never change the physics);
//   - scripted input: a seeded player varies the yank's start, speed and slope; the hand drives
//     the cloth's near edge (the scene's pins[0]) as kinematic particles on an accelerated path;
//   - game state read back from the rigid bodies: events (dish left the table, tipped, fell)
//     in events.csv, dishes that are lost drawn grey, the score in score.txt.
//
//   tablecloth_trick [-o OUT] [--yank fast|slow|both] [--seed S] [--scene FILE]
//                    [--no-render] [--width W --height H]
#include "game_cli.hpp"
#include "tablecloth_trick.hpp"

#include <filesystem>
#include <fstream>
#include <iostream>

using namespace drape::samples;
using namespace drape::samples::tablecloth;

int main(int argc, char** argv) {
    CLI::App app{"tablecloth_trick: yank a tablecloth from under the dishes, score the ones left "
                 "standing (headless)"};
    GameCommandLine cl{"tablecloth_trick_out", kDefaultSeed, DRAPE_TABLECLOTH_TRICK_SCENE};
    std::string yank = "both";
    cl.addTo(app, "Output folder for frames, events and the score");
    app.add_option("--yank", yank, "Which rounds to play")
        ->check(CLI::IsMember({"fast", "slow", "both"}));
    if (const int code = parseGameCommandLine(app, argc, argv); code >= 0) return code;

    try {
        const SceneDesc scene = loadScene(cl.scene);
        const std::filesystem::path outDir(cl.out);
        std::filesystem::create_directories(outDir);
        std::ofstream events(outDir / "events.csv");
        events << kEventsHeader << '\n';
        std::vector<YankKind> rounds;
        if (yank != "fast") rounds.push_back(YankKind::Slow);
        if (yank != "slow") rounds.push_back(YankKind::Fast);

        std::ofstream score(outDir / "score.txt");
        int total = 0, dishes = 0;
        for (YankKind kind : rounds) {
            RoundOptions options;
            options.kind = kind;
            options.seed = cl.seed;
            options.events = &events;
            options.width = cl.width;
            options.height = cl.height;
            if (!cl.noRender) options.frames = outDir / toString(kind) / "frames";
            const RoundResult r = playRound(scene, options);
            std::cout << toString(kind) << " yank (" << r.yank.speed << " m/s):";
            for (const DishReport& d : r.dishes)
                std::cout << "  " << d.name << (d.standing ? " standing" : " lost") << " (moved "
                          << (d.end - d.start).norm() << " m)";
            std::cout << "\n  score " << r.standing << " of " << r.dishes.size() << " in "
                      << r.seconds << " s (" << r.frames << " frames, " << r.clothSubsteps
                      << " cloth sub-steps per step)\n  lowest dish corner over the table: "
                      << r.minTableClearance * 1000.0
                      << " mm above its top; deepest cloth particle inside a dish: "
                      << r.maxClothDepth * 1000.0 << " mm (negative: outside)\n";
            score << toString(kind) << ": " << r.standing << " of " << r.dishes.size()
                  << " dishes left standing\n";
            total += r.standing;
            dishes += static_cast<int>(r.dishes.size());
        }
        std::cout << "final score: " << total << " of " << dishes << " dishes left standing\n";
    } catch (const std::exception& e) {
        std::cerr << "tablecloth_trick: error: " << e.what() << "\n";
        return 1;
    }
    return 0;
}
