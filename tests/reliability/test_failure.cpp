// Blow-up detection: hard strain cap, energy growth without a source, retry with sub-steps.
#include "drape/cloth.hpp"
#include "drape/error.hpp"
#include "drape/snapshot.hpp"

#include <catch2/catch.hpp>

using namespace drape;

namespace {

// A 6 x 6 sheet without gravity, one particle kicked: energy is conserved by the physics,
// so any growth is numerical.
std::unique_ptr<Cloth> kickedSheet(const ClothSettings& base) {
    SheetSpec spec;
    spec.rows = 6;
    spec.cols = 6;
    spec.spacing = 0.1;
    ClothSettings s = base;
    s.particleMass = 0.01;
    s.springStiffness = 100.0;
    s.gravity = Vec3::Zero();
    s.limiter.kind = LimiterKind::None;
    s.rejectUnstableTimeStep = false;
    s.substeps.automatic = false; // each step is the dt given
    auto c = std::make_unique<Cloth>(ClothTopology::build(makeSheet(spec)), s);
    c->setVelocity(14, Vec3(0.3, 0.2, 0.5));
    return c;
}

} // namespace

TEST_CASE("energy growth is detected before the state turns non-finite", "[blowup]") {
    ClothSettings s;
    s.relativeDamping = 0.0; // the motion measured here is undamped or damped by C_d only
    s.integrator = IntegratorKind::SymplecticEuler;
    s.failure.maxEnergyGrowth = 0.5;
    auto cloth = kickedSheet(s);
    const double dt = 1.5 * cloth->stableTimeStep(); // beyond the limit: the top mode grows
    int failedAt = -1;
    for (int i = 0; i < 2000 && failedAt < 0; ++i) {
        const auto before = stateHash(*cloth);
        try {
            cloth->step(dt);
        } catch (const Error& e) {
            failedAt = i;
            CHECK(e.code() == ErrorCode::SimulationFailure);
            CHECK_THAT(e.what(), Catch::Contains("energy grew"));
            CHECK(stateHash(*cloth) == before); // last good state kept
        }
    }
    REQUIRE(failedAt >= 0);
    for (const auto& x : cloth->positions())
        CHECK(x.allFinite());
    // The energy at the failure is still moderate (the check fired early, not at overflow).
    CHECK(cloth->kineticEnergy() + cloth->springEnergy() < 1e6);
}

TEST_CASE("the same cloth below the stability limit passes the energy check", "[blowup]") {
    ClothSettings s;
    s.relativeDamping = 0.0; // the motion measured here is undamped or damped by C_d only
    s.integrator = IntegratorKind::VelocityVerlet;
    s.failure.maxEnergyGrowth = 0.05;
    auto cloth = kickedSheet(s);
    const double dt = 0.5 * cloth->stableTimeStep();
    const double e0 = cloth->kineticEnergy() + cloth->springEnergy();
    for (int i = 0; i < 5000; ++i)
        cloth->step(dt);
    // Velocity-Verlet is symplectic: the energy stays within a few percent at half the limit.
    CHECK(cloth->kineticEnergy() + cloth->springEnergy() == Approx(e0).epsilon(0.05));
}

TEST_CASE("a failed step retried as sub-steps keeps the run alive", "[blowup]") {
    ClothSettings s;
    s.relativeDamping = 0.0; // the motion measured here is undamped or damped by C_d only
    s.integrator = IntegratorKind::SymplecticEuler;
    s.failure.maxEnergyGrowth = 0.5;
    s.failure.retrySubsteps = 4; // dt / 4 is below the limit
    auto cloth = kickedSheet(s);
    const double dt = 1.5 * cloth->stableTimeStep();
    const double e0 = cloth->kineticEnergy() + cloth->springEnergy();
    for (int i = 0; i < 2000; ++i)
        cloth->step(dt);
    CHECK(cloth->retriedSteps() > 0);
    CHECK(cloth->stepCount() == 2000);
    CHECK(cloth->time() == Approx(2000 * dt));
    for (const auto& x : cloth->positions())
        CHECK(x.allFinite());
    // Each accepted step grows the energy by at most half the scale; the run stays bounded.
    CHECK(cloth->kineticEnergy() + cloth->springEnergy() < 100.0 * e0);
}

TEST_CASE("a strain beyond the hard cap fails the step", "[blowup]") {
    SheetSpec spec;
    spec.rows = 10;
    spec.cols = 10;
    spec.spacing = 10.0;
    ClothSettings s;
    s.relativeDamping = 0.0; // the motion measured here is undamped or damped by C_d only
    s.particleMass = 0.5;
    s.springStiffness = 20.0;
    s.gravity = Vec3(0.0, -9.8, 0.0);
    s.limiter.kind = LimiterKind::None; // the paper's soft sheet stretches far without it
    s.failure.maxStrain = 0.5;
    Cloth cloth(ClothTopology::build(makeSheet(spec)), s);
    cloth.pin(0);
    cloth.pin(9);
    bool failed = false;
    for (int i = 0; i < 2000 && !failed; ++i) {
        try {
            cloth.step(0.01);
        } catch (const Error& e) {
            failed = true;
            CHECK_THAT(e.what(), Catch::Contains("hard cap"));
        }
    }
    REQUIRE(failed);
    CHECK(cloth.maxStrain() <= 0.5); // the kept state is the last one within the cap
}

TEST_CASE("failure settings are validated", "[blowup]") {
    SheetSpec spec;
    auto topo = ClothTopology::build(makeSheet(spec));
    ClothSettings s;
    s.relativeDamping = 0.0; // the motion measured here is undamped or damped by C_d only
    s.particleMass = 1.0;
    s.springStiffness = 1.0;
    s.failure.maxStrain = -1.0;
    CHECK_THROWS_WITH(Cloth(topo, s), Catch::Contains("failure.maxStrain"));
    s.failure.maxStrain = 0.0; // given: must be positive (not given turns the cap off)
    CHECK_THROWS_WITH(Cloth(topo, s), Catch::Contains("failure.maxStrain"));
    s.failure.maxStrain.reset();
    s.failure.maxEnergyGrowth = std::nan("");
    CHECK_THROWS_WITH(Cloth(topo, s), Catch::Contains("failure.maxEnergyGrowth"));
    s.failure.maxEnergyGrowth.reset();
    s.failure.retrySubsteps = -3;
    CHECK_THROWS_WITH(Cloth(topo, s), Catch::Contains("failure.retrySubsteps"));
}
