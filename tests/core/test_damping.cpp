// Damping and external forces inside a running cloth, against analytic solutions: the damped
// breathing triangle (spring damping and linear damping), convergence orders with damping,
// terminal velocity under aerodynamic drag, the static stretch of a user force, and the
// implicit integrator's two linear solvers agreeing.
#include "helpers.hpp"
#include "measured.hpp"

#include "drape/cloth.hpp"

#include <cstdio>
#include <utility>

using namespace drape;
using namespace drape_test;

namespace {

/// The breathing mode of a free equilateral triangle (see test_integrators.cpp) with damping.
/// Spring damping c acts on the rate of change of each edge, l' = sqrt(3) r', and sums to a
/// radial 3 c r' exactly as the springs sum to 3 k (r - r0); linear damping C_d gives C_d r'.
/// So m r'' = -3k (r - r0) - (3c + C_d) r': a damped linear oscillator with
/// gamma = (3c + C_d) / (2m) and omega_d = sqrt(3k/m - gamma^2).
struct DampedBreathing {
    double r0 = 1.0, m = 1.0, k = 1.0, amp = 0.1;
    double springDamping = 0.0, linearDamping = 0.0;
    double gamma() const { return (3.0 * springDamping + linearDamping) / (2.0 * m); }
    double omegaD() const { return std::sqrt(3.0 * k / m - gamma() * gamma()); }

    std::unique_ptr<Cloth> make(IntegratorKind kind) const {
        ClothSettings s;
        s.relativeDamping = 0.0; // the motion measured here is undamped or damped by C_d only
        s.integrator = kind;
        s.particleMass = m;
        s.springStiffness = k;
        s.springDamping = springDamping;
        s.damping = linearDamping;
        s.gravity = Vec3::Zero();
        s.limiter.kind = LimiterKind::None;
        auto cloth = std::make_unique<Cloth>(ClothTopology::build(equilateralTriangle(r0)), s);
        const auto d = equilateralDirections();
        for (Index i = 0; i < 3; ++i)
            cloth->setPosition(i, (r0 + amp) * d[i]);
        return cloth;
    }
    /// Radial displacement and velocity of the analytic solution released from rest.
    double u(double t) const {
        const double g = gamma(), w = omegaD();
        return amp * std::exp(-g * t) * (std::cos(w * t) + g / w * std::sin(w * t));
    }
    double du(double t) const {
        const double g = gamma(), w = omegaD();
        return -amp * std::exp(-g * t) * (g * g / w + w) * std::sin(w * t);
    }
    /// sqrt(sum |x - x*|^2 + |v - v*|^2 / omega^2) over the three corners [m].
    double error(const Cloth& c, double t) const {
        const auto d = equilateralDirections();
        const double w2 = 3.0 * k / m;
        double e2 = 0.0;
        for (Index i = 0; i < 3; ++i) {
            e2 += (c.positions()[i] - (r0 + u(t)) * d[i]).squaredNorm() +
                  (c.velocities()[i] - du(t) * d[i]).squaredNorm() / w2;
        }
        return std::sqrt(e2);
    }
};

double convergenceOrder(const DampedBreathing& osc, IntegratorKind kind, const std::vector<int>& Ns,
                        double T) {
    std::vector<double> dts, errs;
    for (int N : Ns) {
        auto cloth = osc.make(kind);
        for (int n = 0; n < N; ++n)
            cloth->step(T / N);
        dts.push_back(T / N);
        errs.push_back(osc.error(*cloth, T));
    }
    const double slope = logLogSlope(dts, errs);
    std::string line = measured("damped breathing, %-16s:", toString(kind));
    for (std::size_t i = 0; i < dts.size(); ++i)
        line += measured("  dt=%.4f: %.3e", dts[i], errs[i]);
    line += measured("  -> order %.3f", slope);
    UNSCOPED_INFO(line); // shown with the caller's assertion on the order
    return slope;
}

} // namespace

TEST_CASE("Damped oscillator decays as the analytic solution", "[damping]") {
    // RK4 at dt = 1e-3 is accurate to ~1e-13 here, so the comparison tests the damping forces
    // themselves (their coefficient and direction), not the integrator.
    for (int which = 0; which < 2; ++which) {
        DampedBreathing osc;
        (which == 0 ? osc.springDamping : osc.linearDamping) = 0.2;
        INFO((which == 0 ? "spring damping" : "linear damping"));
        auto cloth = osc.make(IntegratorKind::RungeKutta4);
        const int N = 3000;
        const double dt = 1e-3;
        double e0 = cloth->kineticEnergy() + cloth->springEnergy();
        for (int n = 0; n < N; ++n)
            cloth->step(dt);
        CHECK(osc.error(*cloth, N * dt) < 1e-10);
        // And the energy went down (dissipation), by the factor of the envelope exp(-2 gamma t)
        // up to the phase-dependent split between kinetic and potential energy.
        const double e = cloth->kineticEnergy() + cloth->springEnergy();
        CHECK(e < e0);
        CHECK(e < e0 * std::exp(-2.0 * osc.gamma() * N * dt) * 1.5);
    }
}

TEST_CASE("Convergence orders with damping", "[damping][convergence]") {
    DampedBreathing osc;
    osc.springDamping = 0.2; // damping ratio gamma / omega = 0.17
    const double T = 2.0;
    // Same ranges and tolerance as the undamped orders (test_integrators.cpp).
    CHECK(convergenceOrder(osc, IntegratorKind::RungeKutta4, {50, 100, 200, 400}, T) ==
          Approx(4.0).margin(0.1));
    CHECK(convergenceOrder(osc, IntegratorKind::SymplecticEuler, {400, 800, 1600, 3200}, T) ==
          Approx(1.0).margin(0.1));
    CHECK(convergenceOrder(osc, IntegratorKind::ImplicitEuler, {400, 800, 1600, 3200}, T) ==
          Approx(1.0).margin(0.1));
}

// Velocity-Verlet runs the linear and the spring damping as velocity flows dt/2 on each side
// of its kick-drift-kick (a Strang split, see integrators.cpp); with the damping as a force at
// the half-step velocity it was first order (measured 1.008).
TEST_CASE("Velocity-Verlet stays second order with damping", "[damping][convergence]") {
    for (int which = 0; which < 3; ++which) {
        DampedBreathing osc;
        osc.springDamping = which != 1 ? 0.2 : 0.0;
        osc.linearDamping = which != 0 ? 0.3 : 0.0;
        INFO((which == 0 ? "spring damping" : which == 1 ? "linear damping" : "both"));
        CHECK(convergenceOrder(osc, IntegratorKind::VelocityVerlet, {50, 100, 200, 400}, 2.0) ==
              Approx(2.0).margin(0.1));
    }
}

TEST_CASE(
    "Velocity-Verlet with damping and aerodynamics converges at second order on an irregular sheet",
    "[damping][convergence]") {
    // Unequal (area-lumped) masses, a pinned particle, gravity, both dampings, drag and lift
    // in a wind:
    // no closed form, so the order comes from the differences of runs at dt and dt/2, which
    // shrink as dt^p for a method of order p.
    const auto topo = ClothTopology::build(irregularMesh(4, 4, 7));
    auto run = [&](int N) {
        ClothSettings s;
        s.relativeDamping = 0.0; // the motion measured here is undamped or damped by C_d only
        s.totalMass = 1.0;
        s.lumping = MassLumping::AreaLumped;
        s.springStiffness = 5.0;
        s.springDamping = 0.3;
        s.damping = 0.2;
        s.aero.airDensity = 1.2;
        s.aero.dragCoefficient = 1.0;
        s.aero.liftCoefficient = 0.3;
        s.aero.wind = Vec3(1.0, 0.0, 0.5);
        s.limiter.kind = LimiterKind::None;
        auto cloth = std::make_unique<Cloth>(topo, s);
        Rng rng(11);
        for (Index i = 0; i < cloth->particleCount(); ++i) {
            cloth->setPosition(i, cloth->positions()[i] + 0.1 * Vec3(rng.uniform(-1, 1),
                                                                     rng.uniform(-1, 1),
                                                                     rng.uniform(-1, 1)));
            cloth->setVelocity(i, Vec3(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)));
        }
        cloth->pin(0);
        for (int n = 0; n < N; ++n)
            cloth->step(1.0 / N);
        return cloth;
    };
    std::vector<double> dts, diffs;
    auto previous = run(100);
    for (int N : {200, 400, 800, 1600}) {
        auto next = run(N);
        double d2 = 0.0;
        for (std::size_t i = 0; i < next->particleCount(); ++i) {
            d2 += (next->positions()[i] - previous->positions()[i]).squaredNorm() +
                  (next->velocities()[i] - previous->velocities()[i]).squaredNorm();
        }
        dts.push_back(1.0 / N);
        diffs.push_back(std::sqrt(d2));
        previous = std::move(next);
    }
    const double order = logLogSlope(dts, diffs);
    std::string line = measured("irregular sheet, damping and aero, velocity_verlet: differences");
    for (double d : diffs)
        line += measured(" %.3e", d);
    line += measured(" -> order %.3f", order);
    INFO(line);
    CHECK(order == Approx(2.0).margin(0.1));
}

TEST_CASE("Velocity-Verlet: linear damping decays a free particle's velocity exactly",
          "[damping]") {
    // A triangle translating rigidly (springs at rest length, no gravity): each corner obeys
    // m v' = -C_d v alone, v(t) = v0 exp(-C_d t / m). The split applies exactly this decay, so
    // the velocity matches it to rounding at any dt, even dt = 6 m / C_d (where a damping
    // force in an explicit kick would be unstable). Rounding: the same factor is applied 2N
    // times, a relative error of at most ~2N ulp.
    const double m = 0.2, cd = 0.3, T = 4.0;
    const Vec3 v0(0.7, -0.4, 0.2);
    for (int N : {4000, 400, 40, 4, 1}) {
        ClothSettings s;
        s.relativeDamping = 0.0; // the motion measured here is undamped or damped by C_d only
        s.particleMass = m;
        s.springStiffness = 1e-6; // keeps the stability limit far above dt = 4
        s.damping = cd;
        s.gravity = Vec3::Zero();
        s.limiter.kind = LimiterKind::None;
        Cloth cloth(ClothTopology::build(equilateralTriangle(1.0)), s);
        for (Index i = 0; i < 3; ++i)
            cloth.setVelocity(i, v0);
        for (int n = 0; n < N; ++n)
            cloth.step(T / N);
        const Vec3 exact = v0 * std::exp(-cd * T / m);
        INFO("dt = " << T / N);
        for (Index i = 0; i < 3; ++i) {
            CHECK((cloth.velocities()[i] - exact).norm() <= 4.0 * (N + 4) * 2.3e-16 * exact.norm());
        }
    }
}

TEST_CASE("Velocity-Verlet: damping leaves pinned and kinematic particles alone", "[damping]") {
    // A kinematic corner keeps its path's velocity and a pinned corner stays at rest, with both
    // dampings on; the free corner is dragged along by the springs.
    ClothSettings s;
    s.relativeDamping = 0.0; // the motion measured here is undamped or damped by C_d only
    s.particleMass = 0.1;
    s.springStiffness = 10.0;
    s.damping = 0.5;
    s.springDamping = 0.5;
    s.gravity = Vec3(0, -9.81, 0);
    s.limiter.kind = LimiterKind::None;
    Cloth cloth(ClothTopology::build(equilateralTriangle(1.0)), s);
    const Vec3 pinAt = cloth.positions()[1], start = cloth.positions()[0];
    const Vec3 u(0.25, 0.0, 0.0);
    cloth.pin(1);
    cloth.setKinematic(0, [start, u](double t) { return Vec3(start + t * u); });
    for (int n = 0; n < 500; ++n)
        cloth.step(0.004);
    CHECK(cloth.positions()[1] == pinAt);
    CHECK(cloth.velocities()[1] == Vec3::Zero());
    CHECK((cloth.velocities()[0] - u).norm() < 1e-12);
    CHECK((cloth.positions()[0] - (start + 2.0 * u)).norm() < 1e-12);
    CHECK(cloth.velocities()[2].norm() > 0.0);
}

TEST_CASE("Velocity-Verlet: spring damping passes its reaction on to a held particle",
          "[damping]") {
    // Spring damping alone (no stiffness to speak of, no gravity): the damping impulses between
    // particles cancel, so the free particles' momentum changes only by what the held particle
    // takes, which the step reports as that particle's force (held f times dt): Newton's third
    // law over every step.
    ClothSettings s;
    s.relativeDamping = 0.0; // the motion measured here is undamped or damped by C_d only
    s.particleMass = 0.1;
    s.springStiffness = 1e-9;
    s.springDamping = 0.4;
    s.gravity = Vec3::Zero();
    s.limiter.kind = LimiterKind::None;
    Cloth cloth(ClothTopology::build(equilateralTriangle(1.0)), s);
    cloth.pin(0);
    cloth.setVelocity(1, Vec3(0.3, -0.2, 0.1));
    cloth.setVelocity(2, Vec3(-0.1, 0.5, 0.0));
    const double dt = 0.05;
    const double ke0 = cloth.kineticEnergy();
    for (int n = 0; n < 40; ++n) {
        const Vec3 before = 0.1 * (cloth.velocities()[1] + cloth.velocities()[2]);
        const double keBefore = cloth.kineticEnergy();
        cloth.step(dt);
        const Vec3 after = 0.1 * (cloth.velocities()[1] + cloth.velocities()[2]);
        CHECK((after - before + dt * cloth.forces()[0]).norm() < 1e-12);
        // Damping alone never adds kinetic energy (up to the 1e-9 N/m springs).
        CHECK(cloth.kineticEnergy() <= keBefore * (1.0 + 1e-12));
    }
    CHECK(cloth.kineticEnergy() < 0.5 * ke0); // and it did take some away
}

namespace {
/// One triangle in the x-z plane (area 0.5), held horizontal: the falling plate of the drag
/// tests. Three particles of 0.01 kg, drag only (no limiter).
TriangleMesh fallingPlateMesh() {
    TriangleMesh m;
    m.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 0, -1)};
    m.triangles = {{0, 1, 2}};
    return m;
}
ClothSettings fallingPlateSettings() {
    ClothSettings s;
    s.relativeDamping = 0.0; // the motion measured here is undamped or damped by C_d only
    s.particleMass = 0.01;
    s.springStiffness = 10.0;
    s.gravity = Vec3(0, -9.81, 0);
    s.aero.airDensity = 1.2;
    s.aero.dragCoefficient = 1.0;
    s.limiter.kind = LimiterKind::None;
    return s;
}
/// A sheet of n x n particles 10 cm apart, 50 g, 20 N/m springs, in a fluid of `density`
/// [kg/m^3], stepped without automatic sub-steps (each step is the dt given).
std::pair<TopologyPtr, ClothSettings> sheetInFluid(Index n, double density) {
    SheetSpec spec;
    spec.rows = spec.cols = n;
    spec.spacing = 0.1;
    spec.vAxis = Vec3(0, 0, -1);
    ClothSettings s;
    s.totalMass = 0.05;
    s.springStiffness = 20.0;
    s.aero.airDensity = density;
    s.substeps.automatic = false;
    return {ClothTopology::build(makeSheet(spec)), s};
}
} // namespace

TEST_CASE("A falling plate reaches the terminal velocity of its drag", "[aero]") {
    // One triangle held horizontal (normal along gravity), drag only: by symmetry each corner
    // carries a third of the weight and of the drag, the springs stay at rest and the plate
    // falls flat. Terminal speed: rho/2 C_d A v^2 = M g.
    const TriangleMesh m = fallingPlateMesh();
    ClothSettings s = fallingPlateSettings();
    Cloth cloth(ClothTopology::build(m), s);
    const double M = 0.03, A = 0.5;
    const double vt = std::sqrt(2.0 * M * 9.81 / (1.2 * 1.0 * A));
    const double tau = vt / 9.81; // ~0.1 s
    // v(t) = vt tanh(t / tau); after 20 tau it is vt to 1e-17. VV's error at dt = 1e-3 is
    // O((dt/tau)^2) ~ 1e-4 relative in transients and vanishes at the fixed point.
    for (int n = 0; n < 2000; ++n)
        cloth.step(1e-3);
    for (Index i = 0; i < 3; ++i) {
        CHECK(cloth.velocities()[i].y() == Approx(-vt).epsilon(1e-6));
        CHECK(std::abs(cloth.velocities()[i].x()) < 1e-9);
        CHECK(std::abs(cloth.velocities()[i].z()) < 1e-9);
    }
    INFO(measured("falling plate: speed %.9f m/s, terminal speed %.9f m/s",
                  -cloth.velocities()[0].y(), vt));
    // The transient itself, v = vt tanh(t / tau), with RK4 (error ~(dt/tau)^4 = 1e-8): this
    // checks the drag force's magnitude away from the fixed point.
    s.integrator = IntegratorKind::RungeKutta4;
    Cloth again(ClothTopology::build(m), s);
    const int steps = 100;
    for (int n = 0; n < steps; ++n)
        again.step(1e-3);
    CHECK(-again.velocities()[0].y() == Approx(vt * std::tanh(steps * 1e-3 / tau)).epsilon(1e-6));
}

TEST_CASE("Aerodynamics turned on and off after construction (Cloth::setAero)", "[aero]") {
    // The falling plate built without air: it falls freely (v = -g t), reaches the terminal
    // speed of its drag once setAero gives it air, and falls freely again when the air goes.
    const TriangleMesh m = fallingPlateMesh();
    ClothSettings s = fallingPlateSettings();
    const AeroSettings air = s.aero;
    s.aero.airDensity = 0.0;
    Cloth cloth(ClothTopology::build(m), s);
    for (int n = 0; n < 100; ++n)
        cloth.step(1e-3);
    CHECK(cloth.velocities()[0].y() == Approx(-9.81 * 0.1).epsilon(1e-12));

    cloth.setAero(air);
    for (int n = 0; n < 2000; ++n)
        cloth.step(1e-3);
    const double vt = std::sqrt(2.0 * 0.03 * 9.81 / (1.2 * 1.0 * 0.5));
    for (Index i = 0; i < 3; ++i)
        CHECK(cloth.velocities()[i].y() == Approx(-vt).epsilon(1e-6));

    // Refused settings leave the cloth as it was: still at its terminal speed.
    AeroSettings bad = air;
    bad.airDensity = -1.0;
    CHECK_THROWS_AS(cloth.setAero(bad), Error);
    bad = air;
    bad.wind = Vec3(std::nan(""), 0, 0);
    CHECK_THROWS_AS(cloth.setAero(bad), Error);
    bad = air; // drag takes energy out of the motion: a negative coefficient is refused
    bad.dragCoefficient = -1.0;
    CHECK_THROWS_WITH(cloth.setAero(bad), Catch::Contains("aero.dragCoefficient"));
    ClothSettings negative = fallingPlateSettings();
    negative.aero.dragCoefficient = -0.5;
    CHECK_THROWS_WITH(Cloth(ClothTopology::build(m), negative),
                      Catch::Contains("aero.dragCoefficient"));
    cloth.step(1e-3);
    CHECK(cloth.velocities()[0].y() == Approx(-vt).epsilon(1e-6));
    CHECK(cloth.settings().aero.airDensity == 1.2);

    AeroSettings still = air;
    still.airDensity = 0.0;
    cloth.setAero(still);
    const double v0 = cloth.velocities()[0].y();
    for (int n = 0; n < 100; ++n)
        cloth.step(1e-3);
    CHECK(cloth.velocities()[0].y() - v0 == Approx(-9.81 * 0.1).epsilon(1e-9));
}

TEST_CASE("Automatic sub-steps keep the explicit drag stable: a plate sinking in water",
          "[aero][stability]") {
    // The falling plate in water (rho 1000): its terminal speed sqrt(2 M g / (rho C_d A)) is
    // 3.4 cm/s and its drag relaxes the velocity at about 570 /s there, past 2 / dt = 120 /s
    // for a 60 Hz step whose springs need no sub-step. The drag's own limit
    // (Cloth::aeroTimeStep) takes the step in sub-steps: the plate sinks at the terminal
    // speed. (Without it the state went non-finite within the first frames.)
    const TriangleMesh m = fallingPlateMesh();
    ClothSettings s = fallingPlateSettings();
    s.aero.airDensity = 1000.0;
    Cloth cloth(ClothTopology::build(m), s);
    const double vt = std::sqrt(2.0 * 0.03 * 9.81 / (1000.0 * 1.0 * 0.5));
    CHECK(cloth.aeroTimeStep(1.0 / 60.0) < std::numeric_limits<double>::infinity());
    for (int n = 0; n < 60; ++n)
        REQUIRE_NOTHROW(cloth.step(1.0 / 60.0));
    INFO(measured("sinking plate: %.6f m/s, terminal %.6f m/s, %d sub-steps a 60 Hz step",
                  -cloth.velocities()[0].y(), vt, cloth.substepsFor(1.0 / 60.0)));
    CHECK(cloth.substepsFor(1.0 / 60.0) > 1);
    for (Index i = 0; i < 3; ++i)
        CHECK(cloth.velocities()[i].y() == Approx(-vt).epsilon(1e-3));
    // Without air the limit is not there.
    ClothSettings dry = fallingPlateSettings();
    dry.aero.airDensity = 0.0;
    CHECK(Cloth(ClothTopology::build(m), dry).aeroTimeStep(1.0 / 60.0) ==
          std::numeric_limits<double>::infinity());
}

TEST_CASE("Without automatic sub-steps a cloth that outruns its drag's limit is refused, not "
          "blown up",
          "[aero][stability]") {
    // A 0.5 m sheet of 50 g in water, fixed steps of 3 ms: within the drag's limit at rest
    // (7 ms), beyond it as the sheet sinks (the limit falls as the speed grows). Unchecked, the
    // state grows without bound and goes non-finite after about 1400 steps (review 17: a fixed
    // count called stable reached 1e63 m). Checked, the step that would leave the limit is
    // refused, naming the drag, and the state stays the one before it.
    auto [topology, s] = sheetInFluid(6, 1000.0);
    const double dt = 3e-3;
    Cloth checked(topology, s);
    REQUIRE(checked.aeroTimeStep(dt) > 2.0 * dt);
    REQUIRE(checked.stableTimeStep() > dt);
    int refusedAt = -1;
    std::string message;
    for (int n = 0; n < 2000 && refusedAt < 0; ++n) {
        const double limit = checked.aeroTimeStep(dt);
        try {
            checked.step(dt);
            CHECK(limit >= dt); // nothing beyond the limit is taken
        } catch (const Error& e) {
            REQUIRE(e.code() == ErrorCode::UnstableTimeStep);
            CHECK(limit < dt);
            refusedAt = n;
            message = e.what();
        }
    }
    INFO(message);
    REQUIRE(refusedAt >= 1);
    CHECK_THAT(message,
               Catch::Contains("aerodynamic drag") && Catch::Contains("substeps.automatic"));
    for (const Vec3& x : checked.positions())
        CHECK(x.norm() < 1.0);
    // The same cloth unchecked blows up (a kilometre from where it hangs, or non-finite).
    s.rejectUnstableTimeStep = false;
    Cloth unchecked(topology, s);
    bool failed = false;
    for (int n = 0; n < 3000 && !failed; ++n) {
        try {
            unchecked.step(dt);
            for (const Vec3& x : unchecked.positions())
                failed = failed || !(x.norm() < 1e3);
        } catch (const Error& e) {
            CHECK(e.code() == ErrorCode::SimulationFailure);
            failed = true;
        }
    }
    CHECK(failed);
    // With automatic sub-steps the same steps split as the speed asks and the sheet sinks.
    s.rejectUnstableTimeStep = true;
    s.substeps.automatic = true;
    Cloth split(topology, s);
    for (int n = 0; n < 1000; ++n)
        REQUIRE_NOTHROW(split.step(dt));
    for (const Vec3& v : split.velocities())
        CHECK(v.norm() < 0.5);
}

TEST_CASE("The drag's limit counts the speed relative to the wind: a sheet the wind carries "
          "along is not refused",
          "[aero][stability]") {
    // A free sheet facing a 10 m/s wind, no gravity, fixed steps of 3 ms: the wind speeds it
    // up until it moves with the air, and its speed relative to the air falls from 10 m/s to
    // nothing. The bound counted the wind's speed plus the sheet's (up to 20 m/s) and refused
    // the run at its second step (review 19); it runs, and the sheet ends moving with the air.
    SheetSpec spec;
    spec.rows = spec.cols = 6;
    spec.spacing = 0.1;
    spec.uAxis = Vec3(0, 1, 0);
    spec.vAxis = Vec3(0, 0, -1); // the sheet's normal along x, facing the wind
    ClothSettings s;
    s.totalMass = 0.02;
    s.springStiffness = 20.0;
    s.gravity = Vec3::Zero();
    s.aero.airDensity = 2.0;
    s.aero.wind = Vec3(10.0, 0.0, 0.0);
    s.substeps.automatic = false;
    const double dt = 3e-3;
    Cloth c(ClothTopology::build(makeSheet(spec)), s);
    REQUIRE(c.aeroTimeStep(dt) > dt);
    for (int n = 0; n < 2000; ++n)
        REQUIRE_NOTHROW(c.step(dt));
    double relative = 0.0;
    for (const Vec3& v : c.velocities())
        relative = std::max(relative, (v - s.aero.wind).norm());
    CHECK(relative < 0.1);
    CHECK(c.aeroSpeedBound(dt) == Approx(relative).margin(1e-12));
}

TEST_CASE("The drag's refusal in a fluid far too dense names a count, not an overflow, and no "
          "remedy that fails",
          "[aero][stability]") {
    // A fluid of 1e30 kg/m^3 asked for "-9223372036854775808 sub-steps" and for automatic
    // sub-steps, which would need 1e27 of them and refuse in turn (review 19).
    auto [topology, s] = sheetInFluid(4, 1e30);
    Cloth c(topology, s);
    std::string message;
    try {
        c.step(1e-3);
    } catch (const Error& e) {
        CHECK(e.code() == ErrorCode::UnstableTimeStep);
        message = e.what();
    }
    INFO(message);
    CHECK_THAT(message, Catch::Contains("e+") && Catch::Contains("sub-steps of this step"));
    CHECK(message.find("-9223372036854775808") == std::string::npos);
    CHECK(message.find("automatic") == std::string::npos);
    // A density whose split fits names automatic sub-steps.
    s.aero.airDensity = 1e3;
    Cloth water(topology, s);
    try {
        REQUIRE(water.stableTimeStep() > 0.005);
        for (int k = 0; k < 1000; ++k)
            water.step(0.005);
        FAIL("not refused");
    } catch (const Error& e) {
        CHECK_THAT(e.what(), Catch::Contains("substeps.automatic on"));
    }
}

TEST_CASE("Velocity-Verlet stays second order with aerodynamic drag", "[aero][convergence]") {
    // The falling plate of the test above through its transient: v(t) = vt tanh(t / tau) and
    // the drop y(t) = vt tau ln cosh(t / tau), released from rest. Velocity-Verlet takes the
    // drag in its kicks, the closing one at a predicted end velocity (integrators.cpp); with
    // the drag at the half-step velocity it would be first order.
    const TriangleMesh m = fallingPlateMesh();
    ClothSettings s = fallingPlateSettings();
    const double vt = std::sqrt(2.0 * 0.03 * 9.81 / (1.2 * 1.0 * 0.5)), tau = vt / 9.81;
    const double T = 1.5 * tau;
    const double vExact = vt * std::tanh(T / tau),
                 dropExact = vt * tau * std::log(std::cosh(T / tau));
    std::vector<double> dts, errs;
    for (int N : {20, 40, 80, 160}) {
        Cloth cloth(ClothTopology::build(m), s);
        for (int n = 0; n < N; ++n)
            cloth.step(T / N);
        double e2 = 0.0;
        for (Index i = 0; i < 3; ++i) {
            const double drop = m.vertices[i].y() - cloth.positions()[i].y();
            e2 += std::pow((drop - dropExact) / (vt * tau), 2) +
                  std::pow((-cloth.velocities()[i].y() - vExact) / vt, 2);
        }
        dts.push_back(T / N);
        errs.push_back(std::sqrt(e2));
    }
    const double order = logLogSlope(dts, errs);
    std::string line = measured("falling plate, velocity_verlet: errors");
    for (double e : errs)
        line += measured(" %.3e", e);
    line += measured(" -> order %.3f", order);
    INFO(line);
    CHECK(order == Approx(2.0).margin(0.1));
}

TEST_CASE("A user force stretches a spring by F / k", "[forces][user]") {
    // Free corner at the origin, pinned corners at (L, 0) and (0, L); a force -F x pulls the
    // free corner away from (L, 0): equilibrium at u = F / k along -x (the other spring turns
    // and adds an x force of O(k u^3 / L^2), a 1e-6 relative correction for u = 1e-3 L).
    TriangleMesh m;
    m.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
    m.triangles = {{0, 1, 2}};
    ClothSettings s;
    s.relativeDamping = 0.0; // the motion measured here is undamped or damped by C_d only
    s.integrator = IntegratorKind::ImplicitEuler;
    s.particleMass = 0.1;
    s.springStiffness = 50.0;
    s.gravity = Vec3::Zero();
    s.damping = 1.0;
    s.limiter.kind = LimiterKind::None;
    Cloth cloth(ClothTopology::build(m), s);
    cloth.pin(1);
    cloth.pin(2);
    const double F = 0.05;
    cloth.setUserForce(0, Vec3(-F, 0, 0));
    for (int n = 0; n < 400; ++n)
        cloth.step(0.05);
    CHECK(cloth.velocities()[0].norm() < 1e-12);
    CHECK(-cloth.positions()[0].x() == Approx(F / 50.0).epsilon(1e-4));
    // The pinned corner at (0, L) is now u^2 / 2L too far away; its spring pulls the free
    // corner toward it until y = u^2 / 2L (up to F / kL = 1e-3 relative).
    const double u = F / 50.0;
    CHECK(cloth.positions()[0].y() == Approx(u * u / 2.0).epsilon(1e-2));
    cloth.clearUserForces();
    for (int n = 0; n < 400; ++n)
        cloth.step(0.05);
    CHECK(cloth.positions()[0].norm() < 1e-10); // back to rest
}

TEST_CASE("Implicit Euler: CG and LDLT give the same steps", "[integrators][implicit]") {
    auto run = [](LinearSolverKind solver) {
        SheetSpec spec;
        spec.rows = 8;
        spec.cols = 8;
        spec.spacing = 0.1;
        ClothSettings s;
        s.relativeDamping = 0.0; // the motion measured here is undamped or damped by C_d only
        s.integrator = IntegratorKind::ImplicitEuler;
        s.implicit.solver = solver;
        s.particleMass = 0.01;
        s.springStiffness = 100.0;
        s.damping = 0.01;
        auto cloth = std::make_unique<Cloth>(ClothTopology::build(makeSheet(spec)), s);
        cloth->pin(0);
        cloth->pin(7);
        for (int n = 0; n < 100; ++n)
            cloth->step(0.01);
        return cloth;
    };
    const auto cg = run(LinearSolverKind::ConjugateGradient), ldlt = run(LinearSolverKind::LDLT);
    double diff = 0.0, size = 0.0;
    for (std::size_t i = 0; i < cg->particleCount(); ++i) {
        diff = std::max(diff, (cg->positions()[i] - ldlt->positions()[i]).norm());
        size = std::max(size, (ldlt->positions()[i] - ldlt->topology().restPositions()[i]).norm());
    }
    // CG stops at a relative residual of 1e-10 per step; over 100 steps the difference stays
    // many orders below the motion (~0.1 m).
    CHECK(size > 0.01);
    CHECK(diff < 1e-6 * size);
}

TEST_CASE("A free plate in a steady wind is carried at the wind speed", "[aero]") {
    // No gravity; a triangle facing the wind (normal along x) in a wind of 2 m/s along x.
    // The drag on the relative velocity u = v - w is -rho/2 C_d A |u| (u . n) n, so v -> w;
    // the fixed point is exact for every integrator (f = 0 exactly when u = 0).
    TriangleMesh m;
    m.vertices = {Vec3(0, 0, 0), Vec3(0, 1, 0), Vec3(0, 0, 1)};
    m.triangles = {{0, 1, 2}};
    ClothSettings s;
    s.relativeDamping = 0.0; // the motion measured here is undamped or damped by C_d only
    s.particleMass = 0.01;
    s.springStiffness = 10.0;
    s.gravity = Vec3::Zero();
    s.aero.airDensity = 1.2;
    s.limiter.kind = LimiterKind::None;
    Cloth cloth(ClothTopology::build(m), s);
    const Vec3 wind(2.0, 0.0, 0.0);
    cloth.setWind(wind);
    // Relative speed decays like 1 / (1 + t / tau) with tau = M / (rho/2 C_d A w) = 0.05 s:
    // after 20 s it is 2.5e-3 of the wind.
    for (int n = 0; n < 20000; ++n)
        cloth.step(1e-3);
    for (Index i = 0; i < 3; ++i) {
        CHECK((cloth.velocities()[i] - wind).norm() < 5e-3 * wind.norm());
        CHECK(cloth.velocities()[i].x() < wind.x()); // approached from below, never overshot
    }
}

TEST_CASE("Relative damping keeps momentum and free fall and takes out the motion about the "
          "mean",
          "[damping][relative]") {
    // A free 11 x 11 sheet with scrambled velocities, no gravity: its momentum must stay what
    // it was (to round-off), while the kinetic energy of the motion about the mean velocity
    // falls (by exp(-2 rate t) if the springs did nothing; they exchange it with their own
    // energy, so only a fall below a tenth is asked). A second sheet in free fall at rest
    // relative to itself must fall exactly as without damping.
    SheetSpec spec;
    spec.rows = 11;
    spec.cols = 11;
    spec.spacing = 0.05;
    spec.uAxis = Vec3::UnitX();
    spec.vAxis = Vec3::UnitZ();
    ClothSettings s;
    s.particleMass = 0.01;
    s.springStiffness = 50.0;
    s.gravity = Vec3::Zero();
    s.limiter.kind = LimiterKind::None;
    s.relativeDamping = 2.0;
    Cloth cloth(ClothTopology::build(makeSheet(spec)), s);
    for (Index i = 0; i < cloth.particleCount(); ++i)
        cloth.setVelocity(
            i, Vec3(std::sin(1.3 * i), std::cos(0.7 * i) - 0.5, 0.3 * std::sin(2.1 * i)));
    auto momentum = [&] {
        Vec3 p = Vec3::Zero();
        for (Index i = 0; i < cloth.particleCount(); ++i)
            p += cloth.masses()[i] * cloth.velocities()[i];
        return p;
    };
    auto internalEnergy = [&] {
        const Vec3 vbar = momentum() / (0.01 * static_cast<double>(cloth.particleCount()));
        double e = 0.0;
        for (Index i = 0; i < cloth.particleCount(); ++i)
            e += 0.5 * cloth.masses()[i] * (cloth.velocities()[i] - vbar).squaredNorm();
        return e + cloth.springEnergy();
    };
    const Vec3 p0 = momentum();
    const double e0 = internalEnergy();
    for (int k = 0; k < 480; ++k)
        cloth.step(1.0 / 240.0);
    INFO("momentum change " << (momentum() - p0).norm() << " of " << p0.norm()
                            << ", internal energy " << e0 << " -> " << internalEnergy() << " J");
    CHECK((momentum() - p0).norm() <= 1e-12 * p0.norm());
    CHECK(internalEnergy() < 0.1 * e0);
    CHECK(cloth.pipeline().back() == "verify");
    CHECK(std::find(cloth.pipeline().begin(), cloth.pipeline().end(), "relative_damping") !=
          cloth.pipeline().end());

    ClothSettings fall = s;
    fall.gravity = Vec3(0.0, -9.81, 0.0);
    Cloth falling(ClothTopology::build(makeSheet(spec)), fall);
    const Vec3List x0 = falling.positions();
    for (int k = 0; k < 240; ++k)
        falling.step(1.0 / 240.0);
    for (Index i = 0; i < falling.particleCount(); ++i)
        CHECK((falling.positions()[i] - x0[i] - Vec3(0.0, -0.5 * 9.81, 0.0)).norm() <= 1e-9);
    REQUIRE_DRAPE_ERROR(falling.setRelativeDamping(-1.0), ErrorCode::InvalidArgument,
                        "relativeDamping");
}

TEST_CASE("totalMass() and momentum(): a falling cloth's momentum is M (v0 + g t) with the "
          "default damping",
          "[damping][momentum]") {
    SheetSpec spec;
    spec.rows = 6;
    spec.cols = 7;
    spec.spacing = 0.05;
    ClothSettings s; // the default relative damping keeps momentum exactly
    s.particleMass = 0.002;
    Cloth cloth(ClothTopology::build(makeSheet(spec)), s);
    REQUIRE(cloth.settings().relativeDamping > 0.0);
    const double mass = 0.002 * 42;
    CHECK(cloth.totalMass() == Approx(mass).epsilon(1e-14));
    const Vec3 v0(0.3, 1.0, -0.2);
    for (Index i = 0; i < cloth.particleCount(); ++i) // a shear, not a rigid motion
        cloth.setVelocity(i, v0 + Vec3(0.0, 0.0, 0.1 * std::sin(0.7 * i)));
    const Vec3 p0 = cloth.momentum();
    const double dt = 1.0 / 60.0;
    for (int k = 0; k < 60; ++k)
        cloth.step(dt);
    const Vec3 expected = p0 + mass * cloth.time() * s.gravity;
    INFO("momentum " << cloth.momentum().transpose() << ", expected " << expected.transpose());
    CHECK((cloth.momentum() - expected).norm() <= 1e-12 * expected.norm());
}
