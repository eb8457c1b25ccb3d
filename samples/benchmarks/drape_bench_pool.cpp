// drape-bench-pool: the core's own thread pool (module/src/parallel.hpp, ClothSettings::threads)
// against oneTBB's parallel_for on the same loops, 2 threads: which one the core's per-particle
// passes should run on (issue 30 asks for oneTBB unless a measurement shows the pool is better).
//
//   drape-bench-pool                    particle counts 1225 (Experiment I) to 1e6, 2 threads
//   drape-bench-pool --threads 2 --repetitions 15
//
// Each loop is a Velocity-Verlet kick and drift over n particles (v += f w dt; x += v dt, the
// core's cheapest pass, where scheduling weighs most), split into the same contiguous pieces
// by both: the pool as the core calls it (its default grain, 4 pieces a thread, which runs
// loops shorter than the grain per thread inline), and tbb::parallel_for over a
// blocked_range with the same grain and a static_partitioner (fixed pieces: determinism) in
// a task_arena of the same thread count; and tbb::parallel_for with its default (auto)
// partitioner and a grain of a quarter of the pool's, work stealing deciding the pieces (allowed
// here: the core's loops give the same bits for any split, see parallel.hpp). Also the fork-join
// cost alone: an empty body over a range just long enough to engage every thread. Figures: median
// of the repetitions, each the mean of many calls, the two alternating.
#include "parallel.hpp"

#include <CLI/CLI.hpp>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <vector>

namespace {

using Clock = std::chrono::steady_clock;

struct State {
    std::vector<double> x, v, f, w;
    explicit State(std::size_t n) : x(3 * n, 0.0), v(3 * n, 0.1), f(3 * n, -9.81), w(n, 2.0) {}
    void kickDrift(std::size_t b, std::size_t e, double dt) {
        for (std::size_t i = b; i < e; ++i) {
            for (std::size_t k = 3 * i; k < 3 * i + 3; ++k) {
                v[k] += f[k] * w[i] * dt;
                x[k] += v[k] * dt;
            }
        }
    }
};

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v[v.size() / 2];
}

/// Mean seconds per call of `call` over enough calls to take about 50 ms.
template <class Call> double timePerCall(Call&& call) {
    call(); // warm
    std::size_t calls = 1;
    for (;;) {
        const auto t0 = Clock::now();
        for (std::size_t k = 0; k < calls; ++k)
            call();
        const double s = std::chrono::duration<double>(Clock::now() - t0).count();
        if (s > 0.05) return s / double(calls);
        calls *= 2;
    }
}

} // namespace

int main(int argc, char** argv) {
    int threads = 2, repetitions = 11;
    std::size_t grain = 32768; // the pool's default (parallel.hpp)
    CLI::App app{"drape-bench-pool: the core's thread pool against oneTBB on the same loops"};
    app.add_option("--threads", threads, "threads (the caller's included)")
        ->check(CLI::Range(2, 64));
    app.add_option("--repetitions", repetitions, "alternating repetitions (median)")
        ->check(CLI::Range(1, 99));
    app.add_option("--grain", grain,
                   "the pool's grain: fewest particles a thread (32768: its default)")
        ->check(CLI::Range(16, 1 << 24));
    CLI11_PARSE(app, argc, argv);

    drape::detail::ThreadPool pool(threads);
    tbb::task_arena arena(threads);
    std::printf("threads %d, grain %zu, %d repetitions (median), us per call\n\n", threads, grain,
                repetitions);
    std::printf(
        "| loop | particles | pool | oneTBB, static | pool / static | oneTBB, auto | pool / "
        "auto |\n|---|---:|---:|---:|---:|---:|---:|\n");

    auto row = [&](const char* name, std::size_t n, auto&& body) {
        // The same pieces for both: the pool's (kPiecesPerThread a thread, at least `grain`
        // elements a thread, else inline), given to TBB as its grain size.
        const std::size_t usedThreads =
            std::min<std::size_t>(std::size_t(threads), std::max<std::size_t>(1, n / grain));
        const std::size_t pieces = usedThreads * drape::detail::ThreadPool::kPiecesPerThread;
        const std::size_t piece = std::max<std::size_t>(1, (n + pieces - 1) / pieces);
        std::vector<double> p, t, a;
        for (int r = 0; r < repetitions; ++r) {
            a.push_back(timePerCall([&] {
                arena.execute([&] {
                    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, grain / 4),
                                      [&](const tbb::blocked_range<std::size_t>& range) {
                                          body(range.begin(), range.end());
                                      });
                });
            }));
            p.push_back(timePerCall([&] { pool.parallelFor(n, grain, body); }));
            t.push_back(timePerCall([&] {
                arena.execute([&] {
                    if (usedThreads == 1) {
                        body(std::size_t{0}, n);
                        return;
                    }
                    tbb::parallel_for(
                        tbb::blocked_range<std::size_t>(0, n, piece),
                        [&](const tbb::blocked_range<std::size_t>& range) {
                            body(range.begin(), range.end());
                        },
                        tbb::static_partitioner());
                });
            }));
        }
        const double mp = median(p) * 1e6, mt = median(t) * 1e6, ma = median(a) * 1e6;
        std::printf("| %s | %zu | %.2f | %.2f | %.2f | %.2f | %.2f |\n", name, n, mp, mt, mp / mt,
                    ma, mp / ma);
        std::fflush(stdout);
    };

    const std::size_t fork = std::size_t(threads) * grain;
    row("fork-join, empty body", fork, [](std::size_t, std::size_t) {});
    for (std::size_t n :
         {std::size_t(1225), std::size_t(10000), std::size_t(100000), std::size_t(1000000)}) {
        State s(n);
        row("kick and drift", n, [&s](std::size_t b, std::size_t e) { s.kickDrift(b, e, 1e-3); });
    }
    return 0;
}
