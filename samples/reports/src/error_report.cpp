#include "drape_reports/reports.hpp"
#include <stdexcept>
namespace drape::reports {
ErrorResult runErrorReport(const ErrorOptions&, const Machine&) { throw std::runtime_error("todo"); }
}
