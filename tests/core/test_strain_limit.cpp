// Strain limiting: the paper's Experiment I (without a limiter the sheet overstretches by far
// more than 10 %; with the stress-ordered or Provot limiter it never exceeds 10 % plus the
// documented tolerance), the limiters' rules on small cases (stress order, pinned ends,
// inverse-mass shares), velocities consistent with the corrections, pins and kinematic
// particles.
#include "helpers.hpp"
#include "measured.hpp"

#include "drape/cloth.hpp"
#include "drape/strain_limit.hpp"

#include <cstdio>
#include <memory>
#include <vector>

using namespace drape;
using namespace drape_test;

namespace {

/// Kinetic, gravitational and spring energy [J].
double mechanicalEnergy(const Cloth& cloth) {
    return cloth.kineticEnergy() + cloth.gravityEnergy() + cloth.springEnergy();
}

/// A 1 m sheet of 21 x 21 particles (default settings) held by `pins` and settled for 2 s
/// at 60 Hz.
std::unique_ptr<Cloth> settledSheet21(const std::vector<Index>& pins) {
    SheetSpec sheet;
    sheet.rows = 21;
    sheet.cols = 21;
    sheet.spacing = 0.05;
    sheet.origin = {-0.5, 2.0, 0.0};
    auto cloth = std::make_unique<Cloth>(ClothTopology::build(makeSheet(sheet)), ClothSettings{});
    for (Index p : pins)
        cloth->pin(p);
    for (int f = 0; f < 120; ++f)
        cloth->step(1.0 / 60.0);
    return cloth;
}

/// Unequal particle masses in [0.5, 2] kg drawn from rng, and their inverses.
void randomMasses(Rng& rng, std::size_t n, std::vector<double>& mass,
                  std::vector<double>& invMass) {
    mass.resize(n);
    invMass.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
        mass[i] = rng.uniform(0.5, 2.0);
        invMass[i] = 1.0 / mass[i];
    }
}

/// Experiment I of the paper: 35 x 35 particles, mass 0.5, spacing 10, stiffness 20, the two
/// top corners pinned, gravity 9.8 downward. `vertical`: the sheet hangs in the x-y plane
/// (row 0 on top); otherwise it starts horizontal (x-z plane) and swings down.
std::unique_ptr<Cloth> experimentOne(LimiterKind limiter, bool vertical,
                                     IntegratorKind kind = IntegratorKind::VelocityVerlet) {
    SheetSpec spec;
    spec.rows = 35;
    spec.cols = 35;
    spec.spacing = 10.0;
    spec.uAxis = Vec3::UnitX();
    spec.vAxis = vertical ? Vec3(-Vec3::UnitY()) : Vec3(Vec3::UnitZ());
    ClothSettings s;
    s.relativeDamping = 0.0; // the motion measured here is undamped or damped by C_d only
    s.integrator = kind;
    s.particleMass = 0.5;
    s.springStiffness = 20.0;
    s.gravity = Vec3(0.0, -9.8, 0.0);
    s.limiter.kind = limiter;
    auto cloth = std::make_unique<Cloth>(ClothTopology::build(makeSheet(spec)), s);
    cloth->pin(sheetIndex(spec, 0, 0));
    cloth->pin(sheetIndex(spec, 0, 34));
    return cloth;
}

bool allFinite(const Cloth& c) {
    for (std::size_t i = 0; i < c.particleCount(); ++i)
        if (!c.positions()[i].allFinite() || !c.velocities()[i].allFinite()) return false;
    return true;
}

LimiterSettings limiterSettings(double maxStrain = 0.1) {
    LimiterSettings s;
    s.maxStrain = maxStrain;
    return s;
}

/// The topology of a rows x cols sheet of the given spacing (makeSheet's defaults otherwise).
std::shared_ptr<const ClothTopology> sheetTopology(Index rows, Index cols, double spacing) {
    SheetSpec spec;
    spec.rows = rows;
    spec.cols = cols;
    spec.spacing = spacing;
    return ClothTopology::build(makeSheet(spec));
}

} // namespace

TEST_CASE("Experiment I without a limiter overstretches far beyond 10 %",
          "[limiter][experiment1]") {
    for (bool vertical : {true, false}) {
        auto cloth = experimentOne(LimiterKind::None, vertical);
        double peak = 0.0, at2 = 0.0;
        for (int n = 0; n < 1000; ++n) { // 10 s of simulated time at dt = 0.01
            cloth->step(0.01);
            peak = std::max(peak, cloth->maxStrain());
            if (n == 199) at2 = cloth->maxStrain();
        }
        INFO(measured("Experiment I (%s start), no limiter: max strain at t = 2 s %.3f, "
                      "at t = 10 s %.3f, peak over 10 s %.3f",
                      vertical ? "vertical" : "horizontal", at2, cloth->maxStrain(), peak));
        // The sheet weighs 35*35*0.5*9.8 = 6.0 kN. At 10 % strain a spring holds only
        // k * 0.1 * L0 = 20 N (28 N on a diagonal), so the handful of springs at each pinned
        // corner cannot carry it: the static equilibrium needs corner strains of several
        // hundred percent, and the undamped sheet overshoots on its way there. The tension
        // wave (speed L0 sqrt(k/m) = 63 m/s over a 340 m sheet) is still arriving at 2 s, so
        // we ask for twice the limit then and five times the limit within 10 s.
        if (vertical) CHECK(at2 > 0.2);
        CHECK(at2 > 0.1);
        CHECK(peak > 0.5);
        CHECK(allFinite(*cloth));
    }
}

namespace {
/// Runs Experiment I for 200 steps (2 s) with a limiter and checks the strain bound after
/// every step: maxStrain + tolerance (the limiter's documented stopping rule), plus 1e-12 for
/// the rounding of l / L0; no NaN; pinned corners exactly where they were.
void experimentOneWithLimiter(LimiterKind kind, bool vertical, double slack = 0.0) {
    auto cloth = experimentOne(kind, vertical);
    const double limit =
        cloth->settings().limiter.maxStrain + cloth->settings().limiter.tolerance + slack;
    const Vec3 pin0 = cloth->positions()[0], pin1 = cloth->positions()[34];
    double worst = 0.0;
    int maxRounds = 0, over = 0, firstOver = -1;
    bool finite = true, pinsHeld = true;
    for (int n = 0; n < 200; ++n) {
        cloth->step(0.01);
        const double strain = cloth->maxStrain();
        worst = std::max(worst, strain);
        maxRounds = std::max(maxRounds, cloth->lastLimiterStats().rounds);
        if (strain > limit + 1e-12) {
            ++over;
            if (firstOver < 0) firstOver = n;
        }
        finite = finite && allFinite(*cloth);
        pinsHeld = pinsHeld && cloth->positions()[0] == pin0 && cloth->positions()[34] == pin1 &&
                   cloth->velocities()[0] == Vec3::Zero() &&
                   cloth->velocities()[34] == Vec3::Zero();
    }
    INFO(measured("Experiment I (%s start), %s limiter: max strain over 200 steps "
                  "%.6f (limit %.2f + tolerance %.0e), steps over the limit %d, most rounds "
                  "in a step %d (maxRounds %d)",
                  vertical ? "vertical" : "horizontal", toString(kind), worst,
                  cloth->settings().limiter.maxStrain, cloth->settings().limiter.tolerance, over,
                  maxRounds, cloth->settings().limiter.maxRounds));
    INFO(toString(kind) << (vertical ? " vertical" : " horizontal") << ": worst strain " << worst
                        << ", " << over << " steps over the limit, first at step " << firstOver);
    CHECK(over == 0);
    CHECK(finite);
    CHECK(pinsHeld);
}
} // namespace

TEST_CASE("Experiment I with the Provot limiter stays within 10 % at every step",
          "[limiter][experiment1]") {
    experimentOneWithLimiter(LimiterKind::Provot, true);
    experimentOneWithLimiter(LimiterKind::Provot, false);
}

TEST_CASE("Experiment I (horizontal start) with the stress-ordered limiter stays within 10 %",
          "[limiter][experiment1]") {
    experimentOneWithLimiter(LimiterKind::StressOrdered, false);
}

TEST_CASE("Experiment I (vertical start) with the stress-ordered limiter stays within 10 %",
          "[limiter][experiment1]") {
    experimentOneWithLimiter(LimiterKind::StressOrdered, true);
}

// The shipped scene (samples/scenes/experiment1_suspended_sheet.json): vertical start, damping
// C_d = 0.05 N s/m, 10 s. The bound is a promise after every step (no safety-cap hit), and the
// limiter, an inelastic projection apart from the warm start's bounded overshoot, must not be
// an energy source: the rises of kinetic + gravitational + spring energy from one step to the
// next add up to at most 0.1 % of what the run dissipates, none above 50 J (the bars;
// the sheet's weight times one tolerance band of the 35 rows, 6 kN * 0.35 m = 2 kJ, is the
// scale an unbounded overshoot would reach).
TEST_CASE("Experiment I, 10 s with damping: bound every step, no energy source",
          "[limiter][experiment1][energy]") {
    SheetSpec spec;
    spec.rows = 35;
    spec.cols = 35;
    spec.spacing = 10.0;
    spec.vAxis = -Vec3::UnitY();
    ClothSettings s;
    s.relativeDamping = 0.0; // the motion measured here is undamped or damped by C_d only
    s.particleMass = 0.5;
    s.springStiffness = 20.0;
    s.damping = 0.05;
    s.gravity = Vec3(0.0, -9.8, 0.0);
    Cloth cloth(ClothTopology::build(makeSheet(spec)), s);
    cloth.pin(sheetIndex(spec, 0, 0));
    cloth.pin(sheetIndex(spec, 0, 34));
    auto energy = [&] { return mechanicalEnergy(cloth); };
    double e = energy(), rise = 0.0, maxRise = 0.0, dissipated = 0.0, worst = 0.0;
    for (int n = 0; n < 1000; ++n) {
        cloth.step(0.01);
        worst = std::max(worst, cloth.maxStrain());
        const double e2 = energy();
        if (e2 > e) {
            rise += e2 - e;
            maxRise = std::max(maxRise, e2 - e);
        } else {
            dissipated += e - e2;
        }
        e = e2;
    }
    INFO(measured("Experiment I 10 s, C_d 0.05: peak strain %.6f, energy rise %.2f J "
                  "(largest step %.2f J), dissipated %.4g J, cap hits %llu",
                  worst, rise, maxRise, dissipated,
                  static_cast<unsigned long long>(cloth.limiterCapHits())));
    CHECK(worst <= 0.1 + s.limiter.tolerance + 1e-12);
    CHECK(cloth.limiterCapHits() == 0);
    CHECK(dissipated > 1e5); // the sheet falls ~200 m under 6 kN: most of it is dissipated
    CHECK(rise <= 1e-3 * dissipated);
    CHECK(maxRise <= 50.0);
}

namespace {
/// A triangle with an obtuse corner at particle 2: moving 2 away from 0 along the 0-2 spring
/// shortens 1-2, so only spring 0-2 ends up overstretched.
struct ObtuseCase {
    TopologyPtr topo = [] {
        TriangleMesh m;
        m.vertices = {Vec3(0, 0, 0), Vec3(2, 0, 0), Vec3(1, 0.3, 0)};
        m.triangles = {{0, 1, 2}};
        return ClothTopology::build(m);
    }();
    std::vector<Vec3> stretched() const {
        auto x = topo->restPositions();
        x[2] = 1.3 * x[2]; // spring 0-2 at 30 % strain, 1-2 compressed
        return x;
    }
    double restLength02() const { return topo->restPositions()[2].norm(); }
};
} // namespace

TEST_CASE("Limiters move only free ends, never pinned particles", "[limiter]") {
    ObtuseCase c;
    const auto x0 = c.stretched();
    REQUIRE(maxSpringStrain(*c.topo, x0) == Approx(0.3).epsilon(1e-12));
    LimiterSettings s = limiterSettings();
    const Vec3 target = (1.1 * c.restLength02()) * x0[2].normalized(); // 0-2 at exactly 10 %

    const std::vector<double> k(c.topo->springCount(), 1.0);
    SECTION("one end pinned: the free end is pulled back along the spring") {
        const std::vector<double> invMass{0.0, 1.0, 1.0};
        for (int which = 0; which < 2; ++which) {
            auto x = x0;
            StrainLimitStats st;
            if (which == 0) {
                StrainLimiter limiter;
                st = limiter.limit(*c.topo, invMass, k, s, x);
            } else {
                st = limitStrainProvot(*c.topo, invMass, s, x);
            }
            INFO((which == 0 ? "stress-ordered" : "provot") << " rounds " << st.rounds);
            CHECK(x[0] == x0[0]);
            CHECK(x[1] == x0[1]);
            CHECK((x[2] - target).norm() < 1e-12); // a few operations on O(1) numbers
            // (the stress-ordered scan runs after its long-range attachment moved particle 2)
            if (which == 1) CHECK(st.maxStrainBefore == Approx(0.3).epsilon(1e-12));
            CHECK(st.maxStrainAfter <= 0.1 + s.tolerance);
        }
    }
    SECTION("both ends pinned: nothing moves") {
        const std::vector<double> invMass{0.0, 1.0, 0.0};
        auto x = x0;
        StrainLimiter limiter;
        limiter.limit(*c.topo, invMass, k, s, x);
        CHECK(x == x0);
        x = x0;
        limitStrainProvot(*c.topo, invMass, s, x);
        CHECK(x == x0);
    }
    SECTION("two free ends of equal mass move symmetrically") {
        // Provot's rule: each end moves by its inverse-mass share, so the spring's midpoint
        // stays and the spring ends at exactly 10 %; particle 1 (compressed springs) stays.
        const std::vector<double> invMass{1.0, 1.0, 1.0};
        for (int which = 0; which < 2; ++which) {
            auto x = x0;
            if (which == 0) {
                StrainLimiter limiter;
                limiter.limit(*c.topo, invMass, k, s, x);
            } else {
                limitStrainProvot(*c.topo, invMass, s, x);
            }
            INFO((which == 0 ? "stress-ordered" : "provot"));
            CHECK(x[1] == x0[1]);
            CHECK((0.5 * (x[0] + x[2]) - 0.5 * (x0[0] + x0[2])).norm() < 1e-12);
            CHECK((x[2] - x[0]).norm() == Approx(1.1 * c.restLength02()).epsilon(1e-12));
        }
    }
}

TEST_CASE("The worklist sets a spring to exactly the limit and warm-starts the next step",
          "[limiter]") {
    // One spring 0-1 (rest 1), particle 0 pinned; 1-2 only shortens when 1 moves. Attachments
    // off, so only the spring rule acts.
    TriangleMesh m;
    m.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(10, 0.5, 0)};
    m.triangles = {{0, 1, 2}};
    const auto topo = ClothTopology::build(m);
    const std::vector<double> invMass{0.0, 2.0, 0.0};
    const std::vector<double> k(topo->springCount(), 1.0);
    LimiterSettings s = limiterSettings();
    s.longRangeAttachments = false;
    s.warmStart = 0.5;
    StrainLimiter limiter;
    for (double strain : {0.1005, 0.105, 0.5, 3.0}) {
        limiter.resetWarmStart();
        auto x = topo->restPositions();
        x[1] = Vec3(1.0 + strain, 0, 0);
        limiter.clearMoved();
        const auto st = limiter.limit(*topo, invMass, k, s, x);
        INFO("strain " << strain);
        if (strain <= 0.1 + s.tolerance) { // inside the band: left alone
            CHECK(st.corrections == 0);
            CHECK(x[1] == Vec3(1.0 + strain, 0, 0));
            continue;
        }
        CHECK((x[1] - x[0]).norm() == Approx(1.1).epsilon(1e-12));
        CHECK(x[1].y() == Approx(0.0).margin(1e-12)); // along the spring only
        // The limiter reports what it moved and from where.
        REQUIRE(limiter.movedIndex().size() == 1);
        CHECK(limiter.movedIndex()[0] == 1);
        CHECK(limiter.movedFrom()[0] == Vec3(1.0 + strain, 0, 0));
        // lambda: the end moved by w lambda = strain - 0.1.
        double lambda = 0.0;
        for (double l : limiter.warmStartState())
            lambda = std::max(lambda, l);
        CHECK(2.0 * lambda == Approx(strain - 0.1).epsilon(1e-9));
        // Next step from the same stretched state: the warm start moves particle 1 by half of
        // the last correction first; the walk then finishes at exactly the limit, and lambda
        // still measures the whole correction.
        x[1] = Vec3(1.0 + strain, 0, 0);
        limiter.limit(*topo, invMass, k, s, x);
        CHECK((x[1] - x[0]).norm() == Approx(1.1).epsilon(1e-12));
        double lambda2 = 0.0;
        for (double l : limiter.warmStartState())
            lambda2 = std::max(lambda2, l);
        CHECK(2.0 * lambda2 == Approx(strain - 0.1).epsilon(1e-9));
        // A warm start larger than needed is let out, never turned into a push: the spring,
        // now at its rest length, is pulled in by the warm start (at most to half its rest
        // length) and let out again to where it was.
        x[1] = Vec3(1.0, 0, 0);
        limiter.limit(*topo, invMass, k, s, x);
        CHECK((x[1] - x[0]).norm() == Approx(1.0).epsilon(1e-12));
        for (double l : limiter.warmStartState())
            CHECK(l >= 0.0);
    }
}

TEST_CASE("maxSpringStrain is the largest strain of any spring, on family slots and loose springs",
          "[limiter]") {
    // Its kernel reads a sheet's springs by family slot from coordinate arrays, an irregular
    // mesh's mostly as loose springs: both must give what a loop over the springs gives.
    const std::shared_ptr<const ClothTopology> meshes[] = {
        sheetTopology(17, 23, 0.05), ClothTopology::build(irregularMesh(9, 7, 5, true))};
    Rng rng(11);
    for (const auto& topo : meshes) {
        for (int trial = 0; trial < 20; ++trial) {
            std::vector<Vec3> x;
            for (const Vec3& p : topo->restPositions())
                x.push_back(1.05 * p + Vec3(rng.uniform(-0.02, 0.02), rng.uniform(-0.02, 0.02),
                                            rng.uniform(-0.02, 0.02)));
            // One spring, anywhere, stretched by far the most.
            const Spring& far = topo->springs()[std::size_t(rng.below(int(topo->springCount())))];
            x[far.b] = x[far.a] + 2.5 * (x[far.b] - x[far.a]);
            double direct = -1.0;
            for (const Spring& sp : topo->springs())
                direct = std::max(direct, (x[sp.b] - x[sp.a]).norm() / sp.restLength - 1.0);
            INFO("particles " << topo->particleCount() << ", trial " << trial);
            CHECK(maxSpringStrain(*topo, x) == Approx(direct).epsilon(1e-12));
        }
    }
}

TEST_CASE("Limiters without pins keep the centre of mass (inverse-mass shares)", "[limiter]") {
    // Unpinned, unequal masses: every correction moves the two ends by w_a, w_b shares, so
    // sum m_i x_i is unchanged; on a badly overstretched irregular mesh the sweeps converge.
    const auto topo = ClothTopology::build(irregularMesh(6, 5, 77, true));
    const std::size_t n = topo->particleCount();
    std::vector<double> mass, invMass;
    Rng rng(1);
    randomMasses(rng, n, mass, invMass);
    std::vector<Vec3> x;
    for (const Vec3& p : topo->restPositions())
        x.push_back(1.25 * p +
                    Vec3(rng.uniform(-0.1, 0.1), rng.uniform(-0.1, 0.1), rng.uniform(-0.1, 0.1)));
    auto centre = [&](const std::vector<Vec3>& y) {
        Vec3 c = Vec3::Zero();
        double M = 0.0;
        for (std::size_t i = 0; i < n; ++i) {
            c += mass[i] * y[i];
            M += mass[i];
        }
        return Vec3(c / M);
    };
    const Vec3 c0 = centre(x);
    LimiterSettings s = limiterSettings();
    s.maxRounds = 1000;
    const std::vector<double> k(topo->springCount(), 1.0);
    for (int which = 0; which < 2; ++which) {
        auto y = x;
        StrainLimitStats st;
        if (which == 0) {
            st = limitStrainProvot(*topo, invMass, s, y);
        } else {
            StrainLimiter limiter;
            st = limiter.limit(*topo, invMass, k, s, y);
        }
        INFO((which == 0 ? "provot" : "stress-ordered") << " rounds " << st.rounds);
        CHECK(st.maxStrainBefore > 0.2);
        CHECK(st.maxStrainAfter <= 0.1 + s.tolerance);
        // Provot measures the strain it left; the walk reports its band's top, a bound.
        if (which == 0) CHECK(maxSpringStrain(*topo, y) == Approx(st.maxStrainAfter).margin(1e-15));
        CHECK(maxSpringStrain(*topo, y) <= st.maxStrainAfter + 1e-15);
        CHECK((centre(y) - c0).norm() < 1e-12); // sums of O(1) numbers over a few thousand fixes
    }
}

namespace {
/// The irregular unpinned sheet of the contact-plane tests, its random masses (seed 3), and the
/// mean x of its particles (the left half gets planes).
struct PlaneSheet {
    std::shared_ptr<const ClothTopology> topo;
    std::vector<double> mass, invMass;
    double xMid = 0.0;
};
PlaneSheet planeSheet() {
    PlaneSheet sheet;
    sheet.topo = ClothTopology::build(irregularMesh(8, 6, 5));
    const std::size_t n = sheet.topo->particleCount();
    Rng rng(3);
    randomMasses(rng, n, sheet.mass, sheet.invMass);
    for (const Vec3& p : sheet.topo->restPositions())
        sheet.xMid += p.x() / double(n);
    return sheet;
}
/// A fresh limiter's relimit of x with every particle touched and the walk keeping `planes`.
StrainLimitStats relimitEverything(const ClothTopology& topo, const std::vector<double>& invMass,
                                   const LimiterSettings& s, std::vector<Vec3>& x,
                                   ContactPlanes& planes) {
    std::vector<Index> all(topo.particleCount());
    for (std::size_t i = 0; i < all.size(); ++i)
        all[i] = static_cast<Index>(i);
    const std::vector<double> k(topo.springCount(), 1.0);
    StrainLimiter limiter;
    limiter.clearMoved();
    return limiter.relimit(topo, invMass, k, s, all, x, &planes);
}
} // namespace

TEST_CASE("relimit keeps particles above their contact planes and reaches the bound",
          "[limiter][contact]") {
    // An irregular unpinned sheet, unequal masses: the particles of its left half lie on a
    // table (plane y >= 0, tilted planes too), the right half is pulled far down and sideways
    // (an overhang that fell for one step). relimit with the planes must end with every spring
    // within the bound, every planed particle on or above its plane, and the momentum the
    // planes added (m push, the only outside impulse) equal to the change of sum m x.
    const PlaneSheet sheet = planeSheet();
    const auto& topo = sheet.topo;
    const std::size_t n = topo->particleCount();
    const std::vector<double>& mass = sheet.mass;
    const std::vector<double>& invMass = sheet.invMass;
    LimiterSettings s = limiterSettings();
    s.longRangeAttachments = false;
    const double xMid = sheet.xMid;
    for (const Vec3& normal : {Vec3(0, 1, 0), Vec3(Vec3(0.3, 1, 0.2).normalized())}) {
        std::vector<Vec3> x = topo->restPositions();
        ContactPlanes planes;
        planes.reset(n);
        for (std::size_t i = 0; i < n; ++i) {
            if (x[i].x() < xMid) {
                x[i] -= normal.dot(x[i]) * normal; // on the plane through the origin
                planes.set(static_cast<Index>(i), normal, 0.0);
            } else {
                x[i] += Vec3(0.3 * (x[i].x() - xMid), -2.0 * (x[i].x() - xMid), 0.0);
            }
        }
        const std::vector<Vec3> before = x;
        const auto st = relimitEverything(*topo, invMass, s, x, planes);
        INFO("normal " << normal.transpose() << ", waves " << st.rounds << ", work " << st.work);
        CHECK(maxSpringStrain(*topo, before) > 0.5);
        CHECK_FALSE(st.capHit);
        CHECK(maxSpringStrain(*topo, x) <= s.maxStrain + s.tolerance + 1e-12);
        Vec3 dp = Vec3::Zero(), pushed = Vec3::Zero();
        double totalPush = 0.0;
        for (std::size_t i = 0; i < n; ++i)
            dp += mass[i] * (x[i] - before[i]);
        for (std::size_t p = 0; p < planes.size(); ++p) {
            const Index i = planes.particle(p);
            CHECK(normal.dot(x[i]) >= -1e-12);
            pushed += mass[i] * planes.push[p];
            totalPush += planes.push[p].norm();
            CHECK(planes.push[p].cross(normal).norm() <= 1e-12); // pushes go along n only
        }
        CHECK(totalPush > 0.1); // the overhang pulled the table half into its plane
        CHECK((dp - pushed).norm() <= 1e-10);
    }
}

TEST_CASE("a spring pinned across a contact plane is left long, not shortened by a jump",
          "[limiter][contact]") {
    // A 2 x 2 sheet (spacing 5 cm) hangs from its pinned top row; its bottom row lies on a
    // plane y <= -0.1 (a still body's face: n = -y), a hair's breadth off the vertical below
    // the pins. No slide along the plane brings the bottom row within the bound of its pins
    // (0.1 m apart across the plane against 0.055 allowed): the first-order slide that a
    // correction asks for is excess / sin(theta), 9 m here. The walk must leave those springs
    // long (the plane wins) and move nothing farther than a spring is long.
    const auto topo = sheetTopology(2, 2, 0.05);
    std::vector<double> invMass(4, 1000.0);
    invMass[0] = invMass[1] = 0.0; // the pinned top row
    std::vector<Vec3> x = topo->restPositions();
    x[2] = Vec3(0.0005, -0.1, 0.0);
    x[3] = Vec3(0.0505, -0.1, 0.0);
    ContactPlanes planes;
    planes.reset(4);
    for (Index i : {Index(2), Index(3)})
        planes.set(i, Vec3(0, -1, 0), 0.1);
    LimiterSettings s = limiterSettings();
    s.longRangeAttachments = false;
    const std::vector<Vec3> before = x;
    const auto st = relimitEverything(*topo, invMass, s, x, planes);
    double moved = 0.0;
    for (std::size_t i = 0; i < 4; ++i)
        moved = std::max(moved, (x[i] - before[i]).norm());
    INFO("largest move " << moved << " m, waves " << st.rounds);
    CHECK_FALSE(st.capHit);
    CHECK(moved <= 0.05 * std::sqrt(2.0));
    CHECK(x[2].y() <= -0.1 + 1e-12);
    CHECK(x[3].y() <= -0.1 + 1e-12);
}

TEST_CASE("a walk whose held particles are farther apart than its springs reach stops early",
          "[limiter][bound]") {
    // A 10 x 10 sheet (spacing 0.1 m) with the two ends of its top row held; the row between
    // them is 9 springs, 0.9 m at rest, so within the bound they reach at most
    // 0.9 (1 + 0.1 + 0.001) = 0.991 m apart. Moved 1.05 x 0.9 = 0.945 m apart the walk can and
    // must finish within the bound; moved 1.2 x 0.9 = 1.08 m apart no walk can: it used to run
    // to its cap (1000 sweeps, 1.1 s a frame in a game whose pins were teleported), and now
    // stops after StrainLimiter::kApartCheck sweeps and says why.
    const auto topo = sheetTopology(10, 10, 0.1);
    std::vector<double> invMass(topo->particleCount(), 1.0);
    invMass[0] = invMass[9] = 0.0;
    const std::vector<double> k(topo->springCount(), 1.0);
    LimiterSettings s = limiterSettings();
    const double ns = static_cast<double>(topo->springCount());
    for (const double apart : {1.05, 1.2}) {
        StrainLimiter limiter;
        std::vector<Vec3> x = topo->restPositions();
        const Vec3 along = (x[9] - x[0]).normalized();
        x[9] = x[0] + apart * 0.9 * along;
        // The free particles of the top row spread evenly between the two (a start within
        // reach of both ends for the feasible case).
        for (Index c = 1; c < 9; ++c)
            x[c] = x[0] + (apart * 0.1 * c) * along;
        const StrainLimitStats st = limiter.limit(*topo, invMass, k, s, x);
        INFO(measured("held %.3f m apart: %.1f sweeps, cap %d, pins apart %d, strain after %.4f",
                      apart * 0.9, double(st.work) / ns, int(st.capHit), int(st.pinsApart),
                      maxSpringStrain(*topo, x)));
        if (apart < 1.1) {
            CHECK_FALSE(st.pinsApart);
            CHECK_FALSE(st.capHit);
            CHECK(maxSpringStrain(*topo, x) <= s.maxStrain + s.tolerance + 1e-12);
        } else {
            CHECK(st.pinsApart);
            CHECK(st.capHit);
            CHECK(double(st.work) <= 2.0 * StrainLimiter::kApartCheck * ns);
        }
    }
}

TEST_CASE("a body that gives way in the walk takes what its planes push, momentum conserved",
          "[limiter][contact]") {
    // The sheet of the test above, its left half lying on a free body (ContactPlanes::Mover)
    // instead of a table, the right half pulled far down. The walk must reach the bound with
    // every planed particle on or above its plane where the body moved it, and the body's
    // momentum change M shift must be the opposite of the cloth's, sum m dx (the planes are
    // the only outside push). A light body gives way more than a heavy one.
    const PlaneSheet sheet = planeSheet();
    const auto& topo = sheet.topo;
    const std::size_t n = topo->particleCount();
    const std::vector<double>& mass = sheet.mass;
    const std::vector<double>& invMass = sheet.invMass;
    double clothMass = 0.0;
    for (double m : mass)
        clothMass += m;
    LimiterSettings s = limiterSettings();
    s.longRangeAttachments = false;
    const double xMid = sheet.xMid;
    const Vec3 normal = Vec3(0.3, 1, 0.2).normalized();
    double shiftOf[2] = {0.0, 0.0};
    for (int heavy = 0; heavy < 2; ++heavy) {
        const double bodyMass = heavy ? 100.0 * clothMass : 0.01 * clothMass;
        std::vector<Vec3> x = topo->restPositions();
        ContactPlanes planes;
        planes.reset(n);
        const Vec3 centre(xMid, -0.2, 0.1);
        // A box-like inertia for a body of that mass about 0.5 m across.
        const Eigen::Matrix3d invInertia =
            Eigen::Matrix3d::Identity() / (bodyMass * (0.25 + 0.25) / 12.0);
        planes.movers.push_back(ContactPlanes::Mover{1.0 / bodyMass, invInertia, centre});
        for (std::size_t i = 0; i < n; ++i) {
            if (x[i].x() < xMid) {
                x[i] -= normal.dot(x[i]) * normal; // on the plane through the origin
                const auto plane = std::size_t(planes.set(static_cast<Index>(i), normal, 0.0));
                planes.moveWith(plane, 0, x[i] - centre);
            } else {
                x[i] += Vec3(0.3 * (x[i].x() - xMid), -2.0 * (x[i].x() - xMid), 0.0);
            }
        }
        const std::vector<Vec3> before = x;
        const auto st = relimitEverything(*topo, invMass, s, x, planes);
        const ContactPlanes::Mover& body = planes.movers[0];
        INFO("body mass " << bodyMass << " kg, waves " << st.rounds << ", shift "
                          << body.shift.transpose() << ", turn " << body.turn.transpose());
        CHECK_FALSE(st.capHit);
        CHECK(maxSpringStrain(*topo, x) <= s.maxStrain + s.tolerance + 1e-12);
        Vec3 dp = Vec3::Zero(), pushed = Vec3::Zero();
        for (std::size_t i = 0; i < n; ++i)
            dp += mass[i] * (x[i] - before[i]);
        for (std::size_t p = 0; p < planes.size(); ++p) {
            const Index i = planes.particle(p);
            CHECK(normal.dot(x[i]) >= planes.offsetNow(p) - 1e-12);
            pushed += mass[i] * planes.push[p];
        }
        CHECK(pushed.norm() > 1e-3);
        CHECK((dp - pushed).norm() <= 1e-10);
        CHECK((dp + bodyMass * body.shift).norm() <= 1e-10 * (1.0 + dp.norm()));
        CHECK(body.shift.dot(normal) < 0.0); // pushed into its side, away from the cloth
        shiftOf[heavy] = body.shift.norm();
        // settleMovers moves and turns each plane rigidly with the body: its contact point
        // (centre + lever) stays at the same height over it, its normal at the same angle to
        // the lever; and the body starts again from rest.
        std::vector<double> height, angle;
        for (std::size_t p = 0; p < planes.size(); ++p) {
            height.push_back(planes.offset[p] - planes.normal[p].dot(centre + planes.lever[p]));
            angle.push_back(planes.normal[p].dot(planes.lever[p]));
        }
        const Vec3 moved = centre + body.shift;
        planes.settleMovers();
        CHECK((planes.movers[0].centre - moved).norm() <= 1e-15);
        for (std::size_t p = 0; p < planes.size(); ++p) {
            CHECK(planes.normal[p].norm() == Approx(1.0).margin(1e-14));
            CHECK(planes.normal[p].dot(planes.lever[p]) == Approx(angle[p]).margin(1e-14));
            CHECK(planes.offset[p] - planes.normal[p].dot(moved + planes.lever[p]) ==
                  Approx(height[p]).margin(1e-14));
        }
        CHECK(planes.movers[0].shift == Vec3::Zero());
    }
    CHECK(shiftOf[0] > 100.0 * shiftOf[1]);
}

TEST_CASE("a free body carrying particles gives way in the walk, rigidly, momentum conserved",
          "[limiter][carrier]") {
    // The irregular sheet of the tests above, its left-most particles attached to a free body
    // (zero inverse mass in the cloth, carried by a ContactPlanes::Mover), the rest pulled far
    // down and sideways. The walk (long-range attachments from the carried particles, then the
    // waves) must reach the bound; the carried particles move as one rigid body with it (their
    // distances kept, each where the body's shift and turn put it); the body's momentum
    // change M shift is the opposite of the free particles' sum m dx, and it is what the
    // held particles took (heldPull, the impulse the glue hands the body). A light body gives
    // way more than a heavy one.
    const PlaneSheet sheet = planeSheet();
    const auto& topo = sheet.topo;
    const std::size_t n = topo->particleCount();
    double xMin = 1e9;
    for (const Vec3& p : topo->restPositions())
        xMin = std::min(xMin, p.x());
    std::vector<double> invMass = sheet.invMass;
    std::vector<Index> carried;
    double clothMass = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
        clothMass += sheet.mass[i];
        if (topo->restPositions()[i].x() < xMin + 0.15) {
            carried.push_back(static_cast<Index>(i));
            invMass[i] = 0.0;
        }
    }
    REQUIRE(carried.size() >= 3);
    const LimiterSettings s = limiterSettings();
    const std::vector<double> k(topo->springCount(), 1.0);
    double shiftOf[2] = {0.0, 0.0};
    for (int heavy = 0; heavy < 2; ++heavy) {
        const double bodyMass = heavy ? 100.0 * clothMass : 0.5 * clothMass;
        std::vector<Vec3> x = topo->restPositions();
        for (std::size_t i = 0; i < n; ++i)
            if (invMass[i] > 0.0) x[i] += Vec3(0.1, -0.5, 0.1) * (x[i].x() - xMin - 0.15);
        Vec3 centre = Vec3::Zero();
        for (Index i : carried)
            centre += x[i] / double(carried.size());
        centre += Vec3(-0.05, 0.1, 0.0);
        ContactPlanes planes;
        planes.reset(n);
        const Eigen::Matrix3d invInertia =
            Eigen::Matrix3d::Identity() / (bodyMass * (0.04 + 0.04) / 12.0);
        planes.movers.push_back(ContactPlanes::Mover{1.0 / bodyMass, invInertia, centre});
        for (Index i : carried)
            planes.carry(0, i, x[i]);
        const std::vector<Vec3> before = x;
        StrainLimiter limiter;
        limiter.setRecordHeld(true);
        limiter.clearMoved();
        const StrainLimitStats st = limiter.limit(*topo, invMass, k, s, x, &planes);
        const ContactPlanes::Mover& body = planes.movers[0];
        INFO("body mass " << bodyMass << " kg, waves " << st.rounds << ", shift "
                          << body.shift.transpose() << ", turn " << body.turn.transpose());
        CHECK(maxSpringStrain(*topo, before) > 0.3);
        CHECK_FALSE(st.capHit);
        CHECK(body.applied());
        CHECK(maxSpringStrain(*topo, x) <= s.maxStrain + s.tolerance + 1e-12);
        // Rigid: where the body put them, their distances kept.
        for (Index i : carried) {
            const ContactPlanes::Carried& c =
                planes.carried[std::size_t(planes.carriedOf[std::size_t(i)])];
            CHECK((x[i] - planes.carriedNow(c)).norm() <= 1e-12);
            for (Index j : carried)
                CHECK((x[i] - x[j]).norm() == Approx((before[i] - before[j]).norm()).margin(1e-12));
        }
        Vec3 dp = Vec3::Zero(), held = Vec3::Zero();
        for (std::size_t i = 0; i < n; ++i)
            if (invMass[i] > 0.0) dp += sheet.mass[i] * (x[i] - before[i]);
        for (Index i : limiter.heldIndex())
            held += limiter.heldPull()[i];
        CHECK(dp.norm() > 1e-3);
        CHECK((dp + bodyMass * body.shift).norm() <= 1e-10 * (1.0 + dp.norm()));
        CHECK((held - bodyMass * body.shift).norm() <= 1e-10 * (1.0 + dp.norm()));
        shiftOf[heavy] = body.shift.norm();
        // settleMovers carries them on: each where the body now is, lever turned with it.
        const Vec3 moved = centre + body.shift;
        planes.settleMovers();
        for (Index i : carried) {
            const ContactPlanes::Carried& c =
                planes.carried[std::size_t(planes.carriedOf[std::size_t(i)])];
            CHECK((c.at - x[i]).norm() <= 1e-12);
            CHECK((moved + c.lever - x[i]).norm() <= 1e-12);
        }
    }
    CHECK(shiftOf[0] > 50.0 * shiftOf[1]);
}

TEST_CASE("the walk holds a spring whose ends two bodies carry by moving both bodies",
          "[limiter][carrier]") {
    // The irregular sheet, every particle held (zero inverse mass): its left half carried by
    // body A, its right half by body B (the posts a banner hangs between). B's half is moved
    // away along x, so the springs across the middle have both ends held by different bodies:
    // no particle can move, the bodies must. The walk brings them to the bound by shifting A
    // and B towards each other (turning them a little: the springs cross at different
    // heights), the halves rigid; the momentum M_A shift_A + M_B shift_B stays zero, and what
    // each body's particles took (heldPull) is its own M shift. Before, the walk skipped every
    // spring with both ends held and left these at their stretch.
    const PlaneSheet sheet = planeSheet();
    const auto& topo = sheet.topo;
    const std::size_t n = topo->particleCount();
    const std::vector<double> invMass(n, 0.0);
    std::vector<Vec3> x = topo->restPositions();
    std::vector<int> side(n);
    for (std::size_t i = 0; i < n; ++i) {
        side[i] = x[i].x() < sheet.xMid ? 0 : 1;
        if (side[i] == 1) x[i].x() += 0.3;
    }
    const double mass[2] = {0.3, 0.1};
    ContactPlanes planes;
    planes.reset(n);
    for (int b = 0; b < 2; ++b) {
        Vec3 centre = Vec3::Zero();
        double count = 0.0;
        for (std::size_t i = 0; i < n; ++i)
            if (side[i] == b) {
                centre += x[i];
                count += 1.0;
            }
        planes.movers.push_back(ContactPlanes::Mover{
            1.0 / mass[b], Eigen::Matrix3d::Identity() / mass[b], centre / count}); // gyration 1 m
    }
    // (One body's particles after the other's; interleaved, carry refuses them.)
    REQUIRE_THROWS_AS(
        [&] {
            ContactPlanes wrong = planes;
            for (std::size_t i = 0; i < n; ++i)
                wrong.carry(side[i], static_cast<Index>(i), x[i]);
        }(),
        Error);
    for (int b = 0; b < 2; ++b)
        for (std::size_t i = 0; i < n; ++i)
            if (side[i] == b) planes.carry(b, static_cast<Index>(i), x[i]);
    const LimiterSettings s = limiterSettings();
    const std::vector<double> k(topo->springCount(), 1.0);
    const std::vector<Vec3> before = x;
    StrainLimiter limiter;
    limiter.setRecordHeld(true);
    limiter.clearMoved();
    const StrainLimitStats st = limiter.limit(*topo, invMass, k, s, x, &planes);
    const Vec3 shiftA = planes.movers[0].shift, shiftB = planes.movers[1].shift;
    INFO("waves " << st.rounds << ", shift A " << shiftA.transpose() << ", B " << shiftB.transpose()
                  << ", strain before " << maxSpringStrain(*topo, before) << " after "
                  << maxSpringStrain(*topo, x));
    CHECK(maxSpringStrain(*topo, before) > 0.3);
    CHECK_FALSE(st.capHit);
    CHECK(maxSpringStrain(*topo, x) <= s.maxStrain + s.tolerance + 1e-12);
    CHECK(shiftA.x() > 0.0);
    CHECK(shiftB.x() < 0.0);
    CHECK((mass[0] * shiftA + mass[1] * shiftB).norm() <= 1e-10);
    Vec3 held[2] = {Vec3::Zero(), Vec3::Zero()};
    for (Index i : limiter.heldIndex())
        held[side[i]] += limiter.heldPull()[i];
    CHECK((held[0] - mass[0] * shiftA).norm() <= 1e-10);
    CHECK((held[1] - mass[1] * shiftB).norm() <= 1e-10);
    // Each half rigid: where its body put it.
    for (std::size_t i = 0; i < n; ++i) {
        const ContactPlanes::Carried& c = planes.carried[std::size_t(planes.carriedOf[i])];
        CHECK((x[i] - planes.carriedNow(c)).norm() <= 1e-12);
    }
}

namespace {
/// The carrier tests' body: 0.3 kg with an anisotropic, turned inertia, carrying five point
/// masses (0.01-0.2 kg) at levers drawn from rng within 0.5 m of its centre.
struct TestCarrier {
    double invMass = 1.0 / 0.3;
    Eigen::Matrix3d inertia, invInertia;
    std::vector<Vec3> levers;
    std::vector<double> masses;
};
TestCarrier testCarrier(Rng& rng) {
    TestCarrier c;
    const Eigen::Matrix3d R = Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized()).toRotationMatrix();
    c.inertia = R * Vec3(2e-3, 5e-3, 8e-3).asDiagonal() * R.transpose();
    c.invInertia = c.inertia.inverse();
    for (int k = 0; k < 5; ++k) {
        c.levers.push_back(
            Vec3(rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5)));
        c.masses.push_back(rng.uniform(0.01, 0.2));
    }
    return c;
}
} // namespace

TEST_CASE("a body and the point masses it carries answer an impulse as one rigid body",
          "[limiter][carrier]") {
    // carrierMatrices: a 0.3 kg body (an anisotropic, turned inertia) carrying five point
    // masses at random levers. An impulse (linear J, angular L about the centre) on the whole
    // moves it by mobility (J, L); the body takes share (J, L) itself and moves by W times
    // that, the same motion, and the rest moves the point masses with it: the linear momentum
    // of body and masses changes by J, their angular momentum about the centre by L.
    Rng rng(11);
    const TestCarrier body = testCarrier(rng);
    const double invMass = body.invMass;
    const Eigen::Matrix3d &inertia = body.inertia, &invInertia = body.invInertia;
    const std::vector<Vec3>& levers = body.levers;
    const std::vector<double>& masses = body.masses;
    const CarrierMatrices whole = carrierMatrices(invMass, invInertia, levers, masses);
    CHECK((whole.mobility - whole.mobility.transpose()).norm() <= 1e-12 * whole.mobility.norm());
    for (int trial = 0; trial < 4; ++trial) {
        Eigen::Matrix<double, 6, 1> impulse;
        for (int k = 0; k < 6; ++k)
            impulse[k] = rng.uniform(-1.0, 1.0);
        const Eigen::Matrix<double, 6, 1> motion = whole.mobility * impulse;
        const Eigen::Matrix<double, 6, 1> own = whole.share * impulse;
        const Vec3 dv = motion.head<3>(), dw = motion.tail<3>();
        // The body's own answer to its share is the whole's motion.
        CHECK((invMass * own.head<3>() - dv).norm() <= 1e-10 * (1.0 + dv.norm()));
        CHECK((invInertia * own.tail<3>() - dw).norm() <= 1e-10 * (1.0 + dw.norm()));
        // Momentum and angular momentum (about the centre) of body and masses.
        Vec3 p = dv / invMass, l = inertia * dw;
        for (std::size_t k = 0; k < levers.size(); ++k) {
            const Vec3 u = dv + dw.cross(levers[k]);
            p += masses[k] * u;
            l += levers[k].cross(masses[k] * u);
        }
        CHECK((p - impulse.head<3>()).norm() <= 1e-10);
        CHECK((l - impulse.tail<3>()).norm() <= 1e-10);
    }
    // Carrying nothing it is the body alone.
    const CarrierMatrices alone = carrierMatrices(invMass, invInertia, {}, {});
    CHECK((alone.share - Eigen::Matrix<double, 6, 6>::Identity()).norm() <= 1e-15);
    CHECK((alone.mobility.topLeftCorner<3, 3>() - invMass * Eigen::Matrix3d::Identity()).norm() <=
          1e-12);
    CHECK((alone.mobility.bottomRightCorner<3, 3>() - invInertia).norm() <= 1e-9);
}

TEST_CASE("a body in joints answers an impulse only as its joints let it", "[limiter][carrier]") {
    // constrainToJoints, against rigid-body mechanics. The carrier of the test above (a 0.3 kg
    // body and five point masses) on a hinge: a ball joint at p (three rows: the velocity of p
    // is zero) and two rows that stop its turn about the axes across a. Given an impulse
    // (J, L about the centre), the whole turns about the hinge at s = a . (L - p x J) / I_a
    // (I_a: the inertia about the hinge line, parallel axes: the body's a . I a, its mass and
    // every point mass at their distance from the line) and moves its centre at s (p x a).
    // A repeated row (two joints that say the same) changes nothing.
    Rng rng(12);
    const TestCarrier body = testCarrier(rng);
    const double invMass = body.invMass;
    const Eigen::Matrix3d &inertia = body.inertia, &invInertia = body.invInertia;
    const std::vector<Vec3>& levers = body.levers;
    const std::vector<double>& masses = body.masses;
    const Vec3 p(0.3, -0.1, 0.2), a = Vec3(0.2, 1.0, -0.4).normalized();
    const Vec3 b1 = a.unitOrthogonal(), b2 = a.cross(b1);
    using Row = Eigen::Matrix<double, 6, 1>;
    JointRows hinge;
    for (int k = 0; k < 3; ++k) {
        const Vec3 e = Vec3::Unit(k);
        Row r;
        r << e, p.cross(e); // e . (v + w x p)
        hinge.rows.push_back(r);
    }
    for (const Vec3& b : {b1, b2}) {
        Row r;
        r << Vec3::Zero(), b; // b . w
        hinge.rows.push_back(r);
    }
    JointRows repeated = hinge;
    repeated.rows.push_back(hinge.rows[0] + 2.0 * hinge.rows[3]);
    double Ia = a.dot(inertia * a);
    const auto across = [&](const Vec3& r) { // distance^2 of a point from the hinge line
        const Vec3 d = r - p;
        return (d - d.dot(a) * a).squaredNorm();
    };
    Ia += across(Vec3::Zero()) / invMass;
    for (std::size_t k = 0; k < levers.size(); ++k)
        Ia += masses[k] * across(levers[k]);
    for (const JointRows* joints : {&hinge, &repeated}) {
        CarrierMatrices whole = carrierMatrices(invMass, invInertia, levers, masses);
        constrainToJoints(whole, *joints);
        for (int trial = 0; trial < 4; ++trial) {
            Row f;
            for (int k = 0; k < 6; ++k)
                f[k] = rng.uniform(-1.0, 1.0);
            const Row u = whole.mobility * f;
            const double s = a.dot(f.tail<3>() - p.cross(f.head<3>())) / Ia;
            INFO(measured("turn rate %.9f against %.9f", a.dot(u.tail<3>()), s));
            CHECK((u.tail<3>() - s * a).norm() <= 1e-9 * (1.0 + std::abs(s)));
            CHECK((u.head<3>() - s * p.cross(a)).norm() <= 1e-9 * (1.0 + std::abs(s)));
            // The body's own share moves it the same way.
            const Row own = whole.share * f;
            CHECK((invMass * own.head<3>() - u.head<3>()).norm() <= 1e-9 * (1.0 + u.norm()));
            CHECK((invInertia * own.tail<3>() - u.tail<3>()).norm() <= 1e-9 * (1.0 + u.norm()));
        }
    }
    // A ball joint at p to a free body at its centre of mass (0.25 kg): the joint passes it
    // whatever it is pushed with, so the whole answers as if that mass were carried at p.
    JointRows ball;
    for (int k = 0; k < 3; ++k)
        ball.rows.push_back(hinge.rows[std::size_t(k)]);
    ball.give = Eigen::MatrixXd::Identity(3, 3) / 0.25; // J_o W_o J_o^T, J_o = -1 at its centre
    CarrierMatrices joined = carrierMatrices(invMass, invInertia, levers, masses);
    constrainToJoints(joined, ball);
    std::vector<Vec3> leversWith = levers;
    std::vector<double> massesWith = masses;
    leversWith.push_back(p);
    massesWith.push_back(0.25);
    const CarrierMatrices carried = carrierMatrices(invMass, invInertia, leversWith, massesWith);
    CHECK((joined.mobility - carried.mobility).norm() <= 1e-9 * carried.mobility.norm());
    // No rows: unchanged.
    CarrierMatrices free = carrierMatrices(invMass, invInertia, levers, masses);
    const CarrierMatrices before = free;
    constrainToJoints(free, JointRows{});
    CHECK(free.mobility == before.mobility);
    CHECK(free.share == before.share);
}

namespace {
/// A triangle plane's state in the tests below: the plane's triangle (the one around the
/// sheet's middle), its point's weights, and the point where `x` has it.
struct PlanedTriangle {
    Triangle corner;
    Vec3 beta;
    Vec3 point(const std::vector<Vec3>& x) const {
        return beta[0] * x[corner[0]] + beta[1] * x[corner[1]] + beta[2] * x[corner[2]];
    }
};
/// The triangle of planeSheet() nearest its middle, the point at weights (0.5, 0.3, 0.2), its
/// corners pushed `depth` along -z as a contact stage would (the least-mass-weighted move),
/// and the plane z <= that point's z (normal -z) set in `planes`.
PlanedTriangle pushTriangleDown(const PlaneSheet& sheet, double depth, std::vector<Vec3>& x,
                                ContactPlanes& planes) {
    const Vec3 middle(sheet.xMid, 3.0, 0.0);
    PlanedTriangle t{};
    double best = 1e9;
    for (const Triangle& tri : sheet.topo->triangles()) {
        const Vec3 c = (x[tri[0]] + x[tri[1]] + x[tri[2]]) / 3.0;
        if ((c - middle).norm() < best) {
            best = (c - middle).norm();
            t.corner = tri;
        }
    }
    t.beta = Vec3(0.5, 0.3, 0.2);
    double weight = 0.0;
    for (int k = 0; k < 3; ++k)
        weight += t.beta[k] * t.beta[k] * sheet.invMass[t.corner[k]];
    for (int k = 0; k < 3; ++k)
        x[t.corner[k]].z() -= t.beta[k] * sheet.invMass[t.corner[k]] * depth / weight;
    const Vec3 n(0, 0, -1);
    planes.addTriangle(t.corner, t.beta, n, n.dot(t.point(x)));
    return t;
}
} // namespace

TEST_CASE("a triangle plane keeps the triangle's point ahead of it in the walk, within the bound",
          "[limiter][contact]") {
    // The irregular sheet of the tests above, pinned on its border. A body smaller than a
    // triangle pushed one triangle's point 1.5 down (ContactPlanes::TrianglePlane: no corner
    // touches it): the springs around it are stretched far beyond the bound. The walk must
    // reach the bound with the point still where the body holds it (the sheet drawn down
    // around it, a cone), the plane's push along its normal only.
    const PlaneSheet sheet = planeSheet();
    const auto& topo = sheet.topo;
    const std::size_t n = topo->particleCount();
    std::vector<double> invMass = sheet.invMass;
    for (std::size_t i = 0; i < n; ++i) {
        const Vec3& p = topo->restPositions()[i];
        if (p.x() == 0.0 || p.y() == 0.0 || p.x() == 8.0 || p.y() == 6.0) invMass[i] = 0.0;
    }
    PlaneSheet pinned = sheet;
    pinned.invMass = invMass;
    LimiterSettings s = limiterSettings();
    s.longRangeAttachments = false;
    std::vector<Vec3> x = topo->restPositions();
    ContactPlanes planes;
    planes.reset(n);
    const PlanedTriangle t = pushTriangleDown(pinned, 1.5, x, planes);
    const double held = t.point(x).z();
    const std::vector<Vec3> before = x;
    const auto st = relimitEverything(*topo, invMass, s, x, planes);
    INFO("waves " << st.rounds << ", work " << st.work << ", point z " << t.point(x).z()
                  << " held at " << held << ", push " << planes.triangles[0].push.transpose());
    CHECK(maxSpringStrain(*topo, before) > 0.3);
    CHECK_FALSE(st.capHit);
    CHECK(maxSpringStrain(*topo, x) <= s.maxStrain + s.tolerance + 1e-12);
    CHECK(t.point(x).z() <= held + 1e-12);
    // The springs pulled the triangle back: the plane pushed, along -z only.
    const Vec3 push = planes.triangles[0].push;
    CHECK(push.z() < -1e-3);
    CHECK(push.head<2>().norm() <= 1e-12);
    // And the sheet around it came down (not the corners alone up to the bound's reach).
    int drawn = 0;
    for (std::size_t i = 0; i < n; ++i)
        drawn += x[i].z() < -0.1;
    CHECK(drawn > 6);
}

TEST_CASE("a small body that gives way takes what its triangle plane pushes, momentum conserved",
          "[limiter][contact]") {
    // The same triangle of the free sheet pushed down by a free body (a mover: a small ball)
    // above it. The walk must end within the bound with the point ahead of the plane where the
    // body went, and the body's momentum change M shift must be the opposite of the cloth's,
    // sum m dx, which is what the plane pushed (its only outside impulse). A light body gives
    // way more than a heavy one.
    const PlaneSheet sheet = planeSheet();
    const auto& topo = sheet.topo;
    const std::size_t n = topo->particleCount();
    double clothMass = 0.0;
    for (double m : sheet.mass)
        clothMass += m;
    LimiterSettings s = limiterSettings();
    s.longRangeAttachments = false;
    double shiftOf[2] = {0.0, 0.0};
    for (int heavy = 0; heavy < 2; ++heavy) {
        const double bodyMass = heavy ? 100.0 * clothMass : 0.01 * clothMass;
        std::vector<Vec3> x = topo->restPositions();
        ContactPlanes planes;
        planes.reset(n);
        const PlanedTriangle t = pushTriangleDown(sheet, 1.5, x, planes);
        const Vec3 centre = t.point(x) + Vec3(0, 0, 0.3);
        planes.movers.push_back(ContactPlanes::Mover{
            1.0 / bodyMass, Eigen::Matrix3d::Identity() / (0.4 * bodyMass * 0.09), centre});
        planes.triangleMoveWith(0, 0, t.point(x) - centre);
        const std::vector<Vec3> before = x;
        const auto st = relimitEverything(*topo, sheet.invMass, s, x, planes);
        const ContactPlanes::Mover& body = planes.movers[0];
        const ContactPlanes::TrianglePlane& plane = planes.triangles[0];
        INFO("body mass " << bodyMass << " kg, waves " << st.rounds << ", shift "
                          << body.shift.transpose() << ", push " << plane.push.transpose());
        CHECK_FALSE(st.capHit);
        CHECK(maxSpringStrain(*topo, x) <= s.maxStrain + s.tolerance + 1e-12);
        CHECK(plane.normal.dot(t.point(x)) >= planes.triangleOffsetNow(plane) - 1e-12);
        Vec3 dp = Vec3::Zero();
        for (std::size_t i = 0; i < n; ++i)
            dp += sheet.mass[i] * (x[i] - before[i]);
        CHECK(plane.push.norm() > 1e-3);
        CHECK((dp - plane.push).norm() <= 1e-10);
        CHECK((dp + bodyMass * body.shift).norm() <= 1e-10 * (1.0 + dp.norm()));
        CHECK(body.shift.z() > 0.0); // pushed back up, away from the cloth
        shiftOf[heavy] = body.shift.norm();
    }
    CHECK(shiftOf[0] > 100.0 * shiftOf[1]);
}

TEST_CASE("maxSpringStrain and meanSpringStrain of a uniform stretch", "[limiter]") {
    const auto topo = ClothTopology::build(irregularMesh(4, 3, 8));
    std::vector<Vec3> x;
    for (const Vec3& p : topo->restPositions())
        x.push_back(1.2 * p);
    CHECK(maxSpringStrain(*topo, x) == Approx(0.2).epsilon(1e-12));
    CHECK(meanSpringStrain(*topo, x) == Approx(0.2).epsilon(1e-12));
}

TEST_CASE("Velocities stay consistent with the limiter's corrections", "[limiter][velocity]") {
    // A cloth at rest, overstretched by 50 % everywhere, one step: the limiter pulls particles
    // back and the step must turn those displacements into velocities.
    SheetSpec spec;
    spec.rows = 4;
    spec.cols = 5;
    ClothSettings s;
    s.relativeDamping = 0.0; // the motion measured here is undamped or damped by C_d only
    s.particleMass = 0.2;
    s.springStiffness = 3.0;
    s.gravity = Vec3::Zero();
    s.limiter.kind = LimiterKind::StressOrdered;
    const auto topo = ClothTopology::build(makeSheet(spec));
    const double dt = 0.01;

    for (LimiterKind lk : {LimiterKind::StressOrdered, LimiterKind::Provot}) {
        s.limiter.kind = lk;
        SECTION(std::string("symplectic Euler, ") + toString(lk)) {
            // v1 = v0 + a dt, x1 = x0 + v1 dt, then the limiter moves x1 by d and adds d / dt:
            // from rest, v1 = (x1 - x0) / dt exactly (displacement over the step divided by dt).
            s.integrator = IntegratorKind::SymplecticEuler;
            Cloth cloth(topo, s);
            cloth.pin(0);
            for (Index i = 0; i < cloth.particleCount(); ++i)
                cloth.setPosition(i, 1.5 * topo->restPositions()[i]);
            const Vec3List before = cloth.positions();
            cloth.step(dt);
            REQUIRE(cloth.lastLimiterStats().corrections > 0);
            // The documented contract: within the limit, or out of rounds.
            const bool within = cloth.maxStrain() <= 0.1 + s.limiter.tolerance + 1e-12;
            CHECK((within || cloth.lastLimiterStats().capHit));
            for (Index i = 0; i < cloth.particleCount(); ++i) {
                const Vec3 expected = (cloth.positions()[i] - before[i]) / dt;
                // Displacements ~5 m divided by 0.01 s: rounding 1e-16 * 500 m/s relative.
                CHECK((cloth.velocities()[i] - expected).norm() < 1e-10 * (1.0 + expected.norm()));
            }
        }
        SECTION(std::string("Velocity-Verlet, ") + toString(lk)) {
            // VV from rest: v = (x1 - x0) / dt + f(x1) dt / (2 m) (the closing half kick).
            s.integrator = IntegratorKind::VelocityVerlet;
            Cloth cloth(topo, s);
            cloth.pin(0);
            for (Index i = 0; i < cloth.particleCount(); ++i)
                cloth.setPosition(i, 1.5 * topo->restPositions()[i]);
            const Vec3List before = cloth.positions();
            cloth.step(dt);
            REQUIRE(cloth.lastLimiterStats().corrections > 0);
            for (Index i = 1; i < cloth.particleCount(); ++i) {
                const Vec3 expected = (cloth.positions()[i] - before[i]) / dt +
                                      cloth.forces()[i] * (dt / (2.0 * cloth.masses()[i]));
                CHECK((cloth.velocities()[i] - expected).norm() < 1e-10 * (1.0 + expected.norm()));
            }
            CHECK(cloth.velocities()[0] == Vec3::Zero());
        }
    }
}

TEST_CASE("Pins hold, kinematic particles follow their paths", "[pins]") {
    SheetSpec spec;
    spec.rows = 6;
    spec.cols = 6;
    spec.spacing = 0.1;
    ClothSettings s;
    s.relativeDamping = 0.0; // the motion measured here is undamped or damped by C_d only
    s.particleMass = 0.01;
    s.springStiffness = 50.0;
    s.damping = 0.01;
    const auto topo = ClothTopology::build(makeSheet(spec));

    SECTION("pin at a given position, unpin") {
        Cloth cloth(topo, s);
        const Vec3 where(0.05, 0.2, -0.1);
        cloth.pin(3, where);
        cloth.pin(0);
        const Vec3 p0 = cloth.positions()[0];
        CHECK(cloth.isPinned(3));
        CHECK(cloth.inverseMasses()[3] == 0.0);
        for (int n = 0; n < 100; ++n) {
            cloth.step(0.002);
            REQUIRE(cloth.positions()[3] == where);
            REQUIRE(cloth.positions()[0] == p0);
        }
        cloth.setVelocity(3, Vec3(1, 1, 1)); // a pinned particle keeps its (zero) velocity
        CHECK(cloth.velocities()[3] == Vec3::Zero());
        cloth.unpin(3);
        CHECK(!cloth.isPinned(3));
        CHECK(cloth.inverseMasses()[3] == Approx(1.0 / 0.01));
        const double y = cloth.positions()[3].y();
        for (int n = 0; n < 50; ++n)
            cloth.step(0.002);
        CHECK(cloth.positions()[3].y() < y); // free again: it falls (or is pulled) down
    }
    SECTION("kinematic particles follow a path") {
        Cloth cloth(topo, s);
        const Vec3 base = topo->restPositions()[5];
        const double w = 3.0, a = 0.05;
        auto path = [=](double t) {
            return Vec3(base + Vec3(a * std::sin(w * t), 0.0, a * (1 - std::cos(w * t))));
        };
        auto speed = [=](double t) {
            return Vec3(a * w * std::cos(w * t), 0.0, a * w * std::sin(w * t));
        };
        cloth.setKinematic(5, path);
        cloth.pin(0);
        CHECK(cloth.isPinned(5));
        const double dt = 0.002;
        for (int n = 0; n < 300; ++n) {
            cloth.step(dt);
            const double t = cloth.time();
            REQUIRE((cloth.positions()[5] - path(t)).norm() < 1e-12); // it is put on the path
            // Its velocity is the path's, up to the O(dt) of a one-step difference: per
            // component |v - x'(t)| <= dt/2 max |x_c''| = dt/2 a w^2, so sqrt(2) times that.
            REQUIRE((cloth.velocities()[5] - speed(t)).norm() <=
                    0.5 * dt * a * w * w * std::sqrt(2.0) + 1e-12);
        }
        CHECK(cloth.time() == Approx(300 * dt).epsilon(1e-12));
        CHECK(cloth.stepCount() == 300u);
        // The cloth was dragged along: the neighbour of the driven corner moved sideways.
        CHECK(std::abs(cloth.positions()[4].z() - topo->restPositions()[4].z()) > 1e-4);
    }
    SECTION("kinematic targets: a straight move at constant speed, then held; set by data") {
        Cloth cloth(topo, s);
        const Vec3 a = topo->restPositions()[5];
        const Vec3 b = a + Vec3(0.03, -0.02, 0.04);
        const double dt = 0.002, arrival = 20 * dt;
        cloth.setKinematicTarget(5, b, arrival);
        CHECK(cloth.isPinned(5));
        CHECK(cloth.inverseMasses()[5] == 0.0);
        for (int n = 1; n <= 30; ++n) {
            cloth.stepPart(dt / 2, 2); // sub-steps of a caller's step interpolate too
            cloth.stepPart(dt / 2, 2);
            const double f = std::min(1.0, n * dt / arrival);
            INFO("step " << n);
            REQUIRE((cloth.positions()[5] - (a + f * (b - a))).norm() <= 1e-12);
            // Constant speed (b - a) / arrival on the way (exactly: the path is straight), rest
            // after the arrival.
            const Vec3 v = n * dt <= arrival + 1e-12 ? Vec3((b - a) / arrival) : Vec3::Zero();
            REQUIRE((cloth.velocities()[5] - v).norm() <= 1e-9);
        }
        // A new target starts from where the particle is; an arrival now is a jump.
        const Vec3 c = b + Vec3(0.0, 0.05, 0.0);
        cloth.setKinematicTarget(5, c, cloth.time());
        CHECK(cloth.positions()[5] == c);
        cloth.step(dt);
        CHECK(cloth.positions()[5] == c);
        REQUIRE_DRAPE_ERROR(cloth.setKinematicTarget(5, Vec3(NAN, 0, 0), 1.0), ErrorCode::NonFinite,
                            "kinematic target of particle 5");
        REQUIRE_DRAPE_ERROR(cloth.setKinematicTarget(5, c, INFINITY), ErrorCode::InvalidArgument,
                            "arrival time");
        REQUIRE_DRAPE_ERROR(cloth.setKinematicTarget(99, c, 1.0), ErrorCode::IndexOutOfRange,
                            "setKinematicTarget");
        cloth.unpin(5);
        CHECK(!cloth.isPinned(5));
    }
}

namespace {
struct PinCase {
    const char* name;
    Index rows, cols;
    double spacing, mass, k, dt;
    std::vector<std::pair<Index, Index>> pins; ///< (row, col)
    bool pinTopRow = false;
};
} // namespace

// The bound is a promise on any sheet and pin set, not only Experiment I: every step ends
// within (1 + maxStrain + tolerance) L0 with no safety-cap hit, and the limiter is no energy
// source: every cloth starts at rest, so its mechanical energy (kinetic + gravitational +
// spring) may never exceed the starting value by more than 0.1 % of the weight times the
// sheet's height (Velocity-Verlet's own bounded energy oscillation on the stiff undamped
// sheet is far below that). The sum of step-to-step rises is printed; on undamped sheets it
// counts the integrator's oscillation too, so it is the benchmark's figure, not a bar here.
TEST_CASE("The strain bound holds for any pin set and stiffness", "[limiter][bound][energy]") {
    const std::vector<PinCase> cases = {
        {"20 x 20, k 2, two corners", 20, 20, 0.05, 0.005, 2.0, 1.0 / 60.0, {{0, 0}, {0, 19}}},
        {"20 x 20, k 2, one corner", 20, 20, 0.05, 0.005, 2.0, 1.0 / 60.0, {{0, 0}}},
        {"20 x 20, k 2, pinned top row", 20, 20, 0.05, 0.005, 2.0, 1.0 / 60.0, {}, true},
        {"2 x 30 strip, k 2, top pair", 30, 2, 0.05, 0.005, 2.0, 1.0 / 60.0, {{0, 0}, {0, 1}}},
        {"25 x 25, k 2000, two corners",
         25,
         25,
         0.04,
         0.01,
         2000.0,
         1.0 / 1000.0,
         {{0, 0}, {0, 24}}},
        {"35 x 35 paper sheet, one corner", 35, 35, 10.0, 0.5, 20.0, 0.01, {{0, 0}}},
    };
    for (const PinCase& pc : cases) {
        SheetSpec spec;
        spec.rows = pc.rows;
        spec.cols = pc.cols;
        spec.spacing = pc.spacing;
        spec.vAxis = -Vec3::UnitY();
        ClothSettings s;
        s.relativeDamping = 0.0; // the motion measured here is undamped or damped by C_d only
        s.particleMass = pc.mass;
        s.springStiffness = pc.k;
        Cloth cloth(ClothTopology::build(makeSheet(spec)), s);
        for (const auto& p : pc.pins)
            cloth.pin(sheetIndex(spec, p.first, p.second));
        if (pc.pinTopRow)
            for (Index c = 0; c < pc.cols; ++c)
                cloth.pin(sheetIndex(spec, 0, c));
        auto energy = [&] { return mechanicalEnergy(cloth); };
        const double e0 = energy();
        double totalMass = 0.0;
        for (double m : cloth.masses())
            totalMass += m;
        const double scale = totalMass * 9.81 * pc.spacing * (pc.rows - 1);
        double e = e0, rise = 0.0, dissipated = 0.0, worst = 0.0, work = 0.0, excess = 0.0;
        const int steps = 600;
        for (int n = 0; n < steps; ++n) {
            cloth.step(pc.dt);
            worst = std::max(worst, cloth.maxStrain());
            work += static_cast<double>(cloth.lastLimiterStats().work) /
                    static_cast<double>(cloth.topology().springCount());
            const double e2 = energy();
            (e2 > e ? rise : dissipated) += std::abs(e2 - e);
            e = e2;
            excess = std::max(excess, e2 - e0);
        }
        INFO(measured("%s: peak strain %.6f, energy above the start %.3g J (scale %.3g J), "
                      "step-to-step rises %.3g J of %.3g J dissipated, work %.2f sweeps/step, "
                      "cap hits %llu",
                      pc.name, worst, excess, scale, rise, dissipated, work / steps,
                      static_cast<unsigned long long>(cloth.limiterCapHits())));
        INFO(pc.name);
        CHECK(worst <= 0.1 + s.limiter.tolerance + 1e-12);
        CHECK(cloth.limiterCapHits() == 0);
        CHECK(excess <= 1e-3 * scale);
    }
}

TEST_CASE("With the limiter on, the trajectory converges as dt halves", "[limiter][convergence]") {
    // Experiment I's sheet (the paper's units, the shipped damping) with the default limiter
    // (stress-ordered, warm start, long-range attachments), hanging from its two top corners,
    // run to t = 2 s at dt = 0.01, 0.005, ... 0.000625: the RMS distance between the final
    // meshes of dt and dt/2 must fall by a clear factor at every halving. With a fixed band a
    // correction's jump (band L0 / dt) grows as dt shrinks, and this distance grew from 0.003
    // to 0.04 grid spacings over the same halvings.
    SheetSpec spec;
    spec.rows = 35;
    spec.cols = 35;
    spec.spacing = 10.0;
    spec.uAxis = Vec3::UnitX();
    spec.vAxis = -Vec3::UnitY();
    auto finalMesh = [&](double dt) {
        ClothSettings s;
        s.relativeDamping = 0.0; // the motion measured here is undamped or damped by C_d only
        s.particleMass = 0.5;
        s.springStiffness = 20.0;
        s.gravity = Vec3(0.0, -9.8, 0.0);
        s.damping = 0.05;
        s.springDamping = 0.15;
        Cloth cloth(ClothTopology::build(makeSheet(spec)), s);
        cloth.pin(sheetIndex(spec, 0, 0));
        cloth.pin(sheetIndex(spec, 0, spec.cols - 1));
        const int steps = static_cast<int>(std::lround(2.0 / dt));
        double worst = 0.0;
        for (int n = 0; n < steps; ++n) {
            cloth.step(dt);
            worst = std::max(worst, cloth.maxStrain());
        }
        CHECK(worst <= 0.1 + s.limiter.tolerance + 1e-12);
        CHECK(cloth.limiterCapHits() == 0);
        return cloth.positions();
    };
    std::vector<std::vector<Vec3>> meshes;
    for (double dt = 0.01; dt > 0.0006; dt /= 2.0)
        meshes.push_back(finalMesh(dt));
    std::vector<double> err;
    for (std::size_t k = 0; k + 1 < meshes.size(); ++k) {
        double sum = 0.0;
        for (std::size_t i = 0; i < meshes[k].size(); ++i)
            sum += (meshes[k][i] - meshes[k + 1][i]).squaredNorm();
        err.push_back(std::sqrt(sum / static_cast<double>(meshes[k].size())) / spec.spacing);
    }
    INFO(measured("RMS distance dt vs dt/2 [spacings], dt = 0.01, 0.005, 0.0025, 0.00125: "
                  "%.3g %.3g %.3g %.3g",
                  err[0], err[1], err[2], err[3]));
    for (std::size_t k = 0; k + 1 < err.size(); ++k)
        CHECK(err[k + 1] < 0.7 * err[k]);
}

TEST_CASE("a mover counted lighter takes more of a push, the rest of it held, never lighter "
          "than kLightest particles",
          "[limiter][contacts]") {
    // One plane of a 1 kg body through its centre (lever along the normal: its give there is
    // 1/M), pushing a particle of 1 g out by 1 mm. At its own mass the body takes
    // w_body / (w + w_body) of the overlap; counted lighter by L it takes L w_body / (w + L
    // w_body), but never more than the share of a body of kLightest particles. What the
    // particle moves is its own momentum; the body's extra share is held (the pins').
    auto run = [](double lighter, double& own, double& bodyMoved, Vec3& held) {
        ContactPlanes planes;
        planes.reset(1);
        const Vec3 n = Vec3::UnitY();
        const Vec3 centre(0.0, -0.1, 0.0);
        planes.movers.push_back(ContactPlanes::Mover{1.0, Eigen::Matrix3d::Identity(), centre});
        const auto k = std::size_t(planes.set(0, n, 0.0));
        planes.moveWith(k, 0, Vec3(0.0, 0.1, 0.0)); // straight above the centre
        const double w = 1000.0, below = 1e-3;
        own = planes.giveWay(k, below, w, std::numeric_limits<double>::infinity(), lighter);
        bodyMoved = -planes.movers[0].moved(n, planes.lever[k]);
        held = planes.held[k];
        CHECK(own + bodyMoved == Approx(below).epsilon(1e-12)); // the overlap is gone
    };
    double own = 0.0, moved = 0.0;
    Vec3 held;
    run(1.0, own, moved, held);
    CHECK(moved == Approx(1e-3 * 1.0 / 1001.0).epsilon(1e-9));
    CHECK(held.norm() == 0.0);
    const double ownAtMass = own;
    run(50.0, own, moved, held);
    CHECK(moved == Approx(1e-3 * 50.0 / 1050.0).epsilon(1e-9));
    // The particle's own momentum (own / w) plus what is held is what moved the body (its
    // mass times its move): the body's extra share came from the pins.
    CHECK(own / 1000.0 + held.y() == Approx(1.0 * moved).epsilon(1e-9));
    CHECK(own < ownAtMass);
    // At most kLightest particles' worth of give: w / kLightest = 100 here, so a factor of
    // 1e6 counts the body as 1/100 kg.
    run(1e6, own, moved, held);
    const double g = 1000.0 / ContactPlanes::kLightest;
    CHECK(moved == Approx(1e-3 * g / (1000.0 + g)).epsilon(1e-9));
}

TEST_CASE("a cloth held far beyond its reach and let go gains no energy (ClothState::overBound)",
          "[limiter][energy]") {
    // A 21 x 21 sheet hung from two corners; its middle particle is pulled 1 m out of the
    // sheet at `speed` (Cloth::setKinematicTarget, a mouse drag) and held there for a second:
    // the limiter cannot meet its bound (the held particles are too far apart) and stops at
    // its cap. Then the particle is let go. Bringing the stretched cloth back within the bound
    // is a repair of positions, not a motion: the mechanical energy never rises above what it
    // was at release. (Before the repair walk, the whole correction became velocity: 464 J
    // from 27 J, particles at 148 m/s.)
    for (const double speed : {2.0, 10.0, 40.0}) {
        auto owned = settledSheet21({0, 20});
        Cloth& cloth = *owned;
        const Index p = 10 * 21 + 10;
        const Vec3 grab = cloth.positions()[p];
        cloth.setKinematicTarget(p, grab + Vec3(0, 0, 1.0), cloth.time() + 1.0 / speed);
        for (int f = 0; f < 60; ++f)
            cloth.step(1.0 / 60.0);
        REQUIRE(cloth.state().overBound);
        REQUIRE(cloth.maxStrain() > 1.0); // far beyond the bound while held
        const double atRelease = mechanicalEnergy(cloth);
        cloth.unpin(p);
        double highest = -1e300, fastest = 0.0;
        for (int f = 0; f < 60; ++f) {
            cloth.step(1.0 / 60.0);
            highest = std::max(highest, mechanicalEnergy(cloth));
            for (const Vec3& v : cloth.velocities())
                fastest = std::max(fastest, v.norm());
        }
        INFO(measured("pulled at %.0f m/s: energy at release %.3f J, highest after %.3f J, "
                      "fastest particle %.2f m/s",
                      speed, atRelease, highest, fastest));
        CHECK(highest <= atRelease);
        CHECK(!cloth.state().overBound);
        CHECK(cloth.maxStrain() <= 0.101);
    }
}

TEST_CASE("pins teleported with pin(i, position) give the cloth no speed of the jump",
          "[limiter][energy]") {
    // A 21 x 21 curtain (1 m) hung from its top row at rest; every pin is put 0.5 m (and 1 m)
    // to the side in one call each. A teleport is not a motion: the cloth is brought within
    // its bound as positions, from rest. What moves it then is its own elasticity (particle
    // speeds up to the stretch wave speed c times the strain, below c) and its weight (at
    // most sqrt(2 g H) falling its height H = 1 m), and from the end of the teleport's frame
    // on nothing adds energy. (Before, the jump became velocity: 133 m/s and 186 J.)
    for (const double jump : {0.5, 1.0}) {
        std::vector<Index> topRow(21);
        for (Index c = 0; c < 21; ++c)
            topRow[c] = c;
        auto owned = settledSheet21(topRow);
        Cloth& cloth = *owned;
        for (Index c = 0; c < 21; ++c)
            cloth.pin(c, cloth.positions()[c] + Vec3(jump, 0, 0));
        CHECK(cloth.state().overBound);
        const double g = cloth.settings().gravity.norm();
        const double speedBound = cloth.settings().stretchWaveSpeed + std::sqrt(2.0 * g * 1.0);
        double fastest = 0.0, previous = 0.0, rise = 0.0;
        for (int f = 0; f < 60; ++f) {
            cloth.step(1.0 / 60.0);
            for (const Vec3& v : cloth.velocities())
                fastest = std::max(fastest, v.norm());
            const double e = mechanicalEnergy(cloth);
            if (f > 0) rise = std::max(rise, e - previous);
            previous = e;
        }
        INFO(measured("pins moved %.1f m: fastest particle %.2f m/s (bound %.2f), largest "
                      "energy rise in a frame after the first %.3g J, cap hits %llu",
                      jump, fastest, speedBound, rise,
                      static_cast<unsigned long long>(cloth.limiterCapHits())));
        CHECK(fastest <= speedBound);
        CHECK(rise <= 1e-9);
        CHECK(cloth.limiterCapHits() == 0);
        CHECK(cloth.maxStrain() <= 0.101);
        // The curtain came along: the middle of its lowest row is past half the jump.
        CHECK(cloth.positions()[20 * 21 + 10].x() > 0.5 * jump);
    }
}

TEST_CASE("a limiter tolerance of 0 is the narrowest band, not a walk after rounding errors",
          "[limiter][bound]") {
    // A curtain whose rod is moved 5 cm sideways while it hangs: every walk ends with springs
    // set to the limit, which double arithmetic leaves up to a few 1e-16 beyond it. With no band
    // at all the walk queued them again until its cap, in most steps.
    SheetSpec sheet;
    sheet.rows = 21;
    sheet.cols = 21;
    sheet.spacing = 0.05;
    sheet.origin = {-0.5, 2.0, 0.0};
    sheet.vAxis = -Vec3::UnitY();
    ClothSettings s;
    s.limiter.tolerance = 0.0;
    Cloth cloth(ClothTopology::build(makeSheet(sheet)), s);
    for (Index i = 0; i < 21; ++i)
        cloth.pin(i);
    double worst = 0.0;
    for (int f = 0; f < 60; ++f) {
        if (f == 20)
            for (Index i = 0; i < 21; ++i)
                cloth.pin(i, cloth.positions()[i] + Vec3(0.05, 0.0, 0.0));
        cloth.step(1.0 / 60.0);
        worst = std::max(worst, cloth.maxStrain());
    }
    CHECK(cloth.limiterCapHits() == 0);
    CHECK(worst <= s.limiter.maxStrain + kMinimumLimiterBand + 1e-12);
}
