#include "drape_reports/reports.hpp"
#include <stdexcept>
namespace drape::reports {
CompareResult runCompareReport(const CompareOptions&, const Machine&) { throw std::runtime_error("todo"); }
}
