// The comparison report on its reduced size: every scene x configuration present, the same
// links in every engine, numbers finite, and the physics each engine promises.
#include <drape_reports/reports.hpp>

#include <catch2/catch.hpp>

#include <cmath>
#include <map>

using namespace drape;
using namespace drape::reports;

TEST_CASE("compare report: rows, links, strain limit, iterations stiffen btSoftBody") {
    CompareOptions o;
    o.outDir = std::filesystem::path(DRAPE_REPORTS_TEST_OUT) / "compare";
    o.quick = true;
    const char* argv[] = {"test"};
    const CompareResult r = runCompareReport(o, describeMachine(1, argv));

    REQUIRE(r.rows.size() == 4 * 8); // four scenes x eight configurations
    std::map<std::string, std::size_t> springs;
    std::map<std::string, const CompareRow*> byKey;
    for (const CompareRow& row : r.rows) {
        if (row.engine == "drape") springs[row.scene] = row.links;
        byKey[row.scene + "|" + row.engine + "|" + row.config] = &row;
    }
    for (const CompareRow& row : r.rows) {
        INFO(row.scene << " " << row.engine << " " << row.config << " " << row.note);
        // CreateFromTriMesh makes one link per unique triangle edge, like drape.
        CHECK(row.links == springs.at(row.scene));
        CHECK(row.msPerStep > 0.0);
        CHECK(std::isfinite(row.peakMaxStrain));
        CHECK(std::isfinite(row.finalKinetic));
        CHECK(row.finalKinetic >= 0.0);
        CHECK_FALSE(row.blewUp);
        if (row.engine == "drape" && row.config.find("stress-ordered") != std::string::npos) {
            // The limiter's promise: 10 % plus its stop tolerance (1e-3). In scenes with
            // colliders the contact stage runs after the limiter in each step (the paper's
            // order) and its projections may stretch a spring a little more: allow 1 %.
            const bool contacts = row.scene == "experiment2" || row.scene.rfind("sphere", 0) == 0;
            CHECK(row.finalMaxStrain <= 0.10 + (contacts ? 1e-2 : 1.5e-3));
        }
    }
    // btSoftBody is a position solver: more iterations (or sub-steps) leave less stretch.
    for (const std::string scene : {"experiment1", "hanging16"}) {
        INFO(scene);
        const double p1 = byKey.at(scene + "|btSoftBody|piterations 1, 1 sub-step")->peakMaxStrain;
        const double p4 = byKey.at(scene + "|btSoftBody|piterations 4, 1 sub-step")->peakMaxStrain;
        const double p16 =
            byKey.at(scene + "|btSoftBody|piterations 16, 1 sub-step")->peakMaxStrain;
        const double s4 = byKey.at(scene + "|btSoftBody|piterations 1, 4 sub-steps")->peakMaxStrain;
        CHECK(p4 < p1);
        CHECK(p16 < p4);
        CHECK(s4 < p1);
    }
    const Table t = readCsv(o.outDir / "compare.csv");
    CHECK(t.rows().size() == r.rows.size());
}
