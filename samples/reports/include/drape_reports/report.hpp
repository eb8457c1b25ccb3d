// drape_reports/report.hpp: what every report shares: the machine description, tables that
// write themselves as CSV and Markdown, plots through gnuplot, timing and small statistics.
#pragma once

#include <chrono>
#include <cstddef>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace drape::reports {

/// Where and how a report was produced; printed at the top of every report.
struct Machine {
    std::string cpu;       ///< model name from /proc/cpuinfo
    unsigned cores = 0;    ///< logical cores (std::thread::hardware_concurrency)
    std::string date;      ///< UTC, ISO 8601
    std::string buildType; ///< CMAKE_BUILD_TYPE of this build
    std::string command;   ///< the command line that produced the report
    std::string load;      ///< /proc/loadavg at the start (the machine may be shared)
    std::string host;      ///< uname nodename
};

/// Reads /proc/cpuinfo, /proc/loadavg, the clock and the build type.
Machine describeMachine(int argc, const char* const* argv);
/// The machine as a Markdown section.
std::string machineMarkdown(const Machine& m);

/// A table of strings with a header: written as CSV (for comparing) and as Markdown (for reading).
class Table {
  public:
    explicit Table(std::vector<std::string> columns) : columns_(std::move(columns)) {}
    void add(std::vector<std::string> row);
    const std::vector<std::string>& columns() const { return columns_; }
    const std::vector<std::vector<std::string>>& rows() const { return rows_; }
    void writeCsv(const std::filesystem::path& file) const;
    std::string markdown() const;

  private:
    std::vector<std::string> columns_;
    std::vector<std::vector<std::string>> rows_;
};

/// Reads a CSV written by Table::writeCsv (no quoting of commas is needed: cells never hold one).
Table readCsv(const std::filesystem::path& file);

/// Number formatting: `digits` significant digits, "nan"/"inf" spelled out.
std::string fmt(double value, int digits = 4);
/// Fixed-point with `decimals` decimals.
std::string fixed(double value, int decimals);

/// Whether gnuplot is on the PATH.
bool gnuplotAvailable();
/// Writes `script` to <dir>/<name>.gp and runs gnuplot on it in `dir` (the script writes its
/// own PNG). Returns false (with the reason in `why`) when gnuplot is missing or fails.
bool runGnuplot(const std::filesystem::path& dir, const std::string& name,
                const std::string& script, std::string& why);

/// Median of the values (0 for none).
double median(std::vector<double> values);

/// Wall-clock seconds of a callable.
double timeIt(const std::function<void()>& f);

/// Seconds since an arbitrary origin (steady clock).
inline double now() {
    return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch())
        .count();
}

/// Writes text to a file, creating its folder; throws std::runtime_error on failure.
void writeText(const std::filesystem::path& file, const std::string& text);

/// Prints a progress line on stderr ("[report] what").
void progress(const std::string& what);

} // namespace drape::reports
