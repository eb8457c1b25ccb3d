// drape-report-error: rebuilds the error report (tables, figures, report.md) from scratch.
#include "report_common.hpp"

#include <drape_reports/reports.hpp>

#include <exception>

int main(int argc, char** argv) {
    using namespace drape::reports;
    tool::Args args;
    if (!tool::parse(argc, argv, "error", args)) return 2;
    try {
        const Machine machine = describeMachine(argc, argv);
        ErrorOptions options;
        options.outDir = args.out;
        options.quick = args.quick;
        const double t0 = now();
        runErrorReport(options, machine);
        progress("wrote " + (args.out / "report.md").string() + " in " + fmt(now() - t0, 3) + " s");
    } catch (const std::exception& e) {
        std::cerr << "drape-report-error: " << e.what() << "\n";
        return 1;
    }
    return 0;
}
