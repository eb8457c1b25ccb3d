// Static equilibrium: a hanging strip two particles wide settles to the tensions statics
// predicts.
//
// The strip is makeSheet with 2 columns: two vertical chains joined by rungs and one diagonal
// per cell (alternating direction). It is a statically determinate plane truss (each new row
// adds 2 nodes = 4 equations and 4 bars: 2 verticals, 1 rung, 1 diagonal), so member forces
// follow from statics alone. Cut the strip below row r: the cut crosses the two verticals and
// one diagonal; the part below weighs W_r = 2 (R - 1 - r) m g.
//  - horizontal equilibrium of that part: only the diagonal has a horizontal component, so
//    the diagonal carries no force;
//  - vertical equilibrium and moments (the loads are symmetric): each vertical carries
//    W_r / 2 = (R - 1 - r) m g, the weight of the particles below it in its own column;
//  - the equilibrium of a node along the rung then gives zero rung force.
// So vertical spring r of each column stretches by (R - 1 - r) m g / k, rungs and diagonals
// not at all. This is small-displacement statics: the deformed geometry (verticals tilt by
// ~strain as the strip shears to keep the diagonals' lengths) changes the forces by a
// relative O(strain); with strain <= 1e-4 a 1e-3 relative tolerance covers it.
#include "helpers.hpp"
#include "measured.hpp"

#include "drape/cloth.hpp"

#include <cstdio>

using namespace drape;
using namespace drape_test;

namespace {

constexpr Index kRows = 11;
constexpr double kSpacing = 0.1; // m
constexpr double kMass = 0.01;   // kg per particle
constexpr double kK = 1.0e5;     // N/m: top strain 1e-4
constexpr double kG = 9.81;      // m/s^2

struct Strip {
    SheetSpec spec;
    std::unique_ptr<Cloth> cloth;
};

Strip makeStrip(IntegratorKind kind, double damping) {
    Strip s;
    s.spec.rows = kRows;
    s.spec.cols = 2;
    s.spec.spacing = kSpacing; // row r at y = -r s: row 0 on top
    ClothSettings set;
    set.integrator = kind;
    set.particleMass = kMass;
    set.springStiffness = kK;
    set.gravity = Vec3(0, -kG, 0);
    set.damping = damping;
    set.limiter.kind = LimiterKind::None;
    s.cloth = std::make_unique<Cloth>(ClothTopology::build(makeSheet(s.spec)), set);
    s.cloth->pin(sheetIndex(s.spec, 0, 0));
    s.cloth->pin(sheetIndex(s.spec, 0, 1));
    return s;
}

double maxSpeed(const Cloth& c) {
    double v = 0.0;
    for (const Vec3& vi : c.velocities())
        v = std::max(v, vi.norm());
    return v;
}

void checkStatics(const Strip& s) {
    const Cloth& c = *s.cloth;
    const auto& x = c.positions();
    const double topExtension = (kRows - 1) * kMass * kG / kK; // ~1e-5 m, strain 1e-4
    double worst = 0.0;
    for (const Spring& sp : c.topology().springs()) {
        const Index ra = sp.a / 2, rb = sp.b / 2;
        const bool vertical = (sp.a % 2) == (sp.b % 2);
        const double extension = (x[sp.b] - x[sp.a]).norm() - sp.restLength;
        if (vertical) {
            const Index r = std::min(ra, rb);
            const double expected = (kRows - 1 - r) * kMass * kG / kK;
            INFO("vertical spring below row " << r);
            CHECK(extension == Approx(expected).epsilon(1e-3));
            worst = std::max(worst, std::abs(extension - expected) / expected);
        } else if (ra != 0 || rb != 0) { // rungs and diagonals (the pinned top rung aside)
            INFO("rung or diagonal " << sp.a << "-" << sp.b);
            // Zero force in small-displacement statics; geometric effects make it O(strain)
            // of the vertical extensions: bound it at 1 % of the top one.
            CHECK(std::abs(extension) < 1e-2 * topExtension);
        }
    }
    INFO(measured("hanging strip: worst relative error of vertical extensions %.2e "
                  "(top extension %.4e m)",
                  worst, topExtension));
}

} // namespace

TEST_CASE("Hanging strip settles to the statically determinate tensions", "[statics]") {
    SECTION("Velocity-Verlet with damping (dynamic relaxation)") {
        // Damping near critical for the lowest axial mode: a column is a fixed-free chain of
        // N = 10 masses, omega_1 = 2 sqrt(k/m) sin(pi / (2 (2N + 1))) ~ 470 rad/s; the
        // diagonals stiffen it, so C_d = 2 m omega_1 ~ 9 N s/m is at or below critical for the
        // axial modes (slow, overdamped in-plane bending takes longer; the loop waits).
        const double omega1 = 2.0 * std::sqrt(kK / kMass) * std::sin(kPi / (2.0 * 21.0));
        Strip s = makeStrip(IntegratorKind::VelocityVerlet, 2.0 * kMass * omega1);
        const double dt = 0.5 * s.cloth->stableTimeStep();
        int steps = 0;
        while (steps < 1000000 && (steps < 10 || maxSpeed(*s.cloth) > 1e-10)) {
            s.cloth->step(dt);
            ++steps;
        }
        INFO(measured("hanging strip (VV, dt %.3e s) settled in %d steps", dt, steps));
        // Residual speed 1e-10 m/s means position errors ~ v / omega_1 ~ 1e-12 m, far below
        // the 1e-8 m the tolerance allows.
        REQUIRE(maxSpeed(*s.cloth) <= 1e-10);
        checkStatics(s);
    }
    SECTION("implicit Euler with a large time step reaches the same equilibrium") {
        // Backward Euler's fixed points are exactly the static equilibria (v = 0, f = 0),
        // whatever the time step.
        Strip s = makeStrip(IntegratorKind::ImplicitEuler, 1.0);
        int steps = 0;
        while (steps < 5000 && (steps < 10 || maxSpeed(*s.cloth) > 1e-10)) {
            s.cloth->step(0.02); // ~40 times Velocity-Verlet's stability limit
            ++steps;
        }
        INFO(measured("hanging strip (implicit Euler, dt 0.02 s) settled in %d steps", steps));
        REQUIRE(maxSpeed(*s.cloth) <= 1e-10);
        checkStatics(s);
    }
}
