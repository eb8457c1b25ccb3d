// measured.hpp: a test's measurement as a printf-formatted string, for Catch2's INFO. The
// tests print nothing when they pass; the values show with a failed assertion, and for every
// passing one with `-s` (e.g. `tests/integration/drape_integration_tests "[friction]" -s`).
#pragma once

#include <cstdarg>
#include <cstdio>
#include <string>

#if defined(__GNUC__)
__attribute__((format(printf, 1, 2)))
#endif
inline std::string
measured(const char* format, ...) {
    char buffer[1024];
    va_list args;
    va_start(args, format);
    std::vsnprintf(buffer, sizeof buffer, format, args);
    va_end(args);
    return buffer;
}
