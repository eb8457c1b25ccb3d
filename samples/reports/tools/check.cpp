// drape-check: says, before a run, whether a time step is stable for a cloth's integrator and
// stiffness, and which time step or how many sub-steps would be.
//
//   drape-check --scene samples/scenes/experiment1_suspended_sheet.json [--dt 0.05] [--integrator
//   rk4] drape-check --rows 35 --cols 35 --spacing 10 --mass 0.5 --stiffness 20 --damping 0.05
//               --pins top-corners --integrator velocity_verlet --dt 0.01
// Exit status: 0 stable, 3 unstable, 1 bad input, 2 usage.
#include <drape_reports/check.hpp>
#include <drape_reports/report.hpp>

#include <drape/error.hpp>
#include <drape_samples/scene.hpp>
#include <drape_samples/simulation.hpp>

#include <iostream>
#include <map>
#include <optional>
#include <string>

namespace {

void usage() {
    std::cerr
        << "usage: drape-check --scene FILE [--dt S] [--integrator NAME]\n"
           "       drape-check [--rows N] [--cols N] [--spacing L] [--mass KG] [--stiffness N/m]\n"
           "                   [--damping Ns/m] [--spring-damping Ns/m] [--pins top-corners|none]\n"
           "                   [--integrator NAME] [--dt S]\n"
           "integrators: explicit_euler symplectic_euler velocity_verlet rk4 implicit_euler\n"
           "defaults: the paper's Experiment I (35 x 35, spacing 10, mass 0.5, k 20, C_d 0.05,\n"
           "top corners pinned, velocity_verlet, dt 0.01)\n";
}

} // namespace

int main(int argc, char** argv) {
    using namespace drape;
    std::map<std::string, std::string> opt;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (a.rfind("--", 0) != 0 || i + 1 >= argc) {
            usage();
            return 2;
        }
        opt[a.substr(2)] = argv[++i];
    }
    auto num = [&opt](const std::string& key, double def) {
        auto it = opt.find(key);
        if (it == opt.end()) return def;
        std::size_t used = 0;
        const double v = std::stod(it->second, &used);
        if (used != it->second.size())
            throw std::invalid_argument("--" + key + ": not a number: " + it->second);
        return v;
    };
    try {
        for (const auto& [k, v] : opt) {
            static const char* known[] = {
                "scene", "dt",        "integrator", "rows",           "cols", "spacing",
                "mass",  "stiffness", "damping",    "spring-damping", "pins"};
            bool ok = false;
            for (const char* n : known)
                ok = ok || k == n;
            if (!ok) throw std::invalid_argument("unknown option --" + k);
        }
        std::optional<IntegratorKind> integrator;
        if (opt.count("integrator")) integrator = integratorFromString(opt["integrator"]);
        reports::TimeStepCheck result;
        std::string what;
        if (opt.count("scene")) {
            samples::SceneDesc scene = samples::loadScene(opt["scene"]);
            if (integrator) scene.cloth.integrator = *integrator;
            scene.cloth.rejectUnstableTimeStep = false; // we are asking, not stepping
            const double dt = num("dt", scene.timeStep);
            samples::Simulation sim(scene);
            result = reports::checkTimeStep(sim.cloth(), dt);
            what = scene.name + " (" + std::to_string(sim.cloth().particleCount()) + " particles)";
        } else {
            SheetSpec sheet;
            sheet.rows = static_cast<Index>(num("rows", 35));
            sheet.cols = static_cast<Index>(num("cols", 35));
            sheet.spacing = num("spacing", 10.0);
            ClothSettings s;
            s.integrator = integrator.value_or(IntegratorKind::VelocityVerlet);
            s.particleMass = num("mass", 0.5);
            s.springStiffness = num("stiffness", 20.0);
            s.damping = num("damping", 0.05);
            s.springDamping = num("spring-damping", 0.0);
            s.rejectUnstableTimeStep = false;
            Cloth cloth(ClothTopology::build(makeSheet(sheet)), s);
            const std::string pins = opt.count("pins") ? opt["pins"] : "top-corners";
            if (pins == "top-corners") {
                cloth.pin(sheetIndex(sheet, 0, 0));
                cloth.pin(sheetIndex(sheet, 0, sheet.cols - 1));
            } else if (pins != "none") {
                throw std::invalid_argument("--pins must be top-corners or none, got " + pins);
            }
            result = reports::checkTimeStep(cloth, num("dt", 0.01));
            what = std::to_string(sheet.rows) + " x " + std::to_string(sheet.cols) + " sheet";
        }
        std::cout << what << ": " << result.message << "\n";
        return result.stable ? 0 : 3;
    } catch (const std::exception& e) {
        std::cerr << "drape-check: " << e.what() << "\n";
        return 1;
    }
}
