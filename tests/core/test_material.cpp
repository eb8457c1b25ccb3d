// Material tests: the stiffness rule (M1) of material.hpp (units, linearity, refinement
// invariance, E h / E h/2 on grid edges / diagonals, the energy equivalence 1.5 E h eps^2 A)
// and the particle masses (uniform M/n, area-lumped rho h A/3 per corner, Cloth's choice).
#include "helpers.hpp"

#include "drape/cloth.hpp"
#include "drape/forces.hpp"
#include "drape/material.hpp"
#include "measured.hpp"

#include <limits>
#include <memory>
#include <string>

using namespace drape;
using namespace drape_test;

namespace {

constexpr double kE = 1.2e10;  // PET, Pa
constexpr double kH = 2.5e-4;  // m
constexpr double kRho = 1.3e3; // kg/m^3

/// Number of triangles using each spring, in spring order.
std::vector<int> trianglesPerSpring(const ClothTopology& topo) {
    const auto uses = edgeUses(meshOf(topo));
    std::vector<int> n;
    for (const Spring& s : topo.springs())
        n.push_back(uses.at({s.a, s.b}));
    return n;
}

/// Positions after the affine map x -> c + F (x - c).
Vec3List deform(const ClothTopology& topo, const Eigen::Matrix3d& F, const Vec3& c) {
    Vec3List x;
    for (const Vec3& p : topo.restPositions())
        x.push_back(c + F * (p - c));
    return x;
}

} // namespace

TEST_CASE("Stiffness (M1) on a grid: E h on grid edges, E h / 2 on diagonals", "[material]") {
    SheetSpec spec;
    spec.rows = 6;
    spec.cols = 7;
    spec.spacing = 0.01; // 1 cm
    const auto topo = ClothTopology::build(makeSheet(spec));
    const auto k = springStiffnessFromMaterial(*topo, kE, kH);
    const auto tri = trianglesPerSpring(*topo);
    const double eh = kE * kH; // Pa * m = N/m: 3e6 N/m
    for (std::size_t s = 0; s < k.size(); ++s) {
        const bool diagonal = topo->springs()[s].restLength > 1.2 * spec.spacing;
        INFO("spring " << s << " diagonal " << diagonal << " triangles " << tri[s]);
        // (M1) is a ratio of areas to squared lengths of O(1e-4): 1e-12 relative is rounding.
        if (diagonal) {
            CHECK(tri[s] == 2);
            CHECK(k[s] == Approx(eh / 2).epsilon(1e-12));
        } else if (tri[s] == 2) {
            CHECK(k[s] == Approx(eh).epsilon(1e-12)); // interior grid edge
        } else {
            CHECK(k[s] == Approx(eh / 2).epsilon(1e-12)); // border edge: one triangle
        }
    }
}

TEST_CASE("Stiffness (M1) is linear in E and h", "[material]") {
    const auto topo = ClothTopology::build(irregularMesh(5, 4, 9));
    const auto k1 = springStiffnessFromMaterial(*topo, kE, kH);
    const auto k2 = springStiffnessFromMaterial(*topo, 3.0 * kE, kH);
    const auto k3 = springStiffnessFromMaterial(*topo, kE, 0.5 * kH);
    for (std::size_t s = 0; s < k1.size(); ++s) {
        CHECK(k1[s] > 0.0);
        CHECK(k2[s] == Approx(3.0 * k1[s]).epsilon(1e-14));
        CHECK(k3[s] == Approx(0.5 * k1[s]).epsilon(1e-14));
    }
}

TEST_CASE("Stiffness (M1) does not change under uniform refinement", "[material]") {
    // The same 0.8 m x 0.8 m square as 4 x 4 cells and as 8 x 8 cells (both with equal numbers
    // of the two diagonal directions).
    SheetSpec coarse, fine;
    coarse.rows = coarse.cols = 5;
    coarse.spacing = 0.2;
    fine.rows = fine.cols = 9;
    fine.spacing = 0.1;
    const auto tc = ClothTopology::build(makeSheet(coarse));
    const auto tf = ClothTopology::build(makeSheet(fine));
    const auto kc = springStiffnessFromMaterial(*tc, kE, kH);
    const auto kf = springStiffnessFromMaterial(*tf, kE, kH);
    // Springs do not get stiffer as they get shorter (a 2D network's stiffness is scale-free).
    CHECK(*std::max_element(kc.begin(), kc.end()) ==
          Approx(*std::max_element(kf.begin(), kf.end())).epsilon(1e-12));
    CHECK(*std::min_element(kc.begin(), kc.end()) ==
          Approx(*std::min_element(kf.begin(), kf.end())).epsilon(1e-12));

    // The sheet's response is the same: energy of a uniaxial stretch, an equibiaxial stretch
    // and a simple shear (small, so the two sheets see the same affine strain per triangle).
    const double eps = 1e-3;
    Eigen::Matrix3d uni = Eigen::Matrix3d::Identity(), shear = Eigen::Matrix3d::Identity();
    uni(0, 0) += eps;
    shear(0, 1) = eps;
    const Eigen::Matrix3d bi = (1.0 + eps) * Eigen::Matrix3d::Identity();
    for (const Eigen::Matrix3d& F : {uni, bi, shear}) {
        const double ec = springEnergy(tc->springs(), kc, deform(*tc, F, Vec3::Zero()));
        const double ef = springEnergy(tf->springs(), kf, deform(*tf, F, Vec3::Zero()));
        // Per-triangle energies are identical for each triangle orientation and both sheets
        // have the same mix, so only rounding differs (l - L0 carries ~1e-16/eps = 1e-13).
        CHECK(ec > 0.0);
        CHECK(ef == Approx(ec).epsilon(1e-9));
    }
}

TEST_CASE("Energy equivalence: equibiaxial stretch stores 1.5 E h eps^2 A", "[material]") {
    const double eps = 1e-3;
    const Eigen::Matrix3d F = (1.0 + eps) * Eigen::Matrix3d::Identity();
    struct Case {
        const char* name;
        TriangleMesh mesh;
    };
    SheetSpec sheet;
    sheet.rows = 8;
    sheet.cols = 5;
    sheet.spacing = 0.05;
    std::vector<Case> cases{{"grid sheet", makeSheet(sheet)},
                            {"irregular flat mesh", irregularMesh(6, 5, 21)},
                            {"irregular curved mesh", irregularMesh(5, 7, 5, true)},
                            {"tube", tubeMesh(4, 10)}};
    for (const auto& c : cases) {
        INFO(c.name);
        const auto topo = ClothTopology::build(c.mesh);
        const auto k = springStiffnessFromMaterial(*topo, kE, kH);
        const double area = topo->totalRestArea();
        // Uniform scaling about any centre stretches every spring by exactly eps.
        const double energy =
            springEnergy(topo->springs(), k, deform(*topo, F, Vec3(0.3, -0.2, 0.1)));
        // Exact identity of (M1); l - L0 = eps L0 is computed with a relative rounding error
        // of ~1e-16/eps = 1e-13, so 1e-9 is generous.
        CHECK(energy == Approx(1.5 * kE * kH * eps * eps * area).epsilon(1e-9));
    }
}

TEST_CASE("Masses: uniform M/n and area-lumped rho h A", "[material][mass]") {
    const auto topo = ClothTopology::build(irregularMesh(6, 4, 17, true));
    const double A = topo->totalRestArea();
    // Independent area: sum of the triangle areas of the input mesh.
    const TriangleMesh m = meshOf(*topo);
    double area = 0.0;
    for (std::size_t t = 0; t < m.triangles.size(); ++t)
        area += triangleArea(m, t);
    CHECK(A == Approx(area).epsilon(1e-12));

    SECTION("uniform") {
        const double M = 2.5;
        const auto masses = uniformMasses(*topo, M);
        REQUIRE(masses.size() == topo->particleCount());
        double sum = 0.0;
        for (double mi : masses) {
            CHECK(mi == Approx(M / static_cast<double>(masses.size())).epsilon(1e-15));
            sum += mi;
        }
        CHECK(sum == Approx(M).epsilon(1e-12)); // n additions: n * 1e-16
    }
    SECTION("area-lumped") {
        const auto masses = areaLumpedMasses(*topo, kRho, kH);
        double sum = 0.0;
        for (double mi : masses) {
            CHECK(mi > 0.0);
            sum += mi;
        }
        CHECK(sum == Approx(kRho * kH * A).epsilon(1e-12));
        // A particle's mass is a third of its triangles' mass.
        std::vector<double> expected(topo->particleCount(), 0.0);
        for (std::size_t t = 0; t < m.triangles.size(); ++t)
            for (Index v : m.triangles[t])
                expected[v] += kRho * kH * triangleArea(m, t) / 3.0;
        for (std::size_t i = 0; i < masses.size(); ++i)
            CHECK(masses[i] == Approx(expected[i]).epsilon(1e-12));
    }
}

TEST_CASE("Cloth takes masses and stiffness from the settings it is given", "[material][mass]") {
    const auto topo = ClothTopology::build(irregularMesh(4, 4, 2));
    const double A = topo->totalRestArea();
    auto total = [](const std::vector<double>& v) {
        double s = 0.0;
        for (double x : v)
            s += x;
        return s;
    };

    SECTION("particleMass and springStiffness given directly") {
        ClothSettings s;
        s.particleMass = 0.5;
        s.springStiffness = 20.0;
        Cloth cloth(topo, s);
        for (double mi : cloth.masses())
            CHECK(mi == 0.5);
        for (double ks : cloth.stiffness())
            CHECK(ks == 20.0);
    }
    SECTION("totalMass, uniform and area-lumped") {
        ClothSettings s;
        s.totalMass = 3.0;
        s.springStiffness = 10.0;
        Cloth uniform(topo, s);
        CHECK(total(uniform.masses()) == Approx(3.0).epsilon(1e-12));
        s.lumping = MassLumping::AreaLumped;
        Cloth lumped(topo, s);
        CHECK(total(lumped.masses()) == Approx(3.0).epsilon(1e-12));
        const auto ref = areaLumpedMasses(*topo, 1.0, 1.0); // proportional to the right shares
        for (std::size_t i = 0; i < ref.size(); ++i)
            CHECK(lumped.masses()[i] == Approx(3.0 * ref[i] / A).epsilon(1e-12));
    }
    SECTION("everything from the material") {
        ClothSettings s;
        s.material = FabricMaterial{kE, kH, kRho};
        s.lumping = MassLumping::AreaLumped;
        Cloth cloth(topo, s);
        CHECK(total(cloth.masses()) == Approx(kRho * kH * A).epsilon(1e-12));
        const auto k = springStiffnessFromMaterial(*topo, kE, kH);
        for (std::size_t i = 0; i < k.size(); ++i)
            CHECK(cloth.stiffness()[i] == Approx(k[i]).epsilon(1e-14));
        s.lumping = MassLumping::Uniform;
        Cloth uniform(topo, s);
        CHECK(total(uniform.masses()) == Approx(kRho * kH * A).epsilon(1e-12));
    }
}

TEST_CASE("A default ClothSettings simulates: 200 g/m^2 cotton, mesh-free stiffness, sub-steps",
          "[material][mass][settings]") {
    SheetSpec spec;
    spec.rows = 21;
    spec.cols = 21;
    spec.spacing = 0.05;
    spec.uAxis = Vec3::UnitX();
    spec.vAxis = -Vec3::UnitY(); // hanging in the x-y plane
    const auto topo = ClothTopology::build(makeSheet(spec));
    Cloth cloth(topo, ClothSettings{});
    // Mass: the default material's rho h = 400 kg/m^3 * 0.5 mm = 0.2 kg/m^2 over the 1 m^2.
    double mass = 0.0;
    for (double m : cloth.masses())
        mass += m;
    CHECK(mass == Approx(0.2 * topo->totalRestArea()).epsilon(1e-12));
    CHECK(topo->totalRestArea() == Approx(1.0).epsilon(1e-12));
    // Stiffness: (M1) with E h = rho_A c^2 = 0.2 * 10^2 = 20 N/m: E h on the interior grid
    // edges, E h / 2 on the diagonals and the border edges (one triangle each).
    const double eh = 0.2 * kAutomaticStretchWaveSpeed * kAutomaticStretchWaveSpeed;
    const auto expected = springStiffnessFromMaterial(*topo, eh, 1.0);
    REQUIRE(expected.size() == cloth.stiffness().size());
    for (std::size_t i = 0; i < expected.size(); ++i)
        CHECK(cloth.stiffness()[i] == Approx(expected[i]).epsilon(1e-12));
    const double kMax = *std::max_element(cloth.stiffness().begin(), cloth.stiffness().end());
    CHECK(kMax == Approx(eh).epsilon(1e-12));
    // The same cloth meshed twice as coarse has the same springs (a membrane's stiffness does
    // not depend on the spacing), and so does a heavier cloth scaled by its mass.
    spec.rows = spec.cols = 11;
    spec.spacing = 0.1;
    Cloth coarse(ClothTopology::build(makeSheet(spec)), ClothSettings{});
    CHECK(*std::max_element(coarse.stiffness().begin(), coarse.stiffness().end()) ==
          Approx(eh).epsilon(1e-12));
    ClothSettings heavy;
    heavy.totalMass = 1.0; // 1 kg/m^2: five times the springs
    Cloth canvas(topo, heavy);
    CHECK(*std::max_element(canvas.stiffness().begin(), canvas.stiffness().end()) ==
          Approx(5.0 * eh).epsilon(1e-12));
    // A 60 Hz step is beyond this cloth's stability limit: it takes automatic sub-steps.
    const int n = cloth.substepsFor(1.0 / 60.0);
    CHECK(n == static_cast<int>(std::ceil(1.0 / 60.0 / (0.9 * cloth.stableTimeStep()))));
    CHECK(n > 1);

    // It hangs from two corners at 60 Hz: no error, finite, the limiter holds 10 %.
    cloth.pin(0);
    cloth.pin(20);
    for (int i = 0; i < 180; ++i)
        cloth.step(1.0 / 60.0);
    CHECK(cloth.maxStrain() <= 0.10 + cloth.settings().limiter.tolerance + 1e-12);
    double lowest = 0.0;
    for (const Vec3& x : cloth.positions()) {
        REQUIRE(x.allFinite());
        lowest = std::min(lowest, x.y());
    }
    // A 1 m sheet hanging from its top corners reaches below its own height (it sags), but no
    // farther than its diagonal stretched by the 10 % bound.
    CHECK(lowest < -1.0);
    CHECK(lowest > -std::sqrt(2.0) * 1.1);
}

TEST_CASE("The automatic springs of a large cloth carry its weight hanging, not the limiter",
          "[material][settings]") {
    // A membrane hanging a height H is stretched g H / c^2 at the top: with the least wave speed
    // (20 m/s) a 6 m curtain would hang at 15 %, beyond the 10 % bound, and the limiter carries
    // its weight in every step; its waves are made faster, sqrt(g L / 0.05) (34 m/s for 6 m),
    // and a cloth up to about 2 m keeps the least speed.
    auto curtain = [](double size) {
        SheetSpec spec;
        spec.rows = 21;
        spec.cols = 21;
        spec.spacing = size / 20.0;
        spec.uAxis = Vec3::UnitX();
        spec.vAxis = -Vec3::UnitY();
        return ClothTopology::build(makeSheet(spec));
    };
    const ClothSettings s;
    const double g = s.gravity.norm();
    CHECK(automaticWaveSpeed(*curtain(1.0), s) == kAutomaticStretchWaveSpeed);
    CHECK(automaticWaveSpeed(*curtain(2.0), s) == kAutomaticStretchWaveSpeed);
    CHECK(automaticWaveSpeed(*curtain(4.0), s) ==
          Approx(std::sqrt(g * 4.0 / kAutomaticHangingStrain)).epsilon(1e-12));
    ClothSettings fast;
    fast.stretchWaveSpeed = 100.0; // a given speed above it is kept
    CHECK(automaticWaveSpeed(*curtain(4.0), fast) == 100.0);
    ClothSettings space;
    space.gravity = Vec3::Zero();
    CHECK(automaticWaveSpeed(*curtain(4.0), space) == kAutomaticStretchWaveSpeed);

    // A 6 m curtain hung from its top row and settled: its springs hold it, the limiter has
    // nothing to correct at the end of a step's drift.
    Cloth cloth(curtain(6.0), s);
    for (Index i = 0; i < 21; ++i)
        cloth.pin(i);
    for (int f = 0; f < 600; ++f)
        cloth.step(1.0 / 60.0);
    CHECK(cloth.kineticEnergy() < 1e-2 * cloth.totalMass() * g); // (x 1 m: nearly at rest)
    CHECK(cloth.maxStrain() <= 1.25 * kAutomaticHangingStrain);
    CHECK(cloth.lastLimiterStats().maxStrainBefore < s.limiter.maxStrain);
}

// A cloth in centimetres (ClothSettings::inUnits(100)) is the same cloth as in metres: the
// same masses in kilograms, the same springs in N/m (kg/s^2 has no length in it), the same
// stability limit and sub-steps, and every position 100 times the metre cloth's. Left in SI,
// the centimetre cloth weighs 10,000 times as much (density per cubic metre over square
// centimetres) and its springs, set by stretch waves of 20 cm/s, hold none of its weight.
TEST_CASE("ClothSettings::inUnits: a cloth in centimetres moves as the same cloth in metres",
          "[material][settings][units]") {
    auto build = [](double unit) {
        SheetSpec spec;
        spec.rows = spec.cols = 21;
        spec.spacing = 0.05 * unit;
        spec.origin = Vec3(-0.5, 1.0, 0.0) * unit;
        spec.uAxis = Vec3::UnitX();
        spec.vAxis = -Vec3::UnitY(); // hanging: it stretches under its weight and settles
        ClothSettings s = unit == 1.0 ? ClothSettings{} : ClothSettings::inUnits(unit);
        s.sleep.enabled = true;
        auto cloth = std::make_unique<Cloth>(ClothTopology::build(makeSheet(spec)), s);
        for (Index i = 0; i < 21; ++i)
            cloth->pin(i); // the top row
        return cloth;
    };
    const auto metres = build(1.0);
    const auto centimetres = build(100.0);
    REQUIRE(metres->masses().size() == centimetres->masses().size());
    for (std::size_t i = 0; i < metres->masses().size(); ++i)
        CHECK(centimetres->masses()[i] == Approx(metres->masses()[i]).epsilon(1e-12));
    for (std::size_t s = 0; s < metres->stiffness().size(); ++s)
        CHECK(centimetres->stiffness()[s] == Approx(metres->stiffness()[s]).epsilon(1e-12));
    CHECK(centimetres->stableTimeStep() == Approx(metres->stableTimeStep()).epsilon(1e-12));
    const double frame = 1.0 / 60.0;
    CHECK(centimetres->substepsFor(frame) == metres->substepsFor(frame));
    CHECK(centimetres->settings().gravity.y() == Approx(-981.0).epsilon(1e-15));

    // Five seconds at 60 Hz: stretch waves run down it, the relative damping stops them, the
    // limiter holds its weight, it sleeps.
    double worst = 0.0;
    int asleepM = -1, asleepC = -1;
    for (int f = 0; f < 300; ++f) {
        metres->step(frame);
        centimetres->step(frame);
        for (std::size_t i = 0; i < metres->positions().size(); ++i)
            worst = std::max(worst,
                             (centimetres->positions()[i] / 100.0 - metres->positions()[i]).norm());
        if (asleepM < 0 && metres->isAsleep()) asleepM = f;
        if (asleepC < 0 && centimetres->isAsleep()) asleepC = f;
    }
    UNSCOPED_INFO(measured("centimetres against metres: largest difference %.3g m, asleep at "
                           "frames %d and %d, max strain %.6f and %.6f",
                           worst, asleepM, asleepC, metres->maxStrain(), centimetres->maxStrain()));
    CHECK(worst < 1e-9); // rounding: the two are the same computation scaled by 100
    CHECK(asleepM > 0);
    CHECK(asleepC == asleepM);
    CHECK(centimetres->maxStrain() == Approx(metres->maxStrain()).margin(1e-9));
}

TEST_CASE("ClothSettings::inUnits refuses a unit outside [1e-6, 1e6]",
          "[material][settings][units][errors]") {
    for (double bad : {0.0, -100.0, 1e-7, 1e7, std::numeric_limits<double>::quiet_NaN(),
                       std::numeric_limits<double>::infinity()}) {
        try {
            (void)ClothSettings::inUnits(bad);
            FAIL("accepted unitsPerMetre " << bad);
        } catch (const Error& e) {
            CHECK(std::string(toString(e.code())) == toString(ErrorCode::InvalidArgument));
            CHECK(std::string(e.what()).find("unitsPerMetre") != std::string::npos);
        }
    }
}
