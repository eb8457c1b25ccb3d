// checkTimeStep against closed-form answers: one spring of stiffness k with one end pinned
// and mass m on the other is a harmonic oscillator with omega = sqrt(k / m).
#include <drape_samples/check.hpp>

#include <drape/error.hpp>

#include <catch2/catch.hpp>

#include <time.h>

#include <cmath>
#include <limits>

using namespace drape;
using namespace drape::samples;

namespace {

// A single triangle with two corners pinned: the free corner hangs on two springs whose
// directions n1, n2 have n1 . n2 = 0.6, so its stiffness k (n1 n1^T + n2 n2^T) has
// eigenvalues k (1 +- 0.6): omega_exact = sqrt(1.6 k / m). drape's Laplacian bound is the
// row sum 2 k / m: omega_bound = sqrt(2 k / m). checkTimeStep reports limits from the bound
// (safe); the runs below blow up beyond the exact limits.
std::unique_ptr<Cloth> oscillator(IntegratorKind kind, double k, double m, double damping) {
    TriangleMesh mesh;
    mesh.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0.5, -1, 0)};
    mesh.triangles = {{0, 2, 1}};
    ClothSettings s;
    s.integrator = kind;
    s.particleMass = m;
    s.springStiffness = k;
    s.damping = damping;
    s.gravity = Vec3::Zero();
    s.limiter.kind = LimiterKind::None;
    s.rejectUnstableTimeStep = false;
    s.substeps.automatic = false; // each step is the dt given
    auto c = std::make_unique<Cloth>(ClothTopology::build(mesh), s);
    c->pin(0);
    c->pin(1);
    return c;
}

/// Steps n times from a displaced start; true when the motion stays bounded.
bool bounded(Cloth& c, double dt, int n) {
    c.setPosition(2, c.positions()[2] + Vec3(0.01, 0.01, 0.0));
    try {
        for (int i = 0; i < n; ++i)
            c.step(dt);
    } catch (const Error& e) {
        REQUIRE(e.code() == ErrorCode::SimulationFailure);
        return false;
    }
    return (c.positions()[2] - c.topology().restPositions()[2]).norm() < 1.0;
}

} // namespace

TEST_CASE("checkTimeStep: Velocity-Verlet limit is 2 / sqrt(2 k / m) and holds in a run") {
    const double k = 50.0, m = 0.2;
    const double omega = std::sqrt(2.0 * k / m);
    auto c = oscillator(IntegratorKind::VelocityVerlet, k, m, 0.0);
    const TimeStepCheck ok = checkTimeStep(*c, 0.9 * 2.0 / omega);
    CHECK(ok.omegaMax == Approx(omega).epsilon(1e-6));
    CHECK(ok.limit == Approx(2.0 / omega).epsilon(1e-6));
    CHECK(ok.stable);
    CHECK(ok.substeps == 1);
    const TimeStepCheck bad = checkTimeStep(*c, 3.0 * 2.0 / omega);
    CHECK_FALSE(bad.stable);
    CHECK(bad.substeps >= 3);
    CHECK(bad.message.find("UNSTABLE") != std::string::npos);
    // The suggested sub-steps really are stable, and the rejected dt really blows up.
    CHECK(bounded(*c, 3.0 * 2.0 / omega / bad.substeps, 4000));
    auto c2 = oscillator(IntegratorKind::VelocityVerlet, k, m, 0.0);
    CHECK_FALSE(bounded(*c2, 3.0 * 2.0 / omega, 4000));
}

/// A free triangle moving broadside at `speed` through still water.
std::unique_ptr<Cloth> waterPlate(double speed) {
    auto c = oscillator(IntegratorKind::VelocityVerlet, 200.0, 0.25, 0.0);
    c->unpin(0);
    c->unpin(1);
    AeroSettings water;
    water.airDensity = 1000.0;
    c->setAero(water);
    for (Index i = 0; i < 3; ++i)
        c->setVelocity(i, Vec3(0.0, 0.0, -speed));
    return c;
}

TEST_CASE("checkTimeStep: a plate moving through water is limited by its explicit drag, and "
          "the limit holds in a run") {
    // A free triangle moving broadside at 1 m/s through still water: quadratic drag slows it,
    // v' = -c |v| v. Taken explicitly, a step longer than 2 / (the rate it relaxes at) turns
    // the velocity past zero and makes it larger each step. The springs (no pins: they do not
    // move) are far from binding.
    auto plate = [] { return waterPlate(1.0); };
    // Steps n times; the corners' velocity along z, or NaN when the step failed.
    auto slowed = [](Cloth& c, double dt, int n) {
        try {
            for (int i = 0; i < n; ++i)
                c.step(dt);
        } catch (const Error& e) {
            REQUIRE(e.code() == ErrorCode::SimulationFailure);
            return std::numeric_limits<double>::quiet_NaN();
        }
        return c.velocities()[2].z();
    };
    auto c = plate();
    const double drag = c->aeroTimeStep(0.01);
    REQUIRE(drag < 0.1 * c->stableTimeStep());
    const TimeStepCheck bad = checkTimeStep(*c, 3.0 * drag);
    CHECK(bad.aeroLimit == Approx(drag).epsilon(1e-12));
    CHECK(bad.limit == Approx(drag).epsilon(1e-12));
    CHECK_FALSE(bad.stable);
    CHECK(bad.substeps >= 3);
    INFO(bad.message);
    CHECK(bad.message.find("drag and lift") != std::string::npos);
    CHECK(checkTimeStep(*c, 0.9 * drag).stable);
    // The verdict is the run's: at the suggested sub-step the plate slows toward rest without
    // passing it; at the refused step the state becomes non-finite within a few steps.
    const double v = slowed(*c, 3.0 * drag / bad.substeps, 400);
    CHECK(v < 0.0);
    CHECK(v > -0.1);
    auto c2 = plate();
    CHECK(std::isnan(slowed(*c2, 3.0 * drag, 400)));
}

TEST_CASE("checkTimeStep: a step stable at the plate's speed says up to which speed it holds") {
    // The drag's limit is the state's of the moment: a step within it at 1 m/s leaves it as
    // the plate speeds up (review 17: a sheet sinking in a dense fluid was called stable with
    // a margin of 20 and blew up). The verdict names the relative speed where dt meets the
    // limit; the same plate a little slower is within it, a little faster beyond it.
    const auto plate = waterPlate;
    auto c = plate(1.0);
    const double dt = 0.25 * c->aeroTimeStep(0.01);
    const TimeStepCheck ok = checkTimeStep(*c, dt);
    REQUIRE(ok.stable);
    INFO(ok.message);
    REQUIRE(std::isfinite(ok.aeroSpeed));
    CHECK(ok.aeroSpeed > 1.0);
    CHECK(ok.message.find("relative speed") != std::string::npos);
    // The speed bound adds g dt to the fastest particle: the particle's speed at the limit.
    const double gdt = c->settings().gravity.norm() * dt;
    CHECK(checkTimeStep(*plate(0.99 * ok.aeroSpeed - gdt), dt).stable);
    CHECK_FALSE(checkTimeStep(*plate(1.01 * ok.aeroSpeed - gdt), dt).stable);
    // Without air there is no such speed.
    auto dry = oscillator(IntegratorKind::VelocityVerlet, 200.0, 0.25, 0.0);
    CHECK(std::isinf(checkTimeStep(*dry, dt).aeroSpeed));
}

TEST_CASE("checkTimeStep: a step far beyond the limit names the count it needs, not an int's "
          "overflow") {
    const double k = 50.0, m = 0.2;
    const double omega = std::sqrt(2.0 * k / m);
    auto c = oscillator(IntegratorKind::VelocityVerlet, k, m, 0.0);
    // dt = 1e10 limits: 1.1e10 sub-steps, beyond an int (it said "1 sub-steps").
    const double dt = 1e10 * 2.0 / omega;
    const TimeStepCheck bad = checkTimeStep(*c, dt);
    CHECK_FALSE(bad.stable);
    CHECK(bad.substeps == std::numeric_limits<int>::max());
    INFO(bad.message);
    CHECK(bad.message.find("1.111e+10 sub-steps") != std::string::npos);
}

TEST_CASE("checkTimeStep: RK4's limit is 2.785 / omega") {
    const double k = 10.0, m = 1.0;
    const double omega = std::sqrt(2.0 * k / m), omegaExact = std::sqrt(1.6 * k / m);
    auto c = oscillator(IntegratorKind::RungeKutta4, k, m, 0.0);
    CHECK(checkTimeStep(*c, 0.1).limit == Approx(2.785 / omega).epsilon(1e-6));
    auto a = oscillator(IntegratorKind::RungeKutta4, k, m, 0.0);
    CHECK(bounded(*a, 0.99 * 2.785 / omega, 3000));
    // RK4's stability region meets the imaginary axis at 2 sqrt(2) = 2.828. Just beyond it the
    // growth is slow and the spring's nonlinearity detunes the mode once its amplitude is a
    // fraction of the rest length (at 1.02 x the run saturates near 0.17 m); 10 % beyond,
    // |R(i omega dt)|^2 = 3.6 per step and the run blows up.
    auto b = oscillator(IntegratorKind::RungeKutta4, k, m, 0.0);
    CHECK_FALSE(bounded(*b, 1.10 * 2.0 * std::sqrt(2.0) / omegaExact, 3000));
}

TEST_CASE("checkTimeStep: implicit Euler is stable at any dt, and runs so") {
    auto c = oscillator(IntegratorKind::ImplicitEuler, 1e4, 0.01, 0.0);
    const TimeStepCheck r = checkTimeStep(*c, 1.0);
    CHECK(r.stable);
    CHECK(std::isinf(r.limit));
    CHECK(bounded(*c, 1.0, 200));
}

TEST_CASE("checkTimeStep: explicit Euler needs damping, limit C_d / (m omega^2)") {
    const double k = 20.0, m = 0.5;
    const double omega = std::sqrt(2.0 * k / m);
    auto undamped = oscillator(IntegratorKind::ExplicitEuler, k, m, 0.0);
    const TimeStepCheck r = checkTimeStep(*undamped, 1e-4);
    CHECK_FALSE(r.stable);
    CHECK(r.substeps == 0); // no sub-step count helps
    const double cd = 0.5;
    auto damped = oscillator(IntegratorKind::ExplicitEuler, k, m, cd);
    const TimeStepCheck d = checkTimeStep(*damped, 1e-3);
    CHECK(d.limit == Approx(cd / (m * omega * omega)).epsilon(1e-6));
    // A mode x'' = -w^2 x - 2 g x' under explicit Euler: |1 + lambda dt| < 1 iff
    // dt < 2 g / w^2. Below the limit the run decays, above it grows.
    auto below = oscillator(IntegratorKind::ExplicitEuler, k, m, cd);
    CHECK(bounded(*below, 0.8 * d.limit, 20000));
    auto above = oscillator(IntegratorKind::ExplicitEuler, k, m, cd);
    CHECK_FALSE(bounded(*above, 3.0 * d.limit, 20000));
}

TEST_CASE("checkTimeStep: nothing to oscillate when every particle is pinned") {
    auto c = oscillator(IntegratorKind::VelocityVerlet, 10.0, 1.0, 0.0);
    c->pin(2);
    const TimeStepCheck r = checkTimeStep(*c, 10.0);
    CHECK(r.stable);
    CHECK(r.omegaMax == 0.0);
}

TEST_CASE("checkTimeStep: a bad dt gets a message, not a verdict") {
    auto c = oscillator(IntegratorKind::VelocityVerlet, 10.0, 1.0, 0.0);
    const TimeStepCheck r = checkTimeStep(*c, -1.0);
    CHECK_FALSE(r.stable);
    CHECK(r.message.find("positive") != std::string::npos);
}

TEST_CASE("trialCost: what a step cost, and a CPU budget that stops the trial") {
    using Catch::Matchers::Contains;
    // A step that burns 2 ms of this thread's CPU: the trial measures at least that, and a
    // budget of 20 ms stops it after at most ten such steps of the hundred asked for.
    auto threadCpu = [] {
        timespec ts{};
        clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
        return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
    };
    auto burn = [&threadCpu] {
        const double start = threadCpu();
        while (threadCpu() - start < 2e-3) {
        }
    };
    const TrialCost t = trialCost(burn, 0.01, 4, 100, 0.02);
    INFO(t.message);
    CHECK(t.stoppedByBudget);
    CHECK(t.steps >= 1);
    CHECK(t.steps <= 10);
    CHECK(t.simulated == Approx(0.01 * static_cast<double>(t.steps)));
    CHECK(t.medianCpu >= 2e-3);
    CHECK(t.worstCpu >= t.medianCpu);
    CHECK(t.meanCpu >= 2e-3);
    CHECK(t.meanCpu <= t.worstCpu);
    // Per 1/60 s of simulated time: a step of 0.01 s is 0.6 of a 60 Hz frame.
    CHECK(t.medianPerFrame == Approx(t.medianCpu / 0.6));
    CHECK_THAT(t.message, Contains("(4 cloth sub-steps each)") && Contains("stopped after"));
    // Within its budget the trial takes every step asked for.
    int calls = 0;
    const TrialCost all = trialCost([&calls] { ++calls; }, 1.0 / 60.0, 1, 3, 10.0);
    CHECK(calls == 3);
    CHECK(all.steps == 3);
    CHECK_FALSE(all.stoppedByBudget);
    CHECK_THAT(all.message, !Contains("stopped after"));
}
