// Integrator tests against analytic solutions: free fall, the undamped oscillator (bounded
// energy error of Velocity-Verlet over 1e5 steps, period 2 pi sqrt(m/k), exact per-step energy
// factors of the Euler methods) and measured convergence orders of all five integrators.
//
// The oscillator used throughout is the breathing mode of a free equilateral triangle: three
// equal masses m at distance r from the centroid, springs of stiffness k and rest length
// sqrt(3) r0. Each corner feels 2 k sqrt(3)(r - r0) cos 30 deg = 3 k (r - r0) radially, so
// r'' = -(3k/m)(r - r0) exactly, at any amplitude: a linear oscillator with
// omega = sqrt(3k/m), with no geometric nonlinearity to blur the comparison. By symmetry every
// integrator keeps the motion in that mode and reduces to its scalar form on r.
#include "helpers.hpp"
#include "measured.hpp"

#include "drape/cloth.hpp"

#include <cstdio>
#include <memory>

using namespace drape;
using namespace drape_test;

namespace {

struct Breathing {
    double r0 = 1.0;  // m
    double m = 1.0;   // kg
    double k = 1.0;   // N/m
    double amp = 0.1; // m, initial radial displacement (released from rest)
    double omega() const { return std::sqrt(3.0 * k / m); }

    std::unique_ptr<Cloth> make(IntegratorKind kind) const {
        ClothSettings s;
        s.relativeDamping = 0.0; // the motion measured here is undamped or damped by C_d only
        s.integrator = kind;
        s.particleMass = m;
        s.springStiffness = k;
        s.gravity = Vec3::Zero();
        s.limiter.kind = LimiterKind::None;
        auto cloth = std::make_unique<Cloth>(ClothTopology::build(equilateralTriangle(r0)), s);
        const auto d = equilateralDirections();
        for (Index i = 0; i < 3; ++i)
            cloth->setPosition(i, (r0 + amp) * d[i]);
        return cloth;
    }
    /// Phase-space distance to the analytic solution at time t:
    /// sqrt(sum |x - x*|^2 + |v - v*|^2 / omega^2) [m].
    double error(const Cloth& c, double t) const {
        const auto d = equilateralDirections();
        const double w = omega();
        double e2 = 0.0;
        for (Index i = 0; i < 3; ++i) {
            const Vec3 xe = (r0 + amp * std::cos(w * t)) * d[i];
            const Vec3 ve = (-amp * w * std::sin(w * t)) * d[i];
            e2 += (c.positions()[i] - xe).squaredNorm() +
                  (c.velocities()[i] - ve).squaredNorm() / (w * w);
        }
        return std::sqrt(e2);
    }
};

double totalEnergy(const Cloth& c) {
    return c.kineticEnergy() + c.springEnergy();
}

/// Measured period of s(t) from its upward zero crossings (linear interpolation between
/// steps), averaged over all full periods seen.
double measurePeriod(Cloth& cloth, double dt, int steps,
                     const std::function<double(const Cloth&)>& s) {
    std::vector<double> crossings;
    double prev = s(cloth), tPrev = cloth.time();
    for (int n = 0; n < steps; ++n) {
        cloth.step(dt);
        const double cur = s(cloth), t = cloth.time();
        if (prev < 0.0 && cur >= 0.0) crossings.push_back(tPrev + dt * (-prev) / (cur - prev));
        prev = cur;
        tPrev = t;
    }
    REQUIRE(crossings.size() >= 3);
    return (crossings.back() - crossings.front()) / static_cast<double>(crossings.size() - 1);
}

} // namespace

TEST_CASE("Free fall of a rigidly moving cloth matches x0 + v0 t + g t^2 / 2",
          "[integrators][freefall]") {
    // One triangle, springs at rest, every particle with the same velocity: spring forces stay
    // zero (up to rounding of the lengths) and each particle is a projectile.
    const Vec3 g(0.0, -9.81, 0.0), v0(1.0, 2.0, -0.5);
    const double dt = 0.01;
    const int steps = 300; // 3 s, |x| up to ~45 m
    TriangleMesh tri;
    tri.vertices = {Vec3(0, 0, 0), Vec3(0.5, 0, 0.1), Vec3(0.1, 0.4, 0)};
    tri.triangles = {{0, 1, 2}};
    const auto topo = ClothTopology::build(tri);

    struct Expect {
        IntegratorKind kind;
        double lag; // x_N = x0 + v0 t + g (t^2 + lag t dt) / 2 for constant acceleration
        double tol; // [m]
        const char* why;
    };
    // Velocity-Verlet and RK4 integrate a constant acceleration exactly; the Euler methods
    // have closed forms too: explicit Euler x_N = x0 + v0 t + g dt^2 N(N-1)/2, symplectic and
    // implicit Euler (x += dt v_new) g dt^2 N(N+1)/2.
    const std::vector<Expect> cases{
        {IntegratorKind::VelocityVerlet, 0.0, 1e-9,
         "rounding: 300 steps x few ulp of |x| ~ 45 m is ~1e-11, plus spring forces of "
         "k * (rounding of lengths ~1e-15 m) ~ 1e-15 N"},
        {IntegratorKind::RungeKutta4, 0.0, 1e-9, "as for Velocity-Verlet"},
        {IntegratorKind::ExplicitEuler, -1.0, 1e-9, "as for Velocity-Verlet"},
        {IntegratorKind::SymplecticEuler, 1.0, 1e-9, "as for Velocity-Verlet"},
        {IntegratorKind::ImplicitEuler, 1.0, 1e-7,
         "CG stops at a relative residual of 1e-10 of dv = g dt ~ 0.1 m/s, i.e. 1e-11 m/s per "
         "step, accumulating to < 1e-8 m over 300 steps"},
    };
    for (const auto& e : cases) {
        INFO(toString(e.kind) << ": tolerance " << e.tol << " m because " << e.why);
        ClothSettings s;
        s.relativeDamping = 0.0; // the motion measured here is undamped or damped by C_d only
        s.integrator = e.kind;
        // Soft springs (omega = sqrt(3k/m) = 5.5 rad/s, omega dt = 0.055): explicit Euler
        // amplifies any internal vibration by (1 + omega^2 dt^2)^(1/2) per step, here 1.6x
        // over the run, so the rounding-level spring forces stay at rounding level. (With
        // k = 100 the factor would be 1e17 and rounding would grow to metres: explicit
        // Euler's instability, not a free-fall error.)
        s.particleMass = 0.1;
        s.springStiffness = 1.0;
        s.gravity = g; // default limiter (stress-ordered): nothing is stretched, it must not act
        Cloth cloth(topo, s);
        const Vec3List x0 = cloth.positions();
        for (Index i = 0; i < 3; ++i)
            cloth.setVelocity(i, v0);
        const double E0 = cloth.kineticEnergy() + cloth.gravityEnergy();
        for (int n = 0; n < steps; ++n)
            cloth.step(dt);
        const double t = steps * dt;
        for (Index i = 0; i < 3; ++i) {
            const Vec3 expected = x0[i] + v0 * t + 0.5 * g * (t * t + e.lag * t * dt);
            CHECK((cloth.positions()[i] - expected).norm() < e.tol);
            CHECK((cloth.velocities()[i] - (v0 + g * t)).norm() < e.tol);
        }
        if (e.kind == IntegratorKind::VelocityVerlet) {
            // Kinetic plus gravitational energy is exactly conserved by Verlet under a constant
            // force; 1e-9 relative covers rounding of energies of ~1e3 J.
            const double E = cloth.kineticEnergy() + cloth.gravityEnergy();
            CHECK(E == Approx(E0).epsilon(1e-9).margin(1e-9));
            CHECK(cloth.lastLimiterStats().corrections == 0u);
        }
    }
}

TEST_CASE("Velocity-Verlet energy error stays bounded over 100,000 steps",
          "[integrators][energy]") {
    Breathing osc;
    osc.amp = 0.2;
    const double dt = 0.05 / osc.omega(); // omega dt = 0.05
    auto cloth = osc.make(IntegratorKind::VelocityVerlet);
    const double E0 = totalEnergy(*cloth);
    const int steps = 100000, window = steps / 10;
    double firstMax = 0.0, lastMax = 0.0;
    for (int n = 0; n < steps; ++n) {
        cloth->step(dt);
        const double err = std::abs(totalEnergy(*cloth) - E0) / E0;
        if (n < window) firstMax = std::max(firstMax, err);
        if (n >= steps - window) lastMax = std::max(lastMax, err);
    }
    INFO(measured("VV breathing mode, omega dt = 0.05, 1e5 steps: max |dE|/E first 10%% = %.3e, "
                  "last 10%% = %.3e",
                  firstMax, lastMax));
    // For the harmonic oscillator Verlet exactly conserves v^2 + omega^2 x^2 (1 - (omega dt)^2/4),
    // so E oscillates with a relative amplitude of (omega dt)^2 / 4 = 6.25e-4 and never drifts.
    const double bound = 0.05 * 0.05 / 4.0;
    CHECK(firstMax <= 1.01 * bound);
    CHECK(firstMax >= 0.5 * bound); // the oscillation is really there (the test sees the error)
    // No growth: the last window is no worse than the first, up to rounding that random-walks
    // by ~sqrt(1e5) * 1e-16 ~ 1e-13.
    CHECK(lastMax <= firstMax * 1.001 + 1e-12);

    // The same on a nonlinear oscillator (one free corner swinging between two pinned ones at
    // large amplitude, with gravity): no analytic bound, but a symplectic method must not drift.
    TriangleMesh m;
    m.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
    m.triangles = {{0, 1, 2}};
    ClothSettings s;
    s.relativeDamping = 0.0; // the motion measured here is undamped or damped by C_d only
    s.particleMass = 1.0;
    s.springStiffness = 1.0;
    s.gravity = Vec3(0.0, -0.5, 0.0);
    s.limiter.kind = LimiterKind::None;
    Cloth swing(ClothTopology::build(m), s);
    swing.pin(1);
    swing.pin(2);
    swing.setPosition(0, Vec3(0.3, -0.2, 0.25));
    swing.setVelocity(0, Vec3(0.1, 0.3, -0.2));
    auto energy = [&]() {
        return swing.kineticEnergy() + swing.springEnergy() + swing.gravityEnergy();
    };
    const double e0 = energy();
    const double dts = 0.02; // omega_max = sqrt(2) at most: omega dt < 0.03
    double first = 0.0, last = 0.0;
    for (int n = 0; n < steps; ++n) {
        swing.step(dts);
        const double err = std::abs(energy() - e0);
        if (n < window) first = std::max(first, err);
        if (n >= steps - window) last = std::max(last, err);
    }
    INFO(measured("VV nonlinear swing, 1e5 steps: max |dE| first 10%% = %.3e J, last 10%% "
                  "= %.3e J",
                  first, last));
    // Quasi-periodic motion: windows differ, but a drift over 1e5 steps would be 10x or more.
    CHECK(last <= 2.0 * first + 1e-12);
}

TEST_CASE("Oscillator period matches 2 pi sqrt(m / k)", "[integrators][period]") {
    SECTION("one free particle on a spring (the other corners pinned)") {
        // Free corner at the origin, pinned corners at (L, 0) and (0, L): moving along x it
        // stretches one spring and turns the other, whose restoring force is O(u^2 / L^2)
        // smaller; u0 = 1e-4 L makes that 1e-8.
        TriangleMesh m;
        const double L = 1.0;
        m.vertices = {Vec3(0, 0, 0), Vec3(L, 0, 0), Vec3(0, L, 0)};
        m.triangles = {{0, 1, 2}};
        ClothSettings s;
        s.relativeDamping = 0.0; // the motion measured here is undamped or damped by C_d only
        s.particleMass = 0.3;
        s.springStiffness = 12.0;
        s.gravity = Vec3::Zero();
        s.limiter.kind = LimiterKind::None;
        Cloth cloth(ClothTopology::build(m), s);
        cloth.pin(1);
        cloth.pin(2);
        cloth.setPosition(0, Vec3(1e-4 * L, 0, 0));
        const double omega = std::sqrt(12.0 / 0.3);
        const double dt = 0.01 / omega;
        const double T =
            measurePeriod(cloth, dt, 20 * 629, [](const Cloth& c) { return c.positions()[0].x(); });
        INFO(measured("single spring period %.8f s, analytic %.8f s", T, 2 * kPi / omega));
        // Verlet's phase error is (omega dt)^2 / 24 = 4e-6 relative; interpolated crossings add
        // O(dt^2) per crossing, averaged out over 20 periods. 1e-4 is a safe bound.
        CHECK(T == Approx(2 * kPi / omega).epsilon(1e-4));
    }
    SECTION("breathing triangle: omega = sqrt(3 k / m), independent of amplitude") {
        for (double amp : {0.01, 0.5}) {
            Breathing osc;
            osc.m = 0.2;
            osc.k = 7.0;
            osc.amp = amp;
            auto cloth = osc.make(IntegratorKind::VelocityVerlet);
            const double dt = 0.01 / osc.omega();
            const double T = measurePeriod(*cloth, dt, 20 * 629, [&](const Cloth& c) {
                return c.positions()[0].norm() - osc.r0;
            });
            INFO("amplitude " << amp);
            CHECK(T == Approx(2 * kPi / osc.omega()).epsilon(1e-4)); // as above
        }
    }
}

TEST_CASE("Euler methods change the oscillator energy by their exact per-step factors",
          "[integrators][energy]") {
    // On x'' = -omega^2 x, explicit Euler maps Q = v^2 + omega^2 x^2 to Q (1 + omega^2 dt^2)
    // every step and backward Euler to Q / (1 + omega^2 dt^2); E is proportional to Q.
    Breathing osc;
    const double w = osc.omega(), dt = 0.02;
    const int steps = 200;
    const double factor = 1.0 + w * w * dt * dt;
    {
        auto cloth = osc.make(IntegratorKind::ExplicitEuler);
        const double E0 = totalEnergy(*cloth);
        for (int n = 0; n < steps; ++n)
            cloth->step(dt);
        // Exact in exact arithmetic: only rounding of 200 steps (1e-13) remains.
        CHECK(totalEnergy(*cloth) == Approx(E0 * std::pow(factor, steps)).epsilon(1e-10));
    }
    {
        auto cloth = osc.make(IntegratorKind::ImplicitEuler);
        const double E0 = totalEnergy(*cloth);
        for (int n = 0; n < steps; ++n)
            cloth->step(dt);
        // The linearised step is exact here (the force is linear along the mode and the
        // right-hand side is an eigenvector of the system matrix, so CG converges in one
        // iteration); CG's 1e-10 relative residual is the only slack.
        CHECK(totalEnergy(*cloth) == Approx(E0 * std::pow(factor, -steps)).epsilon(1e-7));
    }
}

TEST_CASE("Measured convergence orders of the five integrators", "[integrators][convergence]") {
    // Error at T = 2 s (about half a period) against the analytic solution, for dt = T / N,
    // N doubling. The dt ranges keep omega dt <= 0.07 (asymptotic range) and the errors
    // far above rounding (RK4's smallest error is ~1e-11, rounding ~1e-14).
    struct Case {
        IntegratorKind kind;
        std::vector<int> N;
        double order;
    };
    const std::vector<Case> cases{
        {IntegratorKind::ExplicitEuler, {400, 800, 1600, 3200}, 1.0},
        {IntegratorKind::SymplecticEuler, {400, 800, 1600, 3200}, 1.0},
        {IntegratorKind::ImplicitEuler, {400, 800, 1600, 3200}, 1.0},
        {IntegratorKind::VelocityVerlet, {50, 100, 200, 400}, 2.0},
        {IntegratorKind::RungeKutta4, {50, 100, 200, 400}, 4.0},
    };
    const double T = 2.0;
    Breathing osc;
    for (const auto& c : cases) {
        std::vector<double> dts, errs;
        for (int N : c.N) {
            auto cloth = osc.make(c.kind);
            const double dt = T / N;
            for (int n = 0; n < N; ++n)
                cloth->step(dt);
            dts.push_back(dt);
            errs.push_back(osc.error(*cloth, N * dt));
        }
        const double slope = logLogSlope(dts, errs);
        std::string line = measured("%-16s errors at T = 2 s:", toString(c.kind));
        for (std::size_t i = 0; i < dts.size(); ++i)
            line += measured("  dt=%.5f: %.3e", dts[i], errs[i]);
        line += measured("  -> order %.3f", slope);
        INFO(line);
        // Leading-error dominance: the next term is ~omega dt (<= 7%) of the leading one, so
        // the fitted slope is within 0.1 of the order.
        CHECK(slope == Approx(c.order).margin(0.1));
    }
}
