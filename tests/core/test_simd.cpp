// Double2 (module/src/simd.hpp), the module's one SIMD type: every operation gives, lane by
// lane, the bits of the scalar IEEE operation, in the SIMD build and in the scalar fallback
// (DRAPE_SIMD=OFF, which the sanitizer build uses), so the kernels built on it give the same
// results either way.
#include "simd.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>

using drape::detail::Double2;

namespace {
bool sameBits(double a, double b) {
    return std::memcmp(&a, &b, sizeof a) == 0;
}
} // namespace

TEST_CASE("Double2: load, store, arithmetic and max are the scalar operations lane by lane",
          "[simd]") {
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> u(-1e3, 1e3);
    for (int k = 0; k < 1000; ++k) {
        const double a[2] = {u(rng), u(rng)}, b[2] = {u(rng) * 1e-7, u(rng)};
        const Double2 x = Double2::load(a), y = Double2::load(b);
        double out[2];
        (x + y).store(out);
        CHECK((sameBits(out[0], a[0] + b[0]) && sameBits(out[1], a[1] + b[1])));
        (x * y).store(out);
        CHECK((sameBits(out[0], a[0] * b[0]) && sameBits(out[1], a[1] * b[1])));
        const Double2 m = max(x, y);
        CHECK((sameBits(m.low(), a[0] > b[0] ? a[0] : b[0]) &&
               sameBits(m.high(), a[1] > b[1] ? a[1] : b[1])));
        CHECK((sameBits(x.lowBoth().high(), a[0]) && sameBits(x.highBoth().low(), a[1])));
        CHECK((sameBits(Double2::of(a[0], a[1]).low(), a[0]) &&
               sameBits(Double2::of(a[0], a[1]).high(), a[1])));
        CHECK(anyGreater(x, y) == (a[0] > b[0] || a[1] > b[1]));
    }
    // maxpd's rule where the scalar max is ambiguous: the second operand for a NaN or a tie
    // of signed zeros.
    const double nan = std::numeric_limits<double>::quiet_NaN();
    CHECK(max(Double2::splat(nan), Double2::splat(1.0)).low() == 1.0);
    CHECK(std::isnan(max(Double2::splat(1.0), Double2::splat(nan)).high()));
    CHECK(std::signbit(max(Double2::splat(0.0), Double2::splat(-0.0)).low()));
    CHECK_FALSE(anyGreater(Double2::splat(nan), Double2::zero()));
}
