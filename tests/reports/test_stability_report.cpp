// The stability report on its reduced size: rows present, values finite, and the measured
// limits where theory puts them.
#include <drape_reports/reports.hpp>

#include <catch2/catch.hpp>

#include <cmath>
#include <fstream>
#include <sstream>

using namespace drape;
using namespace drape::reports;

namespace {
std::string slurp(const std::filesystem::path& p) {
    std::ifstream in(p);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
}
} // namespace

TEST_CASE("stability report: limits against 2 / omega_max, extreme cases, files") {
    StabilityOptions o;
    o.outDir = std::filesystem::path(DRAPE_REPORTS_TEST_OUT) / "stability";
    o.quick = true;
    const char* argv[] = {"test"};
    const StabilityResult r = runStabilityReport(o, describeMachine(1, argv));

    REQUIRE(r.sweep.size() == 5 * 3); // five integrators x three stiffnesses
    for (const StabilityPoint& p : r.sweep) {
        INFO(toString(p.integrator) << " k = " << p.stiffness);
        CHECK(std::isfinite(p.omegaBound));
        CHECK(std::isfinite(p.omegaRest));
        CHECK(p.measured > 0.0);
        // The bound really bounds: the exact omega at rest does not exceed it.
        CHECK(p.omegaRest <= p.omegaBound * (1.0 + 1e-9));
        // omega scales as sqrt(k) (same masses, same topology).
        CHECK(p.omegaBound / std::sqrt(p.stiffness) ==
              Approx(r.sweep.front().omegaBound / std::sqrt(r.sweep.front().stiffness))
                  .epsilon(0.02));
        switch (p.integrator) {
        case IntegratorKind::ImplicitEuler:
            // A-stable: no instability found anywhere in the search, up to 100 x 2 / omega.
            CHECK(p.stableAtAllTested);
            CHECK(p.measured >= 50.0 * 2.0 / p.omegaBound);
            break;
        case IntegratorKind::SymplecticEuler:
        case IntegratorKind::VelocityVerlet:
        case IntegratorKind::RungeKutta4:
            CHECK_FALSE(p.stableAtAllTested);
            // Within a factor of 2 of the theoretical limit from omega_max.
            CHECK(p.measured / p.theoryLimit >= 0.5);
            CHECK(p.measured / p.theoryLimit <= 2.0);
            // And not beyond the exact limit of the state it ran in by more than the search's
            // resolution: 2 / omega_exact (2 sqrt 2 for RK4) with a 5 % margin.
            {
                const double c =
                    p.integrator == IntegratorKind::RungeKutta4 ? 2.0 * std::sqrt(2.0) : 2.0;
                CHECK(p.measured <=
                      1.05 * c /
                          std::min(p.omegaRest, p.omegaFinal > 0 ? p.omegaFinal : p.omegaRest));
            }
            break;
        case IntegratorKind::ExplicitEuler:
            // Damped explicit Euler is stable below C_d / (m omega^2); a finite run sees the
            // growth only near sqrt(2 ln(1e6) / N) / omega: within a factor of 2 of that.
            CHECK(p.measured >= p.theoryLimit);
            CHECK(p.measured / p.horizonLimit >= 0.5);
            CHECK(p.measured / p.horizonLimit <= 2.0);
            break;
        }
    }
    REQUIRE(r.extremes.size() >= 10);
    for (const ExtremeCase& c : r.extremes) {
        INFO(c.name << ": " << c.outcome << " - " << c.detail);
        CHECK(c.stateFinite);
        CHECK(c.ok);
        CHECK(
            (c.outcome == "stable" || c.outcome == "detected failure" || c.outcome == "rejected"));
    }
    // Files: the tables have every row, the report names the machine.
    const Table sweep = readCsv(o.outDir / "stability_vs_stiffness.csv");
    CHECK(sweep.rows().size() == r.sweep.size());
    const Table ext = readCsv(o.outDir / "extreme_cases.csv");
    CHECK(ext.rows().size() == r.extremes.size());
    const std::string md = slurp(o.outDir / "report.md");
    CHECK(md.find("## Machine") != std::string::npos);
    CHECK(md.find("CPU") != std::string::npos);
    if (gnuplotAvailable()) CHECK(std::filesystem::exists(o.outDir / "stability_vs_stiffness.png"));
}
