// Sleeping: a cloth at rest falls asleep with its state frozen, a sleeping step does no
// work, edits and moving kinematic particles wake it, and waking continues exactly as a
// cloth restored from the frozen state.
#include "drape/cloth.hpp"
#include "drape/error.hpp"
#include "drape/snapshot.hpp"

#include <catch2/catch.hpp>

#include <functional>
#include <memory>
#include <string>
#include <vector>

using namespace drape;

namespace {

constexpr double kDt = 1.0 / 240.0;

SheetSpec hangingSpec() {
    SheetSpec spec;
    spec.rows = 8;
    spec.cols = 8;
    spec.spacing = 0.1;
    return spec;
}

/// An 8 x 8 sheet hanging from two corners, damped so that it settles in a few seconds.
std::unique_ptr<Cloth> hangingCloth(bool sleep) {
    static const TopologyPtr topo = ClothTopology::build(makeSheet(hangingSpec()));
    ClothSettings s;
    s.particleMass = 0.01;
    s.springStiffness = 50.0;
    s.damping = 0.03; // C_d / m = 3 /s
    s.sleep.enabled = sleep;
    auto c = std::make_unique<Cloth>(topo, s);
    c->pin(sheetIndex(hangingSpec(), 0, 0));
    c->pin(sheetIndex(hangingSpec(), 0, 7));
    return c;
}

/// Steps until the cloth falls asleep (at most 30 s); returns the steps taken.
int stepUntilAsleep(Cloth& c, Cloth* twin = nullptr) {
    int steps = 0;
    while (!c.isAsleep() && steps < 30 * 240) {
        c.step(kDt);
        if (twin) twin->step(kDt);
        ++steps;
    }
    return steps;
}

/// The hanging sheet of hangingCloth, stepped until it fell asleep.
std::unique_ptr<Cloth> sleepingCloth() {
    auto c = hangingCloth(true);
    stepUntilAsleep(*c);
    REQUIRE(c->isAsleep());
    return c;
}

std::uint64_t calls(const Cloth& c, const char* phase) {
    const PhaseTimer* t = c.timers().find(phase);
    return t ? t->calls : 0;
}

} // namespace

TEST_CASE("a cloth at rest falls asleep frozen, and a sleeping step does no work", "[sleep]") {
    auto a = hangingCloth(true);
    auto b = hangingCloth(false); // the same cloth that never sleeps
    const int steps = stepUntilAsleep(*a, b.get());
    REQUIRE(a->isAsleep());
    // Asleep only after sleep.time of quiet steps; until then the physics is untouched.
    CHECK(steps * kDt >= a->settings().sleep.time);
    CHECK(stateHash(*a) == stateHash(*b));
    CHECK_FALSE(b->isAsleep());
    // At rest: over the last second the sheet (never sleeping) stays within sleep.distance.
    const Vec3List rest = b->positions();
    for (int k = 0; k < 240; ++k)
        b->step(kDt);
    for (std::size_t i = 0; i < rest.size(); ++i) {
        CHECK((b->positions()[i] - rest[i]).norm() <= a->settings().sleep.distance);
    }

    // Asleep is at rest: no kinetic energy, no momentum (velocities() keep the frozen state).
    CHECK(a->kineticEnergy() == 0.0);
    CHECK(a->momentum() == Vec3::Zero());
    double frozenKinetic = 0.0;
    for (std::size_t i = 0; i < a->particleCount(); ++i)
        frozenKinetic += 0.5 * a->masses()[i] * a->velocities()[i].squaredNorm();

    const auto frozen = stateHash(*a);
    const std::uint64_t integrations = calls(*a, "integrate"), stepsBefore = a->stepCount();
    const double timeBefore = a->time();
    for (int k = 0; k < 1000; ++k)
        a->step(kDt);
    CHECK(a->isAsleep());
    CHECK(stateHash(*a) == frozen);
    CHECK(calls(*a, "integrate") == integrations); // no stage ran
    CHECK(calls(*a, "strain_limit") + 240 == calls(*b, "strain_limit"));
    CHECK(a->sleptSteps() == 1000);
    CHECK(a->stepCount() == stepsBefore + 1000);
    CHECK(a->time() == Approx(timeBefore + 1000 * kDt));
    // A sleeping cloth still rejects a bad time step.
    CHECK_THROWS_AS(a->step(-kDt), Error);
    // Woken, it reports the state it resumes from.
    a->wake();
    CHECK(a->kineticEnergy() == Approx(frozenKinetic).margin(1e-300));
}

TEST_CASE("waking continues exactly as a cloth restored from the frozen state", "[sleep]") {
    struct Edit {
        const char* name;
        std::function<void(Cloth&)> apply;
    };
    const std::vector<Edit> edits = {
        {"wake()", [](Cloth& c) { c.wake(); }},
        {"setVelocity", [](Cloth& c) { c.setVelocity(60, Vec3(0.0, 0.0, 0.5)); }},
        {"setPosition",
         [](Cloth& c) { c.setPosition(61, c.positions()[61] + Vec3(0.0, 0.0, 0.05)); }},
        {"setUserForce", [](Cloth& c) { c.setUserForce(63, Vec3(0.05, 0.0, 0.0)); }},
        {"setGravity", [](Cloth& c) { c.setGravity(Vec3(1.0, -9.81, 0.0)); }},
        {"setWind", [](Cloth& c) { c.setWind(Vec3(0.0, 0.0, 3.0)); }},
        {"unpin", [](Cloth& c) { c.unpin(sheetIndex(hangingSpec(), 0, 7)); }},
        {"pin", [](Cloth& c) { c.pin(63); }},
        {"mutableVelocities", [](Cloth& c) { c.mutableVelocities()[62].x() = 0.2; }},
    };
    // Asleep for 500, 1000 and 2000 steps of 1/240 s: whole 60 Hz intervals, so the relative
    // damping's passes (counted from time 0) fall on the same steps of `a` and `b`, whose
    // clocks reach each boundary by different sums (after 1000 steps they damped one step
    // apart, a rounding of the clock).
    for (const int asleepSteps : {500, 1000, 2000})
        for (const auto& edit : edits) {
            INFO(edit.name << ", asleep for " << asleepSteps << " steps");
            auto a = hangingCloth(true);
            stepUntilAsleep(*a);
            REQUIRE(a->isAsleep());
            const auto frozen = saveSnapshot(*a);
            auto b = hangingCloth(false);
            loadSnapshot(*b, frozen);
            for (int k = 0; k < asleepSteps; ++k)
                a->step(kDt); // asleep all along
            REQUIRE(a->isAsleep());

            edit.apply(*a);
            edit.apply(*b);
            CHECK_FALSE(a->isAsleep());
            // Fewer steps than sleep.time: a small edit lets `a` fall asleep again after that.
            for (int k = 0; k < 200; ++k) {
                a->step(kDt);
                b->step(kDt);
            }
            CHECK_FALSE(a->isAsleep());
            CHECK(stateHash(*a) == stateHash(*b));
            CHECK(a->positions() == b->positions());
        }
}

TEST_CASE("a kinematic particle that starts moving wakes the sleeping cloth", "[sleep]") {
    auto c = hangingCloth(true);
    const Index corner = sheetIndex(hangingSpec(), 0, 7);
    const Vec3 p0 = c->positions()[corner];
    const double start = 12.0; // [s], well after the cloth fell asleep
    c->setKinematic(corner, [p0, start](double t) {
        return t <= start ? p0 : Vec3(p0 + (t - start) * Vec3(0.3, 0.0, 0.0));
    });
    stepUntilAsleep(*c);
    REQUIRE(c->isAsleep());
    REQUIRE(c->time() < start - 1.0);
    const Vec3List frozen = c->positions();
    while (c->time() + kDt <= start)
        c->step(kDt);
    CHECK(c->isAsleep());
    CHECK(c->positions() == frozen);

    c->step(kDt); // the path leaves p0 in this step
    CHECK_FALSE(c->isAsleep());
    for (int k = 0; k < 120; ++k)
        c->step(kDt);
    CHECK_FALSE(c->isAsleep());
    CHECK((c->positions()[corner] - (p0 + (c->time() - start) * Vec3(0.3, 0.0, 0.0))).norm() <
          1e-9);
    // The rest of the cloth follows the pin.
    const Index free = sheetIndex(hangingSpec(), 7, 7);
    CHECK(c->positions()[free].x() - frozen[free].x() > 0.02);
}

TEST_CASE("the same wind, gravity, air or damping set every frame keeps the cloth asleep, and a "
          "new value wakes it",
          "[sleep]") {
    // A game pushes its wind and gravity into every object each frame (review 18: a
    // tablecloth given the same still wind each frame never slept). Each setter wakes the
    // cloth only when it changes the value, and the cloth then moves as the new value says.
    auto c = sleepingCloth();
    const auto frozen = stateHash(*c);
    const ClothSettings now = c->settings();
    for (int k = 0; k < 240; ++k) {
        c->setWind(now.aero.wind);
        c->setGravity(now.gravity);
        c->setAero(now.aero);
        c->setRelativeDamping(now.relativeDamping);
        c->step(kDt);
    }
    CHECK(c->isAsleep());
    CHECK(stateHash(*c) == frozen);
    // Each of them with another value wakes the cloth.
    const std::vector<std::function<void(Cloth&)>> changes = {
        [](Cloth& x) { x.setWind(Vec3(1.0, 0.0, 0.0)); },
        [&now](Cloth& x) { x.setGravity(now.gravity + Vec3(0.0, 0.0, 1.0)); },
        [&now](Cloth& x) {
            AeroSettings air = now.aero;
            air.airDensity = 1.2;
            x.setAero(air);
        },
        [&now](Cloth& x) { x.setRelativeDamping(now.relativeDamping + 1.0); },
    };
    for (const auto& change : changes) {
        auto d = sleepingCloth();
        change(*d);
        CHECK_FALSE(d->isAsleep());
    }
    // The sideways gravity moves the woken sheet sideways.
    auto e = sleepingCloth();
    const Vec3List before = e->positions();
    e->setGravity(now.gravity + Vec3(0.0, 0.0, 2.0));
    for (int k = 0; k < 120; ++k)
        e->step(kDt);
    const Index free = sheetIndex(hangingSpec(), 7, 3);
    CHECK(e->positions()[free].z() - before[free].z() > 0.01);
}

TEST_CASE("a sleeping cloth in air keeps the drag's limit of its frozen state, and a woken one "
          "takes it anew",
          "[sleep][aero]") {
    // Asleep, the drag's limit is the frozen state's (it is not computed again each step:
    // review 18); every change that could move it wakes the cloth first, and the limit is
    // then the new state's.
    auto c = hangingCloth(true);
    AeroSettings air;
    air.airDensity = 1.2;
    c->setAero(air);
    stepUntilAsleep(*c);
    REQUIRE(c->isAsleep());
    auto twin = hangingCloth(false); // the same frozen state, awake
    twin->setAero(air);
    twin->restoreState(c->state(), {});
    const double asleep = c->aeroTimeStep(kDt);
    CHECK(asleep == twin->aeroTimeStep(kDt));
    for (int k = 0; k < 100; ++k)
        c->step(kDt);
    CHECK(c->isAsleep());
    CHECK(c->aeroTimeStep(kDt) == asleep);
    CHECK(c->aeroTimeStep(0.5 * kDt) == twin->aeroTimeStep(0.5 * kDt)); // another dt
    // A wind wakes it, and the limit is the windy one.
    c->setWind(Vec3(20.0, 0.0, 0.0));
    twin->setWind(Vec3(20.0, 0.0, 0.0));
    CHECK_FALSE(c->isAsleep());
    CHECK(c->aeroTimeStep(kDt) == twin->aeroTimeStep(kDt));
    CHECK(c->aeroTimeStep(kDt) < 0.5 * asleep);
}

TEST_CASE("sleeping is off by default, validated, and stored in snapshots", "[sleep]") {
    auto off = hangingCloth(false);
    for (int k = 0; k < 20 * 240; ++k)
        off->step(kDt);
    CHECK_FALSE(off->isAsleep());
    CHECK(off->sleptSteps() == 0);
    CHECK_FALSE(ClothSettings{}.sleep.enabled);

    SleepSettings bad;
    bad.distance = 0.0;
    CHECK_THROWS_AS(off->setSleep(bad), Error);
    bad = {};
    bad.time = -1.0;
    CHECK_THROWS_WITH(off->setSleep(bad), Catch::Contains("sleep.time"));

    // setSleep turns it on for an existing cloth; a snapshot keeps the sleep state: a sleeping
    // cloth loads asleep, and one counting its quiet time goes on counting from there.
    SleepSettings on;
    on.enabled = true;
    off->setSleep(on);
    stepUntilAsleep(*off);
    REQUIRE(off->isAsleep());
    const auto asleep = saveSnapshot(*off);
    off->wake();
    off->step(kDt);
    off->step(kDt);
    REQUIRE_FALSE(off->isAsleep());
    const double quiet = off->quietTime();
    REQUIRE(quiet > 0.0);
    const auto counting = saveSnapshot(*off);
    loadSnapshot(*off, asleep);
    CHECK(off->isAsleep());
    loadSnapshot(*off, counting);
    CHECK_FALSE(off->isAsleep());
    CHECK(off->quietTime() == quiet);
    // Asleep after the same number of further steps as the saved cloth would be.
    int more = 0;
    while (!off->isAsleep() && more < 100000) {
        off->step(kDt);
        ++more;
    }
    CHECK(quiet + more * kDt >= on.time - 1e-9);
    CHECK(quiet + (more - 1) * kDt < on.time + 1e-9);
}

TEST_CASE("a kinematic target within a thousandth of sleep.distance of its frozen particle "
          "leaves the cloth asleep, and one that goes on moving wakes it",
          "[sleep]") {
    auto c = hangingCloth(true);
    const Index corner = sheetIndex(hangingSpec(), 0, 0);
    const Vec3 x0 = c->positions()[corner];
    c->setKinematicTarget(corner, x0, c->time()); // kinematic where it is
    stepUntilAsleep(*c);
    REQUIRE(c->isAsleep());
    // The tolerance is 10 um at the default sleep.distance of 1 cm.
    REQUIRE(c->settings().sleep.distance == 0.01);
    const double tol = 1e-5;
    const auto frozen = stateHash(*c);
    // A micrometre off (a body that gave way by as much in the last walk): still asleep.
    for (int k = 0; k < 240; ++k) {
        c->setKinematicTarget(corner, x0 + Vec3(0.0, 0.0, 0.1 * tol), c->time() + kDt);
        c->step(kDt);
    }
    CHECK(c->isAsleep());
    CHECK(stateHash(*c) == frozen);
    // Creeping by 0.4 of the tolerance a step: the offset from the frozen particle grows, and
    // the cloth wakes once it is beyond the tolerance (the third step).
    int woke = 0;
    for (int k = 1; k <= 10 && c->isAsleep(); ++k) {
        c->setKinematicTarget(corner, x0 + Vec3(0.0, 0.0, 0.4 * k * tol), c->time() + kDt);
        c->step(kDt);
        woke = k;
    }
    CHECK_FALSE(c->isAsleep());
    CHECK(woke == 3);
}
