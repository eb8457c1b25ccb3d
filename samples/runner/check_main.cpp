// drape-check: says, before a run, whether a time step is stable for a cloth's integrator,
// stiffness and aerodynamics, and which time step or how many sub-steps would be.
//
//   drape-check --scene samples/scenes/experiment1_suspended_sheet.json [--dt 0.05]
//               [--integrator rk4]
//   drape-check --rows 35 --cols 35 --spacing 10 --mass 0.5 --stiffness 20 --damping 0.05
//               --pins top-corners --integrator velocity_verlet --dt 0.01
// When the step is stable it then runs a trial (--trial seconds of simulated time, 2 by
// default, 0 for none; at most --trial-cpu seconds of CPU) and says what a step cost: a scene
// with its world, bodies and contacts as drape-run steps it, a sheet as Cloth::step.
// Options are parsed by CLI11: a count that is not a whole number in range (--rows 2.5,
// --rows 4294967331) or a value that is not a finite number is refused, never rounded.
// Exit status: 0 stable, 3 unstable, 1 bad input, 2 usage.
#include <drape_samples/check.hpp>

#include <drape/error.hpp>
#include <drape_samples/scene.hpp>
#include <drape_samples/simulation.hpp>

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>

int main(int argc, char** argv) {
    using namespace drape;
    CLI::App app{"drape-check: whether a time step is stable for a cloth, and what would be. "
                 "Defaults: the paper's Experiment I (35 x 35, spacing 10, mass 0.5, k 20, "
                 "C_d 0.05, top corners pinned, velocity_verlet, dt 0.01)"};
    std::string scenePath, integratorName, pins = "top-corners";
    std::optional<double> dt;
    double trialSeconds = 2.0, trialCpu = 5.0;
    // Counts as 64-bit integers, checked against the range a sheet can have: CLI11 refuses a
    // value that is not a whole number or does not fit.
    long long rows = 35, cols = 35;
    double spacing = 10.0, mass = 0.5, stiffness = 20.0, damping = 0.05, springDamping = 0.0;
    // CLI11's Range lets NaN through (it tests val < min || val > max): finite first.
    const CLI::Validator finite(
        [](std::string& in) {
            double v = 0.0;
            if (!CLI::detail::lexical_cast(in, v) || !std::isfinite(v))
                return std::string("not a finite number: ") + in;
            return std::string();
        },
        "FINITE");
    const CLI::Validator positive = finite & CLI::Range(1e-300, 1e300);
    const CLI::Validator nonNegative = finite & CLI::Range(0.0, 1e300);
    auto* sceneOpt = app.add_option("--scene", scenePath, "Scene file (JSON, samples/SCENES.md)");
    app.add_option(
           "--dt", dt,
           "Cloth time step [s] (default: the scene's time step over its sub-steps, or 0.01)")
        ->check(positive);
    app.add_option("--integrator", integratorName,
                   "explicit_euler, symplectic_euler, velocity_verlet, rk4 or implicit_euler");
    app.add_option("--trial", trialSeconds,
                   "Simulated seconds of a trial run that measures what a step costs on this "
                   "machine (default 2; 0: no trial)")
        ->check(finite & CLI::Range(0.0, 1e6));
    app.add_option("--trial-cpu", trialCpu, "CPU seconds after which the trial stops (default 5)")
        ->check(positive);
    // The sheet's options: each checked, none together with --scene.
    auto sheetOption = [&app, sceneOpt](const char* name, auto& value, const char* help,
                                        const CLI::Validator& check) {
        app.add_option(name, value, help)
            ->check(check)
            ->excludes(sceneOpt)
            ->group("a generated sheet (not with --scene)");
    };
    const CLI::Validator count = CLI::Range(2LL, 100000LL);
    sheetOption("--rows", rows, "Rows of the sheet (2 to 100000)", count);
    sheetOption("--cols", cols, "Columns of the sheet (2 to 100000)", count);
    // Ranges that keep the sheet's extent and sqrt(k / m) within double precision.
    const CLI::Validator physical = finite & CLI::Range(1e-12, 1e12);
    sheetOption("--spacing", spacing, "Grid spacing (1e-12 to 1e12)", physical);
    sheetOption("--mass", mass, "Particle mass (1e-12 to 1e12)", physical);
    sheetOption("--stiffness", stiffness, "Spring stiffness (1e-12 to 1e12)", physical);
    sheetOption("--damping", damping, "C_d of eq. (8)", nonNegative);
    sheetOption("--spring-damping", springDamping, "Damping along the springs", nonNegative);
    sheetOption("--pins", pins, "top-corners or none", CLI::IsMember({"top-corners", "none"}));
    try {
        app.parse(argc, argv);
    } catch (const CLI::CallForHelp& e) {
        return app.exit(e);
    } catch (const CLI::ParseError& e) {
        app.exit(e);
        return 2;
    }
    try {
        std::optional<IntegratorKind> integrator;
        if (!integratorName.empty()) integrator = integratorFromString(integratorName);
        samples::TimeStepCheck result;
        std::string what;
        if (!scenePath.empty()) {
            samples::SceneDesc scene = samples::loadScene(scenePath);
            if (integrator) scene.cloth.integrator = *integrator;
            scene.cloth.rejectUnstableTimeStep = false; // we are asking, not stepping
            samples::Simulation sim(scene);
            // What the scene's own step would do (the trial runs it, whatever --dt asks).
            const double ownStep = scene.timeStep / sim.substeps();
            // What loading the scene noticed (a mesh's loose triangles, a weld that merged
            // much, a material assimp could not find), as drape-run prints it.
            for (const std::string& w : sim.warnings())
                std::cerr << "drape-check: warning: " << w << "\n";
            // The aerodynamics judged at the strongest wind of the scene's gusts.
            if (scene.wind) sim.cloth().setWind(scene.wind->strongest());
            // The scene's own cloth step: its time step over its sub-steps (a count, or what
            // "auto" chose); --dt asks about one cloth step of that length instead.
            const int substeps = dt ? 1 : sim.substeps();
            result = samples::checkTimeStep(sim.cloth(), dt.value_or(scene.timeStep / substeps));
            what = scene.name + " (" + std::to_string(sim.cloth().particleCount()) + " particles";
            if (substeps > 1) {
                std::ostringstream step;
                step << ", time_step " << scene.timeStep << " s in " << substeps << " sub-steps";
                what += step.str();
            }
            what += ")";
            std::cout << what << ": " << result.message << "\n";
            // The count the file must give: the verdict above counts sub-steps of one cloth
            // step (time_step / substeps), not of the scene's time_step (review 16: "4
            // sub-steps" for a scene of 3, which then said "3"; it needs 10).
            if (!result.stable && !dt && !scene.autoSubsteps && result.limit > 0.0 &&
                std::isfinite(result.limit))
                std::cout << "in the scene: set simulation.substeps to at least "
                          << static_cast<long long>(std::ceil(scene.timeStep / result.limit))
                          << " (its time_step of " << scene.timeStep << " s in cloth steps of "
                          << samples::formatDown(result.limit) << " s or less), or to \"auto\"\n";
            // A fixed count is checked at the cloth's speed of each step: outrun as the cloth
            // speeds up against the air, its step is refused ("auto" splits as the speed asks).
            if (result.stable && !dt && !scene.autoSubsteps && std::isfinite(result.aeroSpeed))
                std::cout << "in the scene: with a fixed simulation.substeps the cloth's steps "
                             "are refused once it moves faster than "
                          << result.aeroSpeed
                          << " m/s against the air; \"auto\" splits each step as its speed "
                             "asks\n";
            if (trialSeconds > 0.0) {
                const bool ownStable = samples::checkTimeStep(sim.cloth(), ownStep).stable;
                // Back to the wind of t = 0 (the mean: its gust is a sine), as drape-run starts.
                if (scene.wind) sim.cloth().setWind(scene.wind->velocity);
                if (!ownStable) {
                    std::cout << "trial: not run (the scene's own cloth step, " << ownStep
                              << " s, is unstable)\n";
                    return result.stable ? 0 : 3;
                }
                std::cout << std::flush; // the verdict first, whatever the trial does
                try {
                    std::cout << samples::trialCost(sim, trialSeconds, trialCpu).message << "\n";
                } catch (const samples::StepError& e) {
                    // The scene does not run: an unstable answer, whatever the estimate said.
                    std::cout << "trial: FAILED: " << e.what() << "\n";
                    return 3;
                }
            }
            return result.stable ? 0 : 3;
        } else {
            SheetSpec sheet;
            sheet.rows = static_cast<Index>(rows);
            sheet.cols = static_cast<Index>(cols);
            sheet.spacing = spacing;
            ClothSettings s;
            s.integrator = integrator.value_or(IntegratorKind::VelocityVerlet);
            s.particleMass = mass;
            s.springStiffness = stiffness;
            s.damping = damping;
            s.springDamping = springDamping;
            s.rejectUnstableTimeStep = false;
            Cloth cloth(ClothTopology::build(makeSheet(sheet)), s);
            if (pins == "top-corners") {
                cloth.pin(sheetIndex(sheet, 0, 0));
                cloth.pin(sheetIndex(sheet, 0, sheet.cols - 1));
            }
            result = samples::checkTimeStep(cloth, dt.value_or(0.01));
            what = std::to_string(sheet.rows) + " x " + std::to_string(sheet.cols) + " sheet";
            std::cout << what << ": " << result.message << "\n";
            if (trialSeconds > 0.0 && result.stable) {
                const double step = dt.value_or(0.01);
                // In double first: --trial 1e6 at --dt 1e-300 exceeds any integer. The budget
                // stops the trial long before a billion steps.
                const auto steps = static_cast<std::size_t>(
                    std::min(1e9, std::max(1.0, std::ceil(trialSeconds / step))));
                std::cout << std::flush;
                try {
                    std::cout << samples::trialCost(
                                     [&cloth, step] { cloth.step(step); }, step, 1, steps, trialCpu,
                                     nullptr, [&cloth] { return samples::clothStepsTaken(cloth); })
                                     .message
                              << "\n";
                } catch (const Error& e) {
                    std::cout << "trial: FAILED: " << e.what() << "\n";
                    return 3;
                }
            }
        }
        return result.stable ? 0 : 3;
    } catch (const std::exception& e) {
        std::cerr << "drape-check: " << e.what() << "\n";
        return 1;
    }
}
