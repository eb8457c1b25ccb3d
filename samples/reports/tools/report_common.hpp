// tools/report_common.hpp: the command line every report program shares:
//   drape-report-<name> [--quick] [--out DIR]
// DIR defaults to samples/reports/results/<name> in the source tree.
#pragma once

#include <drape_reports/report.hpp>

#include <cstring>
#include <filesystem>
#include <iostream>
#include <string>

#ifndef DRAPE_REPORTS_SOURCE_DIR
#define DRAPE_REPORTS_SOURCE_DIR "."
#endif

namespace drape::reports::tool {

struct Args {
    bool quick = false;
    bool render = true;
    std::filesystem::path out;
};

/// Parses the shared options; returns false (after printing usage) on --help or an error.
inline bool parse(int argc, char** argv, const std::string& name, Args& args) {
    args.out = std::filesystem::path(DRAPE_REPORTS_SOURCE_DIR) / "results" / name;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (a == "--quick") {
            args.quick = true;
        } else if (a == "--no-render") {
            args.render = false;
        } else if (a == "--out" && i + 1 < argc) {
            args.out = argv[++i];
        } else {
            std::cerr << "usage: drape-report-" << name
                      << " [--quick] [--no-render] [--out DIR]\n"
                         "  --quick      reduced sizes (what the tests run)\n"
                         "  --out DIR    results folder (default: samples/reports/results/"
                      << name << ")\n";
            return false;
        }
    }
    // From scratch: remove what an earlier run wrote (tables, figures, plot scripts, the
    // report), and nothing else, so a mistyped --out cannot wipe a folder.
    std::filesystem::create_directories(args.out);
    for (const auto& entry : std::filesystem::directory_iterator(args.out)) {
        const std::string ext = entry.path().extension().string();
        if (entry.is_regular_file() &&
            (ext == ".md" || ext == ".csv" || ext == ".png" || ext == ".gp")) {
            std::filesystem::remove(entry.path());
        }
    }
    return true;
}

} // namespace drape::reports::tool
