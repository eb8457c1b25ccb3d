// Shared by drape-bench and drape-bench-bullet: the machine's description and the filter that
// keeps one row (the median) per benchmark case.
#pragma once

#include <benchmark/benchmark.h>

#include <fstream>
#include <string>
#include <vector>

namespace drape::bench {

/// The CPU model from /proc/cpuinfo, or "unknown".
inline std::string cpuModel() {
    std::ifstream in("/proc/cpuinfo");
    std::string line;
    while (std::getline(in, line)) {
        if (line.rfind("model name", 0) == 0) {
            const auto colon = line.find(':');
            if (colon != std::string::npos) return line.substr(colon + 2);
        }
    }
    return "unknown";
}

/// The 1, 5 and 15 minute load averages from /proc/loadavg.
inline std::string loadAverage() {
    std::ifstream in("/proc/loadavg");
    std::string one, five, fifteen;
    in >> one >> five >> fifteen;
    return one + " " + five + " " + fifteen;
}

/// The runs a report shows: the median of repeated cases, single runs, and failures.
inline std::vector<benchmark::BenchmarkReporter::Run>
keepMedians(const std::vector<benchmark::BenchmarkReporter::Run>& runs) {
    using Run = benchmark::BenchmarkReporter::Run;
    std::vector<Run> keep;
    for (const Run& r : runs) {
        const bool single = r.run_type == Run::RT_Iteration && r.repetitions <= 1;
        const bool median = r.run_type == Run::RT_Aggregate && r.aggregate_name == "median";
        if (single || median || r.error_occurred) keep.push_back(r);
    }
    return keep;
}

} // namespace drape::bench
