// drape-report-compare: rebuilds the compare report (tables, figures, report.md) from scratch.
#include "report_common.hpp"

#include <drape_reports/reports.hpp>

#include <exception>

int main(int argc, char** argv) {
    using namespace drape::reports;
    tool::Args args;
    if (!tool::parse(argc, argv, "compare", args)) return 2;
    try {
        const Machine machine = describeMachine(argc, argv);
        CompareOptions options;
        options.outDir = args.out;
        options.quick = args.quick;
        options.render = args.render;
        const double t0 = now();
        runCompareReport(options, machine);
        progress("wrote " + (args.out / "report.md").string() + " in " + fmt(now() - t0, 3) + " s");
    } catch (const std::exception& e) {
        std::cerr << "drape-report-compare: " << e.what() << "\n";
        return 1;
    }
    return 0;
}
