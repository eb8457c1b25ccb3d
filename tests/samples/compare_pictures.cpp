// drape_compare_pictures: compares the committed pictures (docs/pictures/*.png) with the ones
// scripts/pictures.sh renders now, pixel by pixel, for the test
// samples.pictures.match_the_committed_ones (pictures_expect.cmake).
//
//   drape_compare_pictures COMMITTED_DIR RENDERED_DIR
//
// Every PNG in either folder must be in both, of the same size. A pixel differs when one of
// its channels differs by more than kChannelTolerance levels; a picture fails when more than
// kMaxDifferingFraction of its pixels differ. Rendering is deterministic (OSMesa's llvmpipe,
// the reference toolchain's simulation), so the tolerance only absorbs rounding in the
// rasteriser on another CPU. For scale: the pictures committed before this check differed in
// 38 to 14,482 pixels each, and the fix for black triangles at folds changed 10 pixels of
// trampoline.png (by up to 6 levels) and 2,363 of towel_fold.png.
// Exit status 0 when every picture matches, 1 when one does not, 2 on a usage or read error.
#include "drape_samples/render.hpp"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <set>
#include <string>

namespace fs = std::filesystem;
using drape::samples::Image;
using drape::samples::readPng;

namespace {

constexpr int kChannelTolerance = 3;              // levels of 255
constexpr double kMaxDifferingFraction = 0.00005; // 1 pixel in 20,000: 3 of 320 x 240

std::set<std::string> pngsIn(const fs::path& dir) {
    std::set<std::string> names;
    for (const fs::directory_entry& e : fs::directory_iterator(dir))
        if (e.is_regular_file() && e.path().extension() == ".png")
            names.insert(e.path().filename().string());
    return names;
}

} // namespace

int main(int argc, char** argv) {
    if (argc != 3) {
        std::fprintf(stderr, "usage: %s COMMITTED_DIR RENDERED_DIR\n", argv[0]);
        return 2;
    }
    const fs::path committed = argv[1], rendered = argv[2];
    try {
        const std::set<std::string> want = pngsIn(committed), got = pngsIn(rendered);
        std::set<std::string> all = want;
        all.insert(got.begin(), got.end());
        int bad = 0;
        long mostDiffering = 0; // pixels, over the pictures
        for (const std::string& name : all) {
            const fs::path a = committed / name, b = rendered / name;
            if (!want.count(name)) {
                std::printf("%s: rendered by scripts/pictures.sh but not committed\n",
                            b.string().c_str());
                ++bad;
                continue;
            }
            if (!got.count(name)) {
                std::printf("%s: committed but no longer rendered by scripts/pictures.sh\n",
                            a.string().c_str());
                ++bad;
                continue;
            }
            const Image x = readPng(a), y = readPng(b);
            if (x.width != y.width || x.height != y.height) {
                std::printf("%s: %d x %d, but scripts/pictures.sh renders %d x %d (%s)\n",
                            a.string().c_str(), x.width, x.height, y.width, y.height,
                            b.string().c_str());
                ++bad;
                continue;
            }
            long differing = 0;
            int largest = 0, lx = 0, ly = 0;
            for (int j = 0; j < x.height; ++j)
                for (int i = 0; i < x.width; ++i) {
                    const auto p = x.pixel(i, j), q = y.pixel(i, j);
                    int d = 0;
                    for (std::size_t c = 0; c < 3; ++c)
                        d = std::max(d, std::abs(int(p[c]) - int(q[c])));
                    if (d > kChannelTolerance) ++differing;
                    if (d > largest) {
                        largest = d;
                        lx = i;
                        ly = j;
                    }
                }
            const long pixels = static_cast<long>(x.width) * x.height;
            mostDiffering = std::max(mostDiffering, differing);
            if (static_cast<double>(differing) <=
                kMaxDifferingFraction * static_cast<double>(pixels))
                continue;
            std::printf("%s: %ld of its %ld pixels differ from what scripts/pictures.sh "
                        "renders now (%s) by more than %d levels (at most %ld may); the "
                        "largest difference is %d levels, at x %d y %d\n",
                        a.string().c_str(), differing, pixels, b.string().c_str(),
                        kChannelTolerance,
                        static_cast<long>(kMaxDifferingFraction * static_cast<double>(pixels)),
                        largest, lx, ly);
            ++bad;
        }
        if (bad) {
            std::printf("%d of %zu pictures differ from what scripts/pictures.sh renders now "
                        "(rendered into %s). Run scripts/pictures.sh, look at the pictures and "
                        "commit docs/pictures.\n",
                        bad, all.size(), rendered.string().c_str());
            return 1;
        }
        std::printf("all %zu pictures match what scripts/pictures.sh renders now (at most %ld "
                    "pixels of one picture differ by more than %d levels)\n",
                    all.size(), mostDiffering, kChannelTolerance);
        return 0;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "drape_compare_pictures: %s\n", e.what());
        return 2;
    }
}
