// Force tests: springs are conservative (force = -grad energy, momentum and angular momentum
// conserved), the implicit integrator's Jacobians match finite differences (also for
// compressed springs), damping dissipates and spares rigid motion, aerodynamics follow
// their formulas.
#include "helpers.hpp"

#include "drape/forces.hpp"

#include "spring_layout.hpp" // the private layout the family kernels read

#include <Eigen/Dense>

using namespace drape;
using namespace drape_test;

namespace {

/// An irregular curved mesh with positions perturbed in 3D by up to +-0.3 (springs both
/// stretched and compressed) and a different stiffness on every spring.
struct Scene {
    TopologyPtr topo;
    std::vector<double> k;
    Vec3List x;
};

Scene perturbedScene(std::uint64_t seed) {
    Scene s;
    s.topo = ClothTopology::build(irregularMesh(3, 3, seed, true));
    Rng rng(seed + 100);
    for (std::size_t i = 0; i < s.topo->springCount(); ++i)
        s.k.push_back(rng.uniform(5.0, 50.0));
    for (const Vec3& p : s.topo->restPositions())
        s.x.push_back(p +
                      Vec3(rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3)));
    return s;
}

Vec3List springForces(const Scene& s, const Vec3List& x) {
    Vec3List f(x.size(), Vec3::Zero());
    addSpringForces(s.topo->springs(), s.k, x, f);
    return f;
}

Eigen::MatrixXd dense(const Eigen::SparseMatrix<double>& m) {
    return Eigen::MatrixXd(m);
}

} // namespace

TEST_CASE("Spring force is minus the gradient of the spring energy", "[forces]") {
    const Scene s = perturbedScene(5);
    std::size_t compressed = 0, stretched = 0;
    for (const Spring& sp : s.topo->springs()) {
        ((s.x[sp.b] - s.x[sp.a]).norm() < sp.restLength ? compressed : stretched) += 1;
    }
    REQUIRE(compressed > 0);
    REQUIRE(stretched > 0);

    const Vec3List f = springForces(s, s.x);
    double fmax = 0.0;
    for (const Vec3& fi : f)
        fmax = std::max(fmax, fi.norm());
    // Central differences with h = 1e-6: truncation ~ h^2 k = 5e-11, rounding ~ 1e-16 E / h
    // = 1e-10 (E ~ 1 J); 1e-7 relative to the largest force (~10 N) is far above both.
    const double h = 1e-6;
    for (std::size_t i = 0; i < s.x.size(); ++i) {
        for (int c = 0; c < 3; ++c) {
            Vec3List xp = s.x, xm = s.x;
            xp[i][c] += h;
            xm[i][c] -= h;
            const double grad = (springEnergy(s.topo->springs(), s.k, xp) -
                                 springEnergy(s.topo->springs(), s.k, xm)) /
                                (2 * h);
            CHECK(f[i][c] == Approx(-grad).margin(1e-7 * fmax));
        }
    }
    // Internal forces: zero net force and zero net torque (Newton's third law, central forces).
    Vec3 total = Vec3::Zero(), torque = Vec3::Zero();
    for (std::size_t i = 0; i < f.size(); ++i) {
        total += f[i];
        torque += s.x[i].cross(f[i]);
    }
    CHECK(total.norm() < 1e-12 * fmax * static_cast<double>(f.size()));
    CHECK(torque.norm() < 1e-12 * fmax * static_cast<double>(f.size()));
}

TEST_CASE("springJacobianBlock matches finite differences, stretched and compressed",
          "[forces][jacobian]") {
    Rng rng(3);
    for (int trial = 0; trial < 20; ++trial) {
        const Vec3 xa(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1));
        const Vec3 xb(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1));
        const double l = (xb - xa).norm();
        const double k = rng.uniform(1.0, 100.0);
        // Half the trials stretched (L0 < l), half compressed (L0 > l).
        const double L0 = trial % 2 == 0 ? 0.6 * l : 1.7 * l;
        INFO("trial " << trial << " l " << l << " L0 " << L0);
        auto fa = [&](const Vec3& b) {
            const Vec3 d = b - xa;
            return Vec3(k * (d.norm() - L0) * d / d.norm());
        };
        const Eigen::Matrix3d J = springJacobianBlock(xa, xb, k, L0, false);
        const double h = 1e-6;
        for (int c = 0; c < 3; ++c) {
            Vec3 bp = xb, bm = xb;
            bp[c] += h;
            bm[c] -= h;
            const Vec3 col = (fa(bp) - fa(bm)) / (2 * h);
            // Truncation h^2 |f'''| ~ 1e-12 k / l^2 and rounding 1e-16 k / h ~ 1e-8: 1e-6 k.
            for (int r = 0; r < 3; ++r)
                CHECK(J(r, c) == Approx(col[r]).margin(1e-6 * k));
        }
        // Symmetric (a conservative force has a symmetric Hessian).
        CHECK((J - J.transpose()).norm() < 1e-12 * k);
        // Clamping drops only the transverse term of compressed springs.
        const Eigen::Matrix3d Jc = springJacobianBlock(xa, xb, k, L0, true);
        const Vec3 n = (xb - xa) / l;
        if (L0 > l) {
            CHECK((Jc - k * n * n.transpose()).norm() < 1e-12 * k);
        } else {
            CHECK((Jc - J).norm() < 1e-12 * k);
        }
    }
}

TEST_CASE("ForceModel::assembleJacobians matches finite differences of the forces",
          "[forces][jacobian]") {
    const Scene s = perturbedScene(8);
    const std::size_t n = s.x.size();
    std::vector<double> mass(n, 0.2);
    ClothSettings settings;
    settings.damping = 0.3;
    settings.springDamping = 0.7;
    settings.gravity = Vec3(0, -9.81, 0); // constant: drops out of both derivatives
    PhaseTimers timers;
    ForceModel model(s.topo, s.k, mass, settings, timers);

    Eigen::SparseMatrix<double> dfdx, dfdv;
    model.assembleJacobians(s.x, false, dfdx, dfdv);
    const Eigen::MatrixXd Kx = dense(dfdx), Kv = dense(dfdv);
    REQUIRE(Kx.rows() == static_cast<Eigen::Index>(3 * n));
    const double kmax = *std::max_element(s.k.begin(), s.k.end());

    auto force = [&](const Vec3List& x, const Vec3List& v) {
        Vec3List f;
        model.evaluate(x, v, f);
        return f;
    };

    // d f / d x at v = 0: spring damping depends on x only through (v_b - v_a) . n, which
    // vanishes at v = 0, so the finite difference sees the springs alone, as the implicit
    // integrator assumes.
    const Vec3List zero(n, Vec3::Zero());
    const double h = 1e-6;
    for (std::size_t j = 0; j < n; ++j) {
        for (int c = 0; c < 3; ++c) {
            Vec3List xp = s.x, xm = s.x;
            xp[j][c] += h;
            xm[j][c] -= h;
            const Vec3List fp = force(xp, zero), fm = force(xm, zero);
            for (std::size_t i = 0; i < n; ++i)
                for (int r = 0; r < 3; ++r) {
                    const double fd = (fp[i][r] - fm[i][r]) / (2 * h);
                    // Same budget as the single-block test: 1e-6 k.
                    CHECK(Kx(static_cast<Eigen::Index>(3 * i + r),
                             static_cast<Eigen::Index>(3 * j + c)) ==
                          Approx(fd).margin(1e-6 * kmax));
                }
        }
    }
    CHECK((Kx - Kx.transpose()).norm() < 1e-12 * kmax);

    // d f / d v: the forces are linear in v, so differences are exact up to rounding.
    Rng rng(4);
    Vec3List v;
    for (std::size_t i = 0; i < n; ++i)
        v.emplace_back(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1));
    for (std::size_t j = 0; j < n; ++j) {
        for (int c = 0; c < 3; ++c) {
            Vec3List vp = v, vm = v;
            vp[j][c] += h;
            vm[j][c] -= h;
            const Vec3List fp = force(s.x, vp), fm = force(s.x, vm);
            for (std::size_t i = 0; i < n; ++i)
                for (int r = 0; r < 3; ++r) {
                    const double fd = (fp[i][r] - fm[i][r]) / (2 * h);
                    CHECK(Kv(static_cast<Eigen::Index>(3 * i + r),
                             static_cast<Eigen::Index>(3 * j + c)) == Approx(fd).margin(1e-7));
                }
        }
    }

    // With clampCompression the stiffness matrix is negative semi-definite (CG needs it).
    Eigen::SparseMatrix<double> dfdxClamped, unused;
    model.assembleJacobians(s.x, true, dfdxClamped, unused);
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(dense(dfdxClamped));
    CHECK(eig.eigenvalues().maxCoeff() < 1e-9 * kmax);
    // Without clamping compressed springs make it indefinite here (their transverse term is
    // negative), which is why the clamp exists.
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig2(Kx);
    CHECK(eig2.eigenvalues().maxCoeff() > 1e-6 * kmax);
}

TEST_CASE("Damping dissipates and leaves rigid motion alone", "[forces][damping]") {
    const Scene s = perturbedScene(12);
    const std::size_t n = s.x.size();
    Rng rng(5);
    Vec3List v;
    for (std::size_t i = 0; i < n; ++i)
        v.emplace_back(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1));

    // Spring damping: power sum f . v <= 0, zero net force.
    Vec3List f(n, Vec3::Zero());
    addSpringDamping(s.topo->springs(), 0.8, s.x, v, f);
    double power = 0.0;
    Vec3 total = Vec3::Zero();
    for (std::size_t i = 0; i < n; ++i) {
        power += f[i].dot(v[i]);
        total += f[i];
    }
    CHECK(power < 0.0);
    CHECK(total.norm() < 1e-12);

    // Rigid motion v = u + w x x: no relative motion along any spring, no damping force.
    const Vec3 u(0.3, -1.0, 2.0), w(0.5, 0.2, -0.7);
    Vec3List rigid;
    for (const Vec3& p : s.x)
        rigid.push_back(u + w.cross(p));
    Vec3List fr(n, Vec3::Zero());
    addSpringDamping(s.topo->springs(), 0.8, s.x, rigid, fr);
    for (const Vec3& fi : fr)
        CHECK(fi.norm() < 1e-12); // rounding of O(1) dot products

    // Linear damping (eq. 8) and gravity (eq. 6).
    Vec3List fl(n, Vec3::Zero());
    addLinearDamping(0.4, v, fl);
    for (std::size_t i = 0; i < n; ++i)
        CHECK((fl[i] + 0.4 * v[i]).norm() == 0.0);
    std::vector<double> mass(n);
    for (std::size_t i = 0; i < n; ++i)
        mass[i] = 0.1 * static_cast<double>(i + 1);
    Vec3List fg(n, Vec3::Zero());
    addGravity(mass, Vec3(0, -9.81, 0), fg);
    for (std::size_t i = 0; i < n; ++i)
        CHECK((fg[i] - mass[i] * Vec3(0, -9.81, 0)).norm() < 1e-15);
}

TEST_CASE("Aerodynamic drag and lift follow their formulas", "[forces][aero]") {
    // One triangle in the z = 0 plane (unit normal +z), area 0.5.
    const std::vector<Triangle> tris{{0, 1, 2}};
    const Vec3List x{Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
    AeroSettings aero;
    aero.airDensity = 1.2;
    aero.dragCoefficient = 1.1;
    aero.liftCoefficient = 0.4;
    const double A = 0.5;
    auto total = [&](const Vec3& vel) {
        Vec3List v(3, vel), f(3, Vec3::Zero());
        addAeroForces(tris, aero, x, v, f);
        // Shared equally by the corners.
        CHECK((f[0] - f[1]).norm() < 1e-15);
        CHECK((f[0] - f[2]).norm() < 1e-15);
        return Vec3(f[0] + f[1] + f[2]);
    };
    // Face-on: pure drag rho/2 Cd A |u|^2 against the motion; the lift term vanishes (n x u = 0).
    const Vec3 faceOn = total(Vec3(0, 0, 2.0));
    CHECK((faceOn - Vec3(0, 0, -0.5 * 1.2 * 1.1 * A * 4.0)).norm() < 1e-12);
    // Edge-on: no force at all.
    CHECK(total(Vec3(3.0, 1.0, 0.0)).norm() < 1e-12);
    // At 45 degrees: drag along -n, and lift perpendicular to the relative flow.
    const double U = 2.0;
    const Vec3 u = U * Vec3(1, 0, 1).normalized();
    const Vec3 n(0, 0, 1);
    const Vec3 expectedDrag = -0.5 * 1.2 * 1.1 * A * U * u.dot(n) * n;
    const Vec3 expectedLift = -0.5 * 1.2 * 0.4 * A * std::abs(u.dot(n)) * n.cross(u).cross(u) / U;
    const Vec3 f45 = total(u);
    CHECK((f45 - expectedDrag - expectedLift).norm() < 1e-12);
    CHECK(std::abs(expectedLift.dot(u)) < 1e-12);
    // Wind is relative: a still triangle in a wind -u feels what a triangle moving at u feels.
    aero.wind = -u;
    CHECK((total(Vec3::Zero()) - f45).norm() < 1e-12);
}

TEST_CASE("Spring families: every spring in one slot or loose, and the family kernels sum the "
          "same forces as the per-spring loop",
          "[forces][families]") {
    auto checkMesh = [](const TriangleMesh& mesh, std::uint64_t seed, bool allInFamilies) {
        const TopologyPtr topo = ClothTopology::build(mesh);
        // Coverage: each spring exactly once, in a family slot (matching its ends) or loose.
        std::vector<int> seen(topo->springCount(), 0);
        const detail::SpringLayout& layout = topo->springLayout();
        const auto& slotSpring = layout.slotSpring;
        for (const detail::SpringFamily& fam : layout.families) {
            for (Index j = 0; j < fam.count; ++j) {
                const Index s = slotSpring[fam.slot + j];
                if (s == kNoParticle) continue;
                ++seen[s];
                CHECK(topo->springs()[s].a == fam.first + j);
                CHECK(topo->springs()[s].b == fam.first + j + fam.offset);
                CHECK(layout.springSlot[s] == fam.slot + j);
                CHECK(layout.slotRest[fam.slot + j] == topo->springs()[s].restLength);
                CHECK(layout.slotInverseSquaredRest[fam.slot + j] == layout.inverseSquaredRest[s]);
            }
        }
        for (Index s : layout.looseSprings) {
            ++seen[s];
            CHECK(layout.springSlot[s] == detail::kNoSlot);
        }
        CHECK(std::all_of(seen.begin(), seen.end(), [](int c) { return c == 1; }));
        CHECK(layout.looseSprings.empty() == allInFamilies);

        // Forces: springs stretched and compressed, one spring's ends made to coincide.
        Rng rng(seed);
        std::vector<double> k;
        for (std::size_t i = 0; i < topo->springCount(); ++i)
            k.push_back(rng.uniform(5.0, 50.0));
        Vec3List x;
        for (const Vec3& p : topo->restPositions())
            x.push_back(
                p + Vec3(rng.uniform(-0.2, 0.2), rng.uniform(-0.2, 0.2), rng.uniform(-0.2, 0.2)));
        const Spring& sp = topo->springs()[topo->springCount() / 2];
        x[sp.b] = x[sp.a];
        Vec3List expected(x.size(), Vec3::Zero());
        addSpringForces(topo->springs(), k, x, expected);
        ClothSettings settings;
        settings.gravity = Vec3::Zero();
        PhaseTimers timers;
        ForceModel model(topo, k, std::vector<double>(x.size(), 0.1), settings, timers);
        Vec3List f;
        model.evaluate(x, Vec3List(x.size(), Vec3::Zero()), f);
        double scale = 0.0, worst = 0.0;
        for (std::size_t i = 0; i < x.size(); ++i) {
            REQUIRE(f[i].allFinite());
            scale = std::max(scale, expected[i].norm());
            worst = std::max(worst, (f[i] - expected[i]).norm());
        }
        INFO("largest difference " << worst << " against forces up to " << scale);
        CHECK(worst <= 1e-12 * scale); // the same terms, summed in another order
    };
    SECTION("a sheet: all springs in families") {
        SheetSpec spec;
        spec.rows = 13;
        spec.cols = 17;
        spec.spacing = 0.1;
        checkMesh(makeSheet(spec), 3, true);
    }
    SECTION("a sheet of several blocks: the slots before each block are carried over") {
        SheetSpec spec; // 12000 particles: the pass works in blocks of 2048
        spec.rows = 40;
        spec.cols = 300;
        spec.spacing = 0.1;
        checkMesh(makeSheet(spec), 11, true);
    }
    SECTION("a sheet with rows wider than the blocked pass takes: the whole-cloth pass") {
        SheetSpec spec; // offsets 16399 .. 16401 > 16384
        spec.rows = 2;
        spec.cols = 16400;
        spec.spacing = 0.1;
        checkMesh(makeSheet(spec), 13, true);
    }
    SECTION("an irregular mesh: some springs loose") {
        checkMesh(irregularMesh(4, 4, 7, true), 5, false);
    }
}
