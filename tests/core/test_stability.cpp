// Stability limits: estimateMaxAngularFrequency against cases with known answers and against
// a dense eigen-decomposition, and explicit integrators just above the limit blow up while
// just below it they stay bounded.
#include "helpers.hpp"
#include "measured.hpp"

#include "drape/cloth.hpp"
#include "drape/stability.hpp"

#include <Eigen/Dense>

#include <cstdio>
#include <cstdlib>
#include <string>

using namespace drape;
using namespace drape_test;

namespace {

TriangleMesh rightTriangle() {
    TriangleMesh m;
    m.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
    m.triangles = {{0, 1, 2}};
    return m;
}

} // namespace

TEST_CASE("Max angular frequency of small networks with known answers", "[stability]") {
    const double k = 8.0, m = 0.5;
    const auto topo = ClothTopology::build(rightTriangle());
    const std::vector<double> stiffness(3, k);
    // The bound is lambda_max(M^-1 L) of the graph Laplacian L with fixed rows removed; these
    // small cases have it in closed form. Power iteration converges in a handful of steps,
    // so 1e-9 relative is ample.
    SECTION("one free particle held by two springs: sqrt(2k/m)") {
        // L restricted to the free particle is the scalar 2k. (Its true frequencies at rest
        // are sqrt(k/m), twice, since the springs are orthogonal: the bound is an upper bound.)
        const double w = estimateMaxAngularFrequency(*topo, stiffness, {1.0 / m, 0.0, 0.0});
        CHECK(w == Approx(std::sqrt(2 * k / m)).epsilon(1e-9));
        CHECK(w >= std::sqrt(k / m));
    }
    SECTION("single spring with one end pinned: sqrt(k/m)") {
        // The two other springs given zero stiffness leave one spring between the free
        // particle 0 and the pinned particle 1.
        const double w = estimateMaxAngularFrequency(*topo, {k, 0.0, 0.0}, {1.0 / m, 0.0, 0.0});
        INFO("springs: " << topo->springs()[0].a << "-" << topo->springs()[0].b);
        REQUIRE(topo->springs()[0].a == 0u);
        REQUIRE(topo->springs()[0].b == 1u);
        CHECK(w == Approx(std::sqrt(k / m)).epsilon(1e-9));
    }
    SECTION("two free particles on a free spring: sqrt(2k/m)") {
        // Only spring 0-1, both ends free: L = k [[1, -1], [-1, 1]], eigenvalues 0 and 2k.
        const double w = estimateMaxAngularFrequency(*topo, {k, 0.0, 0.0}, {1.0 / m, 1.0 / m, 0.0});
        CHECK(w == Approx(std::sqrt(2 * k / m)).epsilon(1e-9));
    }
    SECTION("two free particles, one pinned: sqrt(3k/m)") {
        // L on {0, 1} = [[2k, -k], [-k, 2k]]: eigenvalues k and 3k.
        const double w = estimateMaxAngularFrequency(*topo, stiffness, {1.0 / m, 1.0 / m, 0.0});
        CHECK(w == Approx(std::sqrt(3 * k / m)).epsilon(1e-9));
    }
    SECTION("free triangle: sqrt(3k/m), also the exact breathing frequency") {
        const double w = estimateMaxAngularFrequency(*topo, stiffness, {1.0 / m, 1.0 / m, 1.0 / m});
        CHECK(w == Approx(std::sqrt(3 * k / m)).epsilon(1e-9));
    }
    SECTION("nothing free") {
        CHECK(estimateMaxAngularFrequency(*topo, stiffness, {0.0, 0.0, 0.0}) == 0.0);
        CHECK(std::isinf(stableTimeStep(IntegratorKind::VelocityVerlet, 0.0)));
    }
    SECTION("limits per integrator") {
        CHECK(stableTimeStep(IntegratorKind::VelocityVerlet, 10.0) == Approx(0.2));
        CHECK(stableTimeStep(IntegratorKind::SymplecticEuler, 10.0) == Approx(0.2));
        CHECK(stableTimeStep(IntegratorKind::RungeKutta4, 10.0) == Approx(0.2785));
        CHECK(std::isinf(stableTimeStep(IntegratorKind::ImplicitEuler, 10.0)));
    }
}

TEST_CASE("Max angular frequency bounds the true one on larger meshes", "[stability]") {
    // Irregular meshes with unequal masses and stiffnesses and a few pinned particles.
    //  - The physical frequencies at rest: eigenvalues of M^-1/2 K M^-1/2 with the 3x3 blocks
    //    k n n^T of every spring (pinned rows removed). The estimate must not be below the
    //    largest (an under-estimate would let unstable steps through).
    //  - The Laplacian bound lambda_max(M^-1/2 L M^-1/2) that stability.hpp says the power
    //    iteration finds: the estimate must be close to it (0.1 %) and never above the
    //    Gershgorin bound max_i sum_j k_ij (w_i^2 + w_i w_j), w = m^-1/2.
    for (std::uint64_t seed : {1u, 2u, 3u}) {
        const auto topo = ClothTopology::build(irregularMesh(9, 8, seed));
        const std::size_t n = topo->particleCount();
        const auto N = static_cast<Eigen::Index>(n);
        Rng rng(seed);
        std::vector<double> k, invMass(n);
        for (std::size_t s = 0; s < topo->springCount(); ++s)
            k.push_back(rng.uniform(1.0, 30.0));
        for (std::size_t i = 0; i < n; ++i)
            invMass[i] = i % 17 == 0 ? 0.0 : 1.0 / rng.uniform(0.1, 1.0);

        Eigen::MatrixXd B = Eigen::MatrixXd::Zero(N, N), K = Eigen::MatrixXd::Zero(3 * N, 3 * N);
        std::vector<double> row(n, 0.0);
        for (std::size_t s = 0; s < topo->springCount(); ++s) {
            const Index ia = topo->springs()[s].a, ib = topo->springs()[s].b;
            const auto a = static_cast<Eigen::Index>(ia), b = static_cast<Eigen::Index>(ib);
            const double wa = std::sqrt(invMass[ia]), wb = std::sqrt(invMass[ib]);
            B(a, a) += k[s] * wa * wa;
            B(b, b) += k[s] * wb * wb;
            B(a, b) -= k[s] * wa * wb;
            B(b, a) -= k[s] * wa * wb;
            row[ia] += k[s] * (wa * wa + wa * wb);
            row[ib] += k[s] * (wb * wb + wa * wb);
            const Vec3 nn = (topo->restPositions()[ib] - topo->restPositions()[ia]).normalized();
            const Eigen::Matrix3d blk = k[s] * nn * nn.transpose();
            K.block<3, 3>(3 * a, 3 * a) += wa * wa * blk;
            K.block<3, 3>(3 * b, 3 * b) += wb * wb * blk;
            K.block<3, 3>(3 * a, 3 * b) -= wa * wb * blk;
            K.block<3, 3>(3 * b, 3 * a) -= wa * wb * blk;
        }
        const double laplacian =
            std::sqrt(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(B).eigenvalues().maxCoeff());
        const double physical =
            std::sqrt(Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(K).eigenvalues().maxCoeff());
        const double gershgorin = std::sqrt(*std::max_element(row.begin(), row.end()));
        const double est = estimateMaxAngularFrequency(*topo, k, invMass);
        INFO(measured("omega_max seed %llu: physical at rest %.6f, Laplacian %.6f, estimate %.6f "
                      "(%+.2e vs Laplacian), Gershgorin %.6f",
                      static_cast<unsigned long long>(seed), physical, laplacian, est,
                      est / laplacian - 1.0, gershgorin));
        INFO("seed " << seed << " physical " << physical << " Laplacian " << laplacian
                     << " estimate " << est);
        CHECK(est >= physical);
        CHECK(est == Approx(laplacian).epsilon(1e-3));
        CHECK(est <= gershgorin * (1.0 + 1e-12));
    }
}

namespace {
/// Runs the free equilateral triangle (omega = sqrt(3k/m) exactly, which is also what the
/// cloth's estimate gives) released from a breathing displacement of 1e-4 r0 for `steps`
/// steps of `factor` times the cloth's own stable time step, and returns
/// max |x - x_rest| / amplitude. The amplitude is small so that the motion stays linear:
/// at large amplitude the breathing mode modulates the other modes' stiffness and can pump
/// them (parametric resonance), which is not what a linear stability limit is about.
double growth(IntegratorKind kind, double factor, int steps) {
    ClothSettings s;
    s.relativeDamping = 0.0; // the motion measured here is undamped or damped by C_d only
    s.integrator = kind;
    s.particleMass = 0.2;
    s.springStiffness = 5.0;
    s.gravity = Vec3::Zero();
    s.limiter.kind = LimiterKind::None;
    s.rejectUnstableTimeStep = false;
    s.substeps.automatic = false; // each step is the dt given, beyond the limit or not
    Cloth cloth(ClothTopology::build(equilateralTriangle(1.0)), s);
    const auto d = equilateralDirections();
    const double amp = 1e-4;
    for (Index i = 0; i < 3; ++i)
        cloth.setPosition(i, (1.0 + amp) * d[i]);
    const double dt = factor * cloth.stableTimeStep();
    double worst = 0.0;
    try {
        for (int n = 0; n < steps; ++n) {
            cloth.step(dt);
            for (Index i = 0; i < 3; ++i)
                worst = std::max(worst, (cloth.positions()[i] - d[i]).norm() / amp);
        }
    } catch (const Error&) {
        return std::numeric_limits<double>::infinity(); // blew up to non-finite values
    }
    return worst;
}
} // namespace

TEST_CASE("Explicit integrators blow up just above the limit and not just below", "[stability]") {
    const double omega = std::sqrt(3 * 5.0 / 0.2);
    {
        ClothSettings s;
        s.relativeDamping = 0.0; // the motion measured here is undamped or damped by C_d only
        s.particleMass = 0.2;
        s.springStiffness = 5.0;
        Cloth cloth(ClothTopology::build(equilateralTriangle(1.0)), s);
        REQUIRE(cloth.maxAngularFrequency() ==
                Approx(omega).epsilon(1e-9)); // the bound is tight here
    }
    // Velocity-Verlet and symplectic Euler: |amplification| = 1 for omega dt < 2 and > 1
    // beyond (at omega dt = 2.04 the growth is 1.49 per step); RK4 (limit 2.785 / omega;
    // on the imaginary axis its region reaches 2 sqrt(2) = 2.83): at 1.05 x 2.785 = 2.92 it
    // grows by ~1.26 per step, at 0.98 x it decays.
    struct Case {
        IntegratorKind kind;
        double above;
    };
    for (const Case& c :
         {Case{IntegratorKind::VelocityVerlet, 1.02}, Case{IntegratorKind::SymplecticEuler, 1.02},
          Case{IntegratorKind::RungeKutta4, 1.05}}) {
        const double below = growth(c.kind, 0.98, 2000);
        const double aboveGrowth = growth(c.kind, c.above, 2000);
        INFO(measured("%s: max displacement / initial over 2000 steps at 0.98 x limit %.3f, "
                      "at %.2f x limit %.3g",
                      toString(c.kind), below, c.above, aboveGrowth));
        INFO(toString(c.kind) << " below " << below << " above " << aboveGrowth);
        // Below: Verlet keeps v^2 + omega^2 x^2 (1 - (omega dt)^2/4), so from rest |x| <= x0;
        // symplectic Euler keeps v^2 + omega^2 x^2 - omega^2 dt x v, so |x| <= x0 /
        // sqrt(1 - (omega dt)^2/4) = 5 x0 at 0.98 of the limit; RK4 decays. 10 is safe.
        CHECK(below <= 10.0);
        // Above: growth of >= 1.26 per step over 2000 steps takes the 1e-4 displacement to
        // the size of the triangle (where nonlinearity takes over) or to overflow.
        CHECK(aboveGrowth > 1e3);
    }
}

TEST_CASE("A sliver that sets the stable step is named when the step is refused",
          "[stability][errors]") {
    using Catch::Matchers::Contains;
    // A 21 x 21 sheet at 2.5 cm with the default settings, and the same sheet with one vertex
    // more, eps from its corner particle 0 in the sheet's plane: a sliver triangle (0, the new
    // vertex, particle 1) whose short spring is much stiffer than the others.
    SheetSpec spec;
    spec.rows = 21;
    spec.cols = 21;
    spec.spacing = 0.025;
    auto withSliver = [&](double eps) {
        TriangleMesh m = makeSheet(spec);
        const Index extra = static_cast<Index>(m.vertices.size());
        m.vertices.push_back(m.vertices[0] + eps * Vec3(0.6, -0.8, 0.0));
        m.triangles.push_back({0, extra, 1});
        return m;
    };
    // Each particle's own bound is its row of the Gershgorin bound, so the highest is at least
    // the network's omega_max; on the even sheet no particle stands out (corners and edges have
    // fewer springs and less mass: within a factor of 4 of the median).
    const Cloth plain(ClothTopology::build(makeSheet(spec)), ClothSettings{});
    const LocalFrequency even =
        highestLocalFrequency(plain.topology(), plain.stiffness(), plain.inverseMasses());
    INFO(measured("even sheet: highest local bound %.1f rad/s (particle %u), median %.1f, "
                  "omega_max %.1f",
                  even.omega, unsigned(even.particle), even.medianOmega,
                  plain.maxAngularFrequency()));
    CHECK(even.omega >= plain.maxAngularFrequency() * (1.0 - 1e-12));
    CHECK(even.omega < 4.0 * even.medianOmega);
    CHECK_NOTHROW(plain.substepsFor(1.0 / 60.0));

    // A sliver 0.1 mm wide: the short spring's ends stand out, and the cloth needs more
    // sub-steps.
    const Cloth thin(ClothTopology::build(withSliver(1e-4)), ClothSettings{});
    const LocalFrequency f =
        highestLocalFrequency(thin.topology(), thin.stiffness(), thin.inverseMasses());
    INFO(measured("sliver 1e-4 m: highest local bound %.1f rad/s (particle %u), median %.1f; "
                  "sub-steps for 1/60 s %d (even sheet %d)",
                  f.omega, unsigned(f.particle), f.medianOmega, thin.substepsFor(1.0 / 60.0),
                  plain.substepsFor(1.0 / 60.0)));
    CHECK((f.particle == 0 || f.particle == thin.particleCount() - 1));
    CHECK(f.omega >= 4.0 * f.medianOmega);
    CHECK(f.mass == Approx(thin.masses()[f.particle]).epsilon(1e-12));
    const auto [lightest, heaviest] =
        std::minmax_element(thin.masses().begin(), thin.masses().end());
    CHECK(f.medianMass >= *lightest);
    CHECK(f.medianMass <= *heaviest);
    CHECK(thin.substepsFor(1.0 / 60.0) > plain.substepsFor(1.0 / 60.0));

    // A hair's width: more sub-steps than allowed, and the refusal names the particle, its
    // shortest spring and what to do.
    const Cloth hair(ClothTopology::build(withSliver(1e-7)), ClothSettings{});
    const std::string last = std::to_string(hair.particleCount() - 1);
    CHECK_THROWS_WITH(hair.substepsFor(1.0 / 60.0), Contains("particle 0 sets that limit") &&
                                                        Contains("to particle " + last) &&
                                                        Contains("weld them"));
    // The same for a fixed step beyond the limit (ClothSettings::rejectUnstableTimeStep).
    ClothSettings fixed;
    fixed.substeps.automatic = false;
    Cloth hairFixed(ClothTopology::build(withSliver(1e-7)), fixed);
    CHECK_THROWS_WITH(hairFixed.step(1.0 / 60.0), Contains("particle 0 sets that limit"));
}

namespace {

/// An 11 x 11 sheet at 5 cm (the review's case for the advice tests).
TopologyPtr elevenSheet() {
    SheetSpec sheet;
    sheet.rows = 11;
    sheet.cols = 11;
    sheet.spacing = 0.05;
    return ClothTopology::build(makeSheet(sheet));
}

/// Its settings for a fixed step: no automatic sub-steps, springs k, 30 g in all.
ClothSettings fixedStepSettings(double k) {
    ClothSettings s;
    s.substeps.automatic = false;
    s.springStiffness = k;
    s.totalMass = 0.03;
    return s;
}

/// What follows "use dt <= " in a message (no std::regex: GCC 12 warns inside it under the
/// sanitizer build); the test fails when the message has no such advice.
std::string afterAdvice(const std::string& message) {
    const std::string key = "use dt <= ";
    const auto at = message.find(key);
    REQUIRE(at != std::string::npos);
    return message.substr(at + key.size());
}

} // namespace

TEST_CASE("the time step an unstable step's refusal advises passes", "[stability][errors]") {
    // "use dt <= L s": L is written with six digits; rounded to nearest it was above the limit
    // about half the time, and that step was refused in turn (review 16: "time step
    // 0.00204128 s exceeds the stability limit 0.00204128 s"). Over a range of stiffnesses the
    // advised step, and the advised count of sub-steps, pass.
    const TopologyPtr topo = elevenSheet();
    int roundedUpBefore = 0, cases = 0;
    for (double k = 20.0; k < 40.0; k += 0.37) {
        Cloth c(topo, fixedStepSettings(k));
        c.pin(0);
        std::string message;
        try {
            c.step(1.0 / 60.0);
        } catch (const Error& e) {
            message = e.what();
        }
        INFO(message);
        // "use dt <= L s, N sub-steps"
        const std::string rest = afterAdvice(message);
        const auto comma = rest.find(" s, ");
        REQUIRE(comma != std::string::npos);
        ++cases;
        const double limit = c.stableTimeStep();
        // What rounding to nearest would have printed.
        char nearest[32];
        std::snprintf(nearest, sizeof nearest, "%.6g", limit);
        if (std::strtod(nearest, nullptr) > limit) ++roundedUpBefore;
        const double advised = std::stod(rest);
        CHECK(advised <= limit);
        CHECK_NOTHROW(c.step(advised));
        const int count = std::stoi(rest.substr(comma + 4));
        CHECK(1.0 / 60.0 / count <= limit);
    }
    INFO(cases << " cases, " << roundedUpBefore << " of which rounded to nearest exceed the limit");
    CHECK(roundedUpBefore > 0); // the range holds the case the test is about
}

TEST_CASE("a step that blew up with the check off names a free particle and the limit to keep",
          "[stability][errors]") {
    using Catch::Matchers::Contains;
    // With rejectUnstableTimeStep off, a step beyond the limit blows up; the message named the
    // first particle with any non-finite value, a pin whose springs' forces were (review 16),
    // and said only "reduce the time step". It names a free particle now, and the limit: the
    // step it advises runs.
    ClothSettings s = fixedStepSettings(20.37);
    s.rejectUnstableTimeStep = false;
    s.limiter.kind = LimiterKind::None; // nothing bounds the stretch: the step blows up
    const TopologyPtr topo = elevenSheet();
    Cloth c(topo, s);
    c.pin(0);
    std::string message;
    try {
        for (int k = 0; k < 2000; ++k)
            c.step(1.0 / 60.0);
    } catch (const Error& e) {
        CHECK(e.code() == ErrorCode::SimulationFailure);
        message = e.what();
    }
    INFO(message);
    REQUIRE_FALSE(message.empty());
    CHECK_THAT(message, Contains("free) after the step") && !Contains("particle 0 ") &&
                            Contains("beyond the stability limit"));
    const double advised = std::stod(afterAdvice(message));
    CHECK(advised <= c.stableTimeStep());
    // The same cloth from the start, at the step advised: it hangs, bounded.
    Cloth again(topo, s);
    again.pin(0);
    for (int k = 0; k < 1000; ++k)
        REQUIRE_NOTHROW(again.step(advised));
    double farthest = 0.0;
    for (const Vec3& x : again.positions())
        farthest = std::max(farthest, (x - again.positions()[0]).norm());
    CHECK(farthest < 10.0);
}
