// simd.hpp (private to module/): Double2, two doubles in one register -- the one SIMD
// vocabulary of the module's kernels. SSE2 (x86-64's baseline) when the target has it, else,
// or with the build option DRAPE_SIMD=OFF (DRAPE_NO_SIMD), a scalar pair with the same
// arithmetic lane by lane: every operation is one IEEE operation per lane, so both give the
// same bits (the sanitizer build runs the test suite with SIMD off; the golden hashes hold).
// No intrinsics anywhere else in drape.
#pragma once

#include <cstddef>

#if defined(__SSE2__) && !defined(DRAPE_NO_SIMD)
#define DRAPE_SIMD_SSE2 1
#include <emmintrin.h>
#else
#define DRAPE_SIMD_SSE2 0
#endif

/// DRAPE_WIDE_KERNEL before a loop kernel's definition: GCC and Clang compile it twice, for
/// x86-64's baseline and for AVX2, and pick one when the program starts (function
/// multi-versioning, an ifunc), so a build for every x86-64 machine still runs four lanes
/// where the CPU has them. Same bits either way: element-wise IEEE operations, and the build
/// turns off floating-point contraction (-ffp-contract=off), so AVX2 fuses no multiply-add.
/// Empty with DRAPE_SIMD=OFF, on other targets, where the build targets AVX2 already, and
/// under GCC's AddressSanitizer (the sanitizer build runs the scalar fallback).
#if DRAPE_SIMD_SSE2 && defined(__x86_64__) && defined(__ELF__) && !defined(__AVX2__) &&            \
    (defined(__GNUC__) || defined(__clang__)) && !defined(__SANITIZE_ADDRESS__)
#define DRAPE_WIDE_KERNEL __attribute__((target_clones("avx2", "default")))
#else
#define DRAPE_WIDE_KERNEL
#endif

namespace drape::detail {

/// Two doubles, (low, high) = (p[0], p[1]) when loaded from p.
class Double2 {
  public:
    static Double2 load(const double* p) {
#if DRAPE_SIMD_SSE2
        return Double2(_mm_loadu_pd(p));
#else
        return Double2(p[0], p[1]);
#endif
    }
    void store(double* p) const {
#if DRAPE_SIMD_SSE2
        _mm_storeu_pd(p, v_);
#else
        p[0] = lo_;
        p[1] = hi_;
#endif
    }
    /// (a, a).
    static Double2 splat(double a) {
#if DRAPE_SIMD_SSE2
        return Double2(_mm_set1_pd(a));
#else
        return Double2(a, a);
#endif
    }
    /// (low, high).
    static Double2 of(double low, double high) {
#if DRAPE_SIMD_SSE2
        return Double2(_mm_set_pd(high, low));
#else
        return Double2(low, high);
#endif
    }
    static Double2 zero() {
        return splat(0.0);
    }

    double low() const {
#if DRAPE_SIMD_SSE2
        return _mm_cvtsd_f64(v_);
#else
        return lo_;
#endif
    }
    double high() const {
#if DRAPE_SIMD_SSE2
        return _mm_cvtsd_f64(_mm_unpackhi_pd(v_, v_));
#else
        return hi_;
#endif
    }
    /// (low, low) and (high, high).
    Double2 lowBoth() const {
#if DRAPE_SIMD_SSE2
        return Double2(_mm_unpacklo_pd(v_, v_));
#else
        return Double2(lo_, lo_);
#endif
    }
    Double2 highBoth() const {
#if DRAPE_SIMD_SSE2
        return Double2(_mm_unpackhi_pd(v_, v_));
#else
        return Double2(hi_, hi_);
#endif
    }

    friend Double2 operator+(Double2 a, Double2 b) {
#if DRAPE_SIMD_SSE2
        return Double2(_mm_add_pd(a.v_, b.v_));
#else
        return Double2(a.lo_ + b.lo_, a.hi_ + b.hi_);
#endif
    }
    friend Double2 operator*(Double2 a, Double2 b) {
#if DRAPE_SIMD_SSE2
        return Double2(_mm_mul_pd(a.v_, b.v_));
#else
        return Double2(a.lo_ * b.lo_, a.hi_ * b.hi_);
#endif
    }
    /// Per lane a > b ? a : b (SSE2's maxpd: b when either is NaN).
    friend Double2 max(Double2 a, Double2 b) {
#if DRAPE_SIMD_SSE2
        return Double2(_mm_max_pd(a.v_, b.v_));
#else
        return Double2(a.lo_ > b.lo_ ? a.lo_ : b.lo_, a.hi_ > b.hi_ ? a.hi_ : b.hi_);
#endif
    }
    /// Whether a lane of a is greater than the same lane of b.
    friend bool anyGreater(Double2 a, Double2 b) {
#if DRAPE_SIMD_SSE2
        return _mm_movemask_pd(_mm_cmpgt_pd(a.v_, b.v_)) != 0;
#else
        return a.lo_ > b.lo_ || a.hi_ > b.hi_;
#endif
    }

  private:
#if DRAPE_SIMD_SSE2
    explicit Double2(__m128d v) : v_(v) {}
    __m128d v_;
#else
    Double2(double lo, double hi) : lo_(lo), hi_(hi) {}
    double lo_, hi_;
#endif
};

} // namespace drape::detail
