// drape-bench-layout: what the state's layout and precision would give, measured. A prototype
// of drape's step without a limiter (spring forces of a sheet's four families + Velocity-
// Verlet), with positions, velocities and forces in structure-of-arrays form, in double and
// in float, on one or two threads. It is not drape (no limiter, contacts, checks or stability
// estimate): its times are floors for the same work, to compare with drape-bench's scaling
// cases (PERF.md, issue 11).
//
//   drape-bench-layout [--side N] [--steps S] [--repeat R]
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdio>
#include <functional>
#include <thread>
#include <vector>

namespace {

/// A rows x cols sheet (spacing s), drape's triangulation: edges along rows and columns, and
/// one diagonal per cell, alternating (cell (r, c) has i00-i11 when r + c is even, else
/// i01-i10). Springs of one offset b - a form a family: slot j joins a = j to b = j + offset,
/// k = 0 where the mesh has no such spring (a hole).
template <class T> struct Sheet {
    struct Family {
        std::size_t offset = 0, count = 0;
        std::vector<T> k, rest;
    };
    std::size_t rows, cols, n;
    std::vector<T> x[3], v[3], f[3], w;
    std::vector<Family> families;

    Sheet(std::size_t r, std::size_t c) : rows(r), cols(c), n(r * c) {
        const double s = 0.001;
        for (int d = 0; d < 3; ++d) {
            x[d].assign(n, T(0));
            v[d].assign(n, T(0));
            f[d].assign(n, T(0));
        }
        w.assign(n, T(2)); // 0.5 kg particles
        for (std::size_t i = 0; i < rows; ++i) {
            for (std::size_t j = 0; j < cols; ++j) {
                const std::size_t p = i * cols + j;
                x[0][p] = T(double(j) * s * 1.01); // 1 % stretched: the springs pull
                x[1][p] = T(-double(i) * s * 1.02);
                x[2][p] = T(1e-5 * double((i * 7 + j * 3) % 11));
            }
        }
        auto add = [&](std::size_t offset, double rest, auto has) {
            Family fam;
            fam.offset = offset;
            fam.count = n - offset;
            fam.k.assign(fam.count, T(0));
            fam.rest.assign(fam.count, T(0));
            for (std::size_t a = 0; a < fam.count; ++a) {
                const std::size_t b = a + offset;
                if (has(a / cols, a % cols, b / cols, b % cols)) {
                    fam.k[a] = T(20);
                    fam.rest[a] = T(rest);
                }
            }
            families.push_back(std::move(fam));
        };
        const double diag = s * std::sqrt(2.0);
        add(1, s,
            [](std::size_t ra, std::size_t, std::size_t rb, std::size_t) { return ra == rb; });
        add(cols - 1, diag, [](std::size_t ra, std::size_t ca, std::size_t rb, std::size_t cb) {
            return rb == ra + 1 && cb + 1 == ca && (ra + cb) % 2 == 1;
        });
        add(cols, s, [](std::size_t, std::size_t, std::size_t, std::size_t) { return true; });
        add(cols + 1, diag, [](std::size_t ra, std::size_t ca, std::size_t rb, std::size_t cb) {
            return rb == ra + 1 && cb == ca + 1 && (ra + ca) % 2 == 0;
        });
    }
};

/// k (l - L0) / l d of m consecutive slots (a, b: the coordinate runs of the two ends).
template <class T>
void slotForces(std::size_t m, const T* __restrict ax, const T* __restrict ay,
                const T* __restrict az, const T* __restrict bx, const T* __restrict by,
                const T* __restrict bz, const T* __restrict k, const T* __restrict rest,
                T* __restrict ox, T* __restrict oy, T* __restrict oz) {
    for (std::size_t j = 0; j < m; ++j) {
        const T dx = bx[j] - ax[j], dy = by[j] - ay[j], dz = bz[j] - az[j];
        const T l = std::sqrt(dx * dx + dy * dy + dz * dz);
        const T t = k[j] * (l - rest[j]) / (l + T(l == T(0)));
        ox[j] = t * dx;
        oy[j] = t * dy;
        oz[j] = t * dz;
    }
}

/// Gravity and the spring forces on particles [p, q): each family's slots starting in
/// [p - offset, q) into a block buffer, then every particle adds the slot it starts and
/// subtracts the one it ends. With `kick`, the closing kick v += dt/2 w f follows in the same
/// sweep.
template <class T>
void forceBlock(Sheet<T>& s, std::size_t p, std::size_t q, std::vector<T>& buf, T kick) {
    const std::size_t m = q - p;
    for (std::size_t i = p; i < q; ++i) {
        s.f[0][i] = T(0);
        s.f[1][i] = T(-9.8) / s.w[i];
        s.f[2][i] = T(0);
    }
    for (const auto& fam : s.families) {
        const std::size_t off = fam.offset, len = m + off;
        if (buf.size() < 3 * len) buf.resize(3 * len);
        T* o[3] = {buf.data(), buf.data() + len, buf.data() + 2 * len};
        // slots a in [p - off, q) that exist: [lo, hi); o[.][a - (p - off)]
        const std::size_t lo = p >= off ? p - off : 0, hi = std::min(q, fam.count);
        const std::size_t head = lo + off - p, done = hi > lo ? head + (hi - lo) : head;
        for (T* c : o) {
            std::fill(c, c + head, T(0));
            std::fill(c + done, c + len, T(0));
        }
        if (hi > lo) {
            slotForces<T>(hi - lo, &s.x[0][lo], &s.x[1][lo], &s.x[2][lo], &s.x[0][lo + off],
                          &s.x[1][lo + off], &s.x[2][lo + off], &fam.k[lo], &fam.rest[lo],
                          o[0] + head, o[1] + head, o[2] + head);
        }
        for (int d = 0; d < 3; ++d) {
            T* fd = &s.f[d][p];
            const T* starts = o[d] + off;
            const T* ends = o[d];
            for (std::size_t j = 0; j < m; ++j)
                fd[j] += starts[j] - ends[j];
        }
    }
    if (kick != T(0)) {
        for (std::size_t i = p; i < q; ++i) {
            const T hw = kick * s.w[i];
            for (int d = 0; d < 3; ++d)
                s.v[d][i] += hw * s.f[d][i];
        }
    }
}

/// Runs body(begin, end) over [0, n) split in `threads` parts (std::thread per call: the
/// passes of the large sheet take milliseconds, a thread's start some microseconds).
void split(std::size_t n, int threads, const std::function<void(std::size_t, std::size_t)>& body) {
    if (threads <= 1) {
        body(0, n);
        return;
    }
    std::vector<std::thread> pool;
    const std::size_t parts = std::size_t(threads);
    for (std::size_t t = 1; t < parts; ++t)
        pool.emplace_back(body, n * t / parts, n * (t + 1) / parts);
    body(0, n / parts);
    for (auto& th : pool)
        th.join();
}

/// Median wall time of one step [ms].
template <class T> double run(std::size_t side, int steps, int threads, bool fused) {
    Sheet<T> s(side, side);
    const T dt = T(1e-4), half = dt / T(2);
    const std::size_t block = 4096, nBlocks = (s.n + block - 1) / block;
    auto forces = [&](T kick) {
        split(nBlocks, threads, [&](std::size_t b, std::size_t e) {
            thread_local std::vector<T> buf;
            for (std::size_t k = b; k < e; ++k)
                forceBlock(s, k * block, std::min(s.n, (k + 1) * block), buf, kick);
        });
    };
    forces(T(0));
    std::vector<double> times;
    for (int step = 0; step < steps; ++step) {
        const auto t0 = std::chrono::steady_clock::now();
        split(s.n, threads, [&](std::size_t b, std::size_t e) { // kick and drift
            for (int d = 0; d < 3; ++d) {
                T* x = s.x[d].data();
                T* v = s.v[d].data();
                const T* f = s.f[d].data();
                const T* w = s.w.data();
                for (std::size_t i = b; i < e; ++i) {
                    v[i] += half * w[i] * f[i];
                    x[i] += dt * v[i];
                }
            }
        });
        forces(fused ? half : T(0));
        if (!fused) {
            split(s.n, threads, [&](std::size_t b, std::size_t e) { // closing kick
                for (int d = 0; d < 3; ++d) {
                    T* v = s.v[d].data();
                    const T* f = s.f[d].data();
                    const T* w = s.w.data();
                    for (std::size_t i = b; i < e; ++i)
                        v[i] += half * w[i] * f[i];
                }
            });
        }
        times.push_back(
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
                .count());
    }
    // The sheet must have moved by the physics, not been optimised away.
    double check = 0.0;
    for (std::size_t i = 0; i < s.n; i += 97)
        check += double(s.x[1][i]);
    if (!std::isfinite(check)) std::fprintf(stderr, "drape-bench-layout: non-finite state\n");
    std::sort(times.begin(), times.end());
    return times[times.size() / 2];
}

} // namespace

int main(int argc, char** argv) {
    CLI::App app{"drape-bench-layout: a prototype step (springs + Velocity-Verlet, no limiter) "
                 "in structure-of-arrays form, double against float"};
    std::size_t side = 1000;
    int steps = 15, repeat = 3;
    app.add_option("--side", side, "particles per side of the square sheet")
        ->check(CLI::Range(std::size_t(3), std::size_t(4000)));
    app.add_option("--steps", steps, "timed steps per run (median)")->check(CLI::Range(1, 100000));
    app.add_option("--repeat", repeat, "runs of each variant")->check(CLI::Range(1, 99));
    CLI11_PARSE(app, argc, argv);
    std::printf("%zu x %zu sheet, 4 spring families, median of %d steps; us per step\n", side, side,
                steps);
    std::printf(
        "| threads | passes | double | float | double / float |\n|---:|---|---:|---:|---:|\n");
    for (int r = 0; r < repeat; ++r) {
        for (int threads : {1, 2}) {
            for (bool fused : {false, true}) {
                const double d = 1e3 * run<double>(side, steps, threads, fused);
                const double f = 1e3 * run<float>(side, steps, threads, fused);
                std::printf("| %d | %s | %.1f | %.1f | %.2f |\n", threads,
                            fused ? "closing kick in the force sweep" : "three", d, f, d / f);
                std::fflush(stdout);
            }
        }
    }
    return 0;
}
