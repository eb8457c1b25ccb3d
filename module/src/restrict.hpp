// Internal: DRAPE_RESTRICT marks a pointer parameter whose array overlaps no other array the
// function reads or writes, so that loops over it vectorise without run-time overlap checks.
// C has `restrict`; GCC, Clang and MSVC spell the same qualifier `__restrict` in C++. Other
// compilers get nothing (correct, possibly slower code).
#pragma once

#if defined(__GNUC__) || defined(__clang__) || defined(_MSC_VER)
#define DRAPE_RESTRICT __restrict
#else
#define DRAPE_RESTRICT
#endif
