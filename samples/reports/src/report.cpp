// Shared report plumbing: machine description, tables, gnuplot, statistics.
#include "drape_reports/report.hpp"

#include <sys/utsname.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <sstream>
#include <stdexcept>
#include <thread>

#ifndef DRAPE_REPORTS_BUILD_TYPE
#define DRAPE_REPORTS_BUILD_TYPE "unknown"
#endif

namespace drape::reports {

namespace {
std::string trim(const std::string& s) {
    const auto b = s.find_first_not_of(" \t\r\n");
    if (b == std::string::npos) return "";
    const auto e = s.find_last_not_of(" \t\r\n");
    return s.substr(b, e - b + 1);
}
} // namespace

Machine describeMachine(int argc, const char* const* argv) {
    Machine m;
    std::ifstream cpuinfo("/proc/cpuinfo");
    std::string line;
    while (std::getline(cpuinfo, line)) {
        if (line.rfind("model name", 0) == 0) {
            m.cpu = trim(line.substr(line.find(':') + 1));
            break;
        }
    }
    if (m.cpu.empty()) m.cpu = "unknown CPU";
    m.cores = std::thread::hardware_concurrency();
    const std::time_t t = std::time(nullptr);
    std::tm tm{};
    gmtime_r(&t, &tm);
    char buf[64];
    std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
    m.date = buf;
    m.buildType = DRAPE_REPORTS_BUILD_TYPE;
    for (int i = 0; i < argc; ++i) {
        if (i) m.command += ' ';
        std::string a = argv[i];
        if (i == 0) a = std::filesystem::path(a).filename().string();
        m.command += a;
    }
    std::ifstream loadavg("/proc/loadavg");
    std::getline(loadavg, m.load);
    m.load = trim(m.load);
    utsname u{};
    if (uname(&u) == 0) m.host = u.nodename;
    return m;
}

std::string machineMarkdown(const Machine& m) {
    std::ostringstream o;
    o << "## Machine\n\n"
      << "| | |\n|---|---|\n"
      << "| CPU | " << m.cpu << " |\n"
      << "| logical cores | " << m.cores << " |\n"
      << "| date (UTC) | " << m.date << " |\n"
      << "| build type | " << m.buildType << " |\n"
      << "| command | `" << m.command << "` |\n"
      << "| load average at start (1, 5, 15 min) | " << m.load
      << " (the machine was shared with other jobs; wall times carry that noise) |\n\n";
    return o.str();
}

void Table::add(std::vector<std::string> row) {
    if (row.size() != columns_.size()) {
        throw std::runtime_error("table row has " + std::to_string(row.size()) +
                                 " cells, header has " + std::to_string(columns_.size()));
    }
    rows_.push_back(std::move(row));
}

void Table::writeCsv(const std::filesystem::path& file) const {
    std::ostringstream o;
    auto line = [&o](const std::vector<std::string>& cells) {
        for (std::size_t i = 0; i < cells.size(); ++i) {
            if (i) o << ',';
            std::string c = cells[i];
            std::replace(c.begin(), c.end(), ',', ';');
            o << c;
        }
        o << '\n';
    };
    line(columns_);
    for (const auto& r : rows_)
        line(r);
    writeText(file, o.str());
}

std::string Table::markdown() const {
    std::ostringstream o;
    o << '|';
    for (const auto& c : columns_)
        o << ' ' << c << " |";
    o << "\n|";
    for (std::size_t i = 0; i < columns_.size(); ++i)
        o << "---|";
    o << '\n';
    for (const auto& r : rows_) {
        o << '|';
        for (const auto& c : r)
            o << ' ' << c << " |";
        o << '\n';
    }
    return o.str();
}

Table readCsv(const std::filesystem::path& file) {
    std::ifstream in(file);
    if (!in) throw std::runtime_error("cannot read " + file.string());
    auto split = [](const std::string& s) {
        std::vector<std::string> cells;
        std::string cell;
        std::istringstream ss(s);
        while (std::getline(ss, cell, ','))
            cells.push_back(cell);
        if (!s.empty() && s.back() == ',') cells.emplace_back();
        return cells;
    };
    std::string line;
    if (!std::getline(in, line)) throw std::runtime_error(file.string() + " is empty");
    Table t(split(line));
    while (std::getline(in, line)) {
        if (!line.empty()) t.add(split(line));
    }
    return t;
}

std::string fmt(double value, int digits) {
    if (std::isnan(value)) return "nan";
    if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
    std::ostringstream o;
    o << std::setprecision(digits) << value;
    return o.str();
}

std::string fixed(double value, int decimals) {
    if (!std::isfinite(value)) return fmt(value);
    std::ostringstream o;
    o << std::fixed << std::setprecision(decimals) << value;
    return o.str();
}

bool gnuplotAvailable() {
    return std::system("command -v gnuplot >/dev/null 2>&1") == 0;
}

bool runGnuplot(const std::filesystem::path& dir, const std::string& name,
                const std::string& script, std::string& why) {
    writeText(dir / (name + ".gp"), script);
    if (!gnuplotAvailable()) {
        why = "gnuplot is not installed (Debian package gnuplot-nox); the script is in " +
              (dir / (name + ".gp")).string();
        return false;
    }
    const std::string cmd =
        "cd '" + dir.string() + "' && gnuplot '" + name + ".gp' > '" + name + ".gp.log' 2>&1";
    if (std::system(cmd.c_str()) != 0) {
        why = "gnuplot failed on " + (dir / (name + ".gp")).string() + " (see its .gp.log)";
        return false;
    }
    std::filesystem::remove(dir / (name + ".gp.log"));
    return true;
}

double median(std::vector<double> values) {
    if (values.empty()) return 0.0;
    std::sort(values.begin(), values.end());
    const std::size_t n = values.size();
    return n % 2 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

double timeIt(const std::function<void()>& f) {
    const double t0 = now();
    f();
    return now() - t0;
}

void writeText(const std::filesystem::path& file, const std::string& text) {
    if (file.has_parent_path()) std::filesystem::create_directories(file.parent_path());
    std::ofstream out(file, std::ios::binary);
    out << text;
    if (!out) throw std::runtime_error("cannot write " + file.string());
}

void progress(const std::string& what) {
    std::cerr << "[report] " << what << std::endl;
}

} // namespace drape::reports
