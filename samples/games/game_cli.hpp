// samples/games/game_cli.hpp: the command-line options every sample game has (output folder,
// seed of the scripted player, world scene file, frame size, no frames), parsed with CLI11.
#pragma once

#include <CLI/CLI.hpp>

#include <cstdint>
#include <string>

namespace drape::samples {

struct GameCommandLine {
    std::string out;
    std::uint64_t seed = 0;
    std::string scene;
    int width = 640, height = 480;
    bool noRender = false;

    /// Adds the shared options to `app`, with these defaults.
    void addTo(CLI::App& app, const std::string& outHelp) {
        app.add_option("-o,--out", out, outHelp);
        app.add_option("--seed", seed, "Seed of the scripted player");
        app.add_option("--scene", scene, "World scene file");
        app.add_option("--width", width, "Frame width [px]")->check(CLI::Range(16, 4096));
        app.add_option("--height", height, "Frame height [px]")->check(CLI::Range(16, 4096));
        app.add_flag("--no-render", noRender, "Do not write frames");
    }
};

/// Parses the command line: -1 when the game should run, else the exit code (0 after --help,
/// 2 for a bad command line, with CLI11's message printed).
inline int parseGameCommandLine(CLI::App& app, int argc, char** argv) {
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError& e) {
        return app.exit(e) == 0 ? 0 : 2;
    }
    return -1;
}

} // namespace drape::samples
