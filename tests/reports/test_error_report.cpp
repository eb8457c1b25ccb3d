// The error report on its reduced size: every row present, errors finite, convergence orders
// as the methods' theory says, references converged, Table 1 complete.
#include <drape_reports/reports.hpp>

#include <catch2/catch.hpp>

#include <cmath>
#include <map>

using namespace drape;
using namespace drape::reports;

TEST_CASE("error report: orders of convergence, references, Table 1") {
    ErrorOptions o;
    o.outDir = std::filesystem::path(DRAPE_REPORTS_TEST_OUT) / "error";
    o.quick = true;
    const char* argv[] = {"test"};
    const ErrorResult r = runErrorReport(o, describeMachine(1, argv));

    // 2 scenes x 2 limiter settings x 5 integrators x 4 time steps.
    REQUIRE(r.points.size() == 2 * 2 * 5 * 4);
    std::map<std::string, std::vector<const ErrorPoint*>> series;
    for (const ErrorPoint& p : r.points) {
        INFO(p.scene << " " << toString(p.integrator) << " dt " << p.dt);
        CHECK(p.wallSeconds >= 0.0);
        if (!p.unstable) CHECK(std::isfinite(p.error));
        // Implicit Euler is unconditionally stable.
        if (p.integrator == IntegratorKind::ImplicitEuler) CHECK_FALSE(p.unstable);
        series[p.scene + (p.limiter ? "+lim " : " ") + toString(p.integrator)].push_back(&p);
    }
    // Experiment I without the limiter is a smooth ODE: halving dt divides the error by
    // ~2^order. Order 1 for the Euler methods, 4 for RK4, 2 for Velocity-Verlet (also with
    // the scene's particle damping, which it applies as an exact velocity flow).
    auto ratios = [&](const std::string& key) {
        std::vector<double> q;
        const auto& s = series.at(key);
        for (std::size_t i = 1; i < s.size(); ++i)
            q.push_back(s[i - 1]->error / s[i]->error);
        return q;
    };
    for (double q : ratios("experiment1 explicit_euler"))
        CHECK(q == Approx(2.0).epsilon(0.25));
    for (double q : ratios("experiment1 symplectic_euler"))
        CHECK(q == Approx(2.0).epsilon(0.25));
    for (double q : ratios("experiment1 implicit_euler"))
        CHECK(q == Approx(2.0).epsilon(0.25));
    for (double q : ratios("experiment1 velocity_verlet"))
        CHECK(q == Approx(4.0).epsilon(0.25));
    {
        const auto q = ratios("experiment1 rk4");
        // Once in the asymptotic range (the last two halvings), the ratio is ~16.
        CHECK(q.back() >= 10.0);
        CHECK(q.back() <= 24.0);
    }
    // The reference is converged: its own error estimate (distance to 2 dt_ref) is far below
    // the sweep's errors without the limiter. Contact makes Experiment II first order, so
    // there the estimate is about dt_ref / dt_min = 1/16 of the smallest sweep error; 1/4
    // leaves room. With the limiter at least below (see the report: it does not converge).
    REQUIRE(r.references.size() == 4);
    for (const ReferenceCheck& c : r.references) {
        INFO(c.scene << (c.limiter ? " limiter" : ""));
        CHECK(std::isfinite(c.selfError));
        if (!c.limiter)
            CHECK(c.selfError < 0.25 * c.smallestSweepError);
        else
            CHECK(c.selfError < c.smallestSweepError);
    }
    REQUIRE(r.table1.size() == 5);
    for (const Table1Row& t : r.table1) {
        INFO(toString(t.integrator));
        CHECK_FALSE(t.unstable);
        CHECK(std::isfinite(t.error));
        CHECK(t.oursWall > 0.0);
    }
    CHECK(std::filesystem::exists(o.outDir / "table1.csv"));
    CHECK(readCsv(o.outDir / "error_all.csv").rows().size() == r.points.size());
}
