// drape_reports/reports.hpp: the three reports as functions. Each writes report.md, CSV
// tables and PNG figures into options.outDir and returns its numbers, so the programs
// (tools/report_*.cpp) and the tests (tests/reports) run exactly the same code; `quick`
// selects the reduced sizes the tests use.
#pragma once

#include "drape_reports/report.hpp"

#include <drape/settings.hpp>

#include <filesystem>
#include <string>
#include <vector>

namespace drape::reports {

/// All five integrators, in the order the reports list them.
const std::vector<IntegratorKind>& allIntegrators();

// --- stability --------------------------------------------------------------------------------

struct StabilityOptions {
    std::filesystem::path outDir;
    bool quick = false; ///< smaller grid, fewer stiffnesses and steps (for CTest)
};

/// Largest stable dt of one integrator at one stiffness.
struct StabilityPoint {
    IntegratorKind integrator;
    double stiffness = 0.0;    ///< k [N/m]
    double omegaBound = 0.0;   ///< drape's bound on omega_max (spring Laplacian) [rad/s]
    double omegaRest = 0.0;    ///< exact omega_max of the 3D stiffness at rest [rad/s]
    double omegaFinal = 0.0;   ///< exact omega_max at the end of a stable run [rad/s]
    double theoryLimit = 0.0;  ///< the integrator's limit from omegaBound [s] (inf: none)
    double horizonLimit = 0.0; ///< explicit Euler only: growth limit over the run's horizon [s]
    double measured = 0.0;     ///< largest dt found stable [s]
    bool stableAtAllTested = false; ///< no instability found up to `measured` (implicit)
};

/// One extreme case and what happened.
struct ExtremeCase {
    std::string name;
    std::string setup;
    std::string outcome;     ///< "stable", "detected failure", "rejected"
    std::string detail;      ///< numbers or the error message
    bool stateFinite = true; ///< no NaN or infinity left in the cloth's state
    bool ok = false;         ///< the outcome is the expected, clean one
};

struct StabilityResult {
    std::vector<StabilityPoint> sweep;
    std::vector<ExtremeCase> extremes;
    std::vector<std::string> checkExamples; ///< checkTimeStep messages shown in the report
};

StabilityResult runStabilityReport(const StabilityOptions& options, const Machine& machine);

// --- error against run time ------------------------------------------------------------------

struct ErrorOptions {
    std::filesystem::path outDir;
    bool quick = false;
};

struct ErrorPoint {
    std::string scene;    ///< "experiment1", "experiment2"
    bool limiter = false; ///< stress-ordered strain limiter on
    IntegratorKind integrator;
    double dt = 0.0;          ///< [s]
    double wallSeconds = 0.0; ///< run time of the whole run [s]
    double error = 0.0;       ///< RMS particle distance to the reference, max over the check times
    double relError = 0.0;    ///< error / grid spacing [-]
    bool unstable = false;    ///< blew up (detected failure) or diverged
    std::string note;
};

struct ReferenceCheck {
    std::string scene;
    bool limiter = false;
    double dtRef = 0.0;              ///< reference dt [s]
    double selfError = 0.0;          ///< RMS distance between reference(dt) and reference(2 dt)
    double crossError = 0.0;         ///< RMS distance between RK4 and Velocity-Verlet at dtRef
    double smallestSweepError = 0.0; ///< smallest error of any sweep point (for comparison)
};

struct Table1Row {
    IntegratorKind integrator;
    double dt = 0.0;
    double paperSeconds = 0.0; ///< the paper's "total time" [s]
    double oursWall = 0.0;     ///< our wall time to the settle time or the cap [s]
    double settleTime = 0.0;   ///< simulated time at which it settled [s] (inf: not)
    double error = 0.0;        ///< against the reference at the check times
    bool unstable = false;
};

struct ErrorResult {
    std::vector<ErrorPoint> points;
    std::vector<ReferenceCheck> references;
    std::vector<Table1Row> table1;
};

ErrorResult runErrorReport(const ErrorOptions& options, const Machine& machine);

// --- comparison with Bullet's soft bodies ----------------------------------------------------

struct CompareOptions {
    std::filesystem::path outDir;
    bool quick = false;
    bool render = true;
};

struct CompareRow {
    std::string scene;
    std::string engine; ///< "drape", "btSoftBody", "btDeformable"
    std::string config; ///< integrator / piterations / sub-steps ...
    std::size_t particles = 0;
    std::size_t links = 0;
    double msPerStep = 0.0; ///< median over repeated runs of the mean step time [ms]
    double peakMaxStrain = 0.0, peakMeanStrain = 0.0;
    double finalMaxStrain = 0.0, finalMeanStrain = 0.0;
    double peakPenetration = 0.0; ///< deepest penetration during the run [scene length]
    std::size_t peakInside = 0;   ///< most particles inside colliders at once
    std::size_t finalInside = 0;
    double settleTime = 0.0;   ///< [s]; inf when it did not settle in the run
    double finalKinetic = 0.0; ///< [J]
    bool blewUp = false;
    std::string note;
};

struct CompareResult {
    std::vector<CompareRow> rows;
};

CompareResult runCompareReport(const CompareOptions& options, const Machine& machine);

} // namespace drape::reports
