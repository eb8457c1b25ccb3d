// tablecloth_trick: a small headless game built on drape. A table is laid with a cloth, two
// plates and a cup; the player yanks the cloth by its near edge and scores the dishes left
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
#include "tablecloth_trick.hpp"

#include <CLI/CLI.hpp>

#include <filesystem>
#include <fstream>
#include <iostream>

using namespace drape::samples;
using namespace drape::samples::tablecloth;

int main(int argc, char** argv) {
    CLI::App app{"tablecloth_trick: yank a tablecloth from under the dishes, score the ones left "
                 "standing (headless)"};
    std::string out = "tablecloth_trick_out";
    std::string yank = "both";
    std::uint64_t seed = 15;
    bool noRender = false;
    int width = 640, height = 480;
    std::string scenePath = DRAPE_TABLECLOTH_TRICK_SCENE;
    app.add_option("-o,--out", out, "Output folder for frames, events and the score");
    app.add_option("--yank", yank, "Which rounds to play")
        ->check(CLI::IsMember({"fast", "slow", "both"}));
    app.add_option("--seed", seed, "Seed of the scripted player");
    app.add_option("--scene", scenePath, "World scene file");
    app.add_option("--width", width, "Frame width [px]")->check(CLI::Range(16, 4096));
    app.add_option("--height", height, "Frame height [px]")->check(CLI::Range(16, 4096));
    app.add_flag("--no-render", noRender, "Do not write frames");
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        return app.exit(e) == 0 ? 0 : 2;
    }

    try {
        const SceneDesc scene = loadScene(scenePath);
        const std::filesystem::path outDir(out);
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
            options.seed = seed;
            options.events = &events;
            options.width = width;
            options.height = height;
            if (!noRender) options.frames = outDir / toString(kind) / "frames";
            const RoundResult r = playRound(scene, options);
            std::cout << toString(kind) << " yank (" << r.yank.speed << " m/s):";
            for (const DishReport& d : r.dishes)
                std::cout << "  " << d.name << (d.standing ? " standing" : " lost") << " (moved "
                          << (d.end - d.start).norm() << " m)";
            std::cout << "\n  score " << r.standing << " of " << r.dishes.size() << " in "
                      << r.seconds << " s (" << r.frames << " frames)\n";
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
