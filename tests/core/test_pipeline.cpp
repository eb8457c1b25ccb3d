// The step pipeline holds only the phases a cloth uses, in the documented order, and the phase
// timers count every call. Also: two identical runs give identical states.
#include "helpers.hpp"

#include "drape/cloth.hpp"

#include <algorithm>
#include <chrono>
#include <thread>

using namespace drape;
using namespace drape_test;

namespace {

bool has(const std::vector<std::string>& p, const std::string& name) {
    return std::find(p.begin(), p.end(), name) != p.end();
}
std::ptrdiff_t pos(const std::vector<std::string>& p, const std::string& name) {
    return std::find(p.begin(), p.end(), name) - p.begin();
}

TopologyPtr smallSheet() {
    SheetSpec spec;
    spec.rows = 5;
    spec.cols = 4;
    spec.spacing = 0.1;
    return ClothTopology::build(makeSheet(spec));
}

ClothSettings basic() {
    ClothSettings s;
    s.particleMass = 0.01;
    s.springStiffness = 20.0;
    return s;
}

std::uint64_t calls(const Cloth& c, const std::string& name) {
    const PhaseTimer* t = c.timers().find(name);
    return t ? t->calls : 0;
}

class CountingStage : public ClothStage {
  public:
    std::string name() const override { return "test_stage"; }
    void run(Cloth& cloth, double dt) override {
        ++runs;
        lastDt = dt;
        stepsSeen = cloth.stepCount();
    }
    int runs = 0;
    double lastDt = 0.0;
    std::uint64_t stepsSeen = 0;
};

} // namespace

TEST_CASE("A plain cloth's pipeline holds only what it uses", "[pipeline]") {
    // VV, stress-ordered limiter, gravity, the default relative damping, no C_d/aero/user
    Cloth cloth(smallSheet(), basic());
    cloth.pin(0);
    cloth.step(0.001);
    const auto p = cloth.pipeline();
    INFO("pipeline has " << p.size() << " phases");
    for (const auto& name : p)
        INFO(name);
    REQUIRE(!p.empty());
    CHECK(p.front() == "integrate");
    CHECK(p.back() == "verify"); // the checks of the finished step come last, always
    REQUIRE(p.size() >= 3);
    CHECK(p[p.size() - 3] == "integrate_finish"); // Velocity-Verlet's closing half kick
    CHECK(p[p.size() - 2] == "relative_damping"); // the default damping, on the finished step
    CHECK(has(p, "strain_limit"));
    CHECK(pos(p, "integrate") < pos(p, "strain_limit"));
    CHECK(has(p, "springs"));
    CHECK(has(p, "gravity"));
    CHECK(pos(p, "strain_limit") < pos(p, "springs"));
    for (const char* unused :
         {"aero", "user", "damping", "spring_damping", "kinematic", "grab", "forces_refresh"})
        CHECK_FALSE(has(p, unused));
}

TEST_CASE("Phases appear when a cloth starts to use them", "[pipeline]") {
    SECTION("no limiter, no gravity, another integrator") {
        ClothSettings s = basic();
        s.limiter.kind = LimiterKind::None;
        s.gravity = Vec3::Zero();
        s.integrator = IntegratorKind::RungeKutta4;
        Cloth cloth(smallSheet(), s);
        cloth.step(0.001);
        const auto p = cloth.pipeline();
        CHECK_FALSE(has(p, "strain_limit"));
        CHECK_FALSE(has(p, "gravity"));
        CHECK_FALSE(has(p, "integrate_finish"));
        CHECK(calls(cloth, "strain_limit") == 0u);
    }
    SECTION("damping, aerodynamics, user and external forces, stages") {
        ClothSettings s = basic();
        s.damping = 0.01;
        s.springDamping = 0.02;
        s.aero.airDensity = 1.2;
        Cloth cloth(smallSheet(), s);
        cloth.step(0.001);
        auto p = cloth.pipeline();
        CHECK(has(p, "damping"));
        CHECK(has(p, "spring_damping"));
        CHECK(has(p, "aero"));
        CHECK_FALSE(has(p, "user"));

        cloth.setUserForce(3, Vec3(0, 0, 0.1));
        CHECK(has(cloth.pipeline(), "user"));
        cloth.clearUserForces();
        CHECK_FALSE(has(cloth.pipeline(), "user"));

        cloth.addExternalForce("contact_penalty", [](const Vec3List&, const Vec3List&,
                                                     Vec3List& f) { f[0] += Vec3(0, 1e-3, 0); });
        CHECK(has(cloth.pipeline(), "contact_penalty"));

        auto stage = std::make_shared<CountingStage>();
        cloth.addStage(stage);
        p = cloth.pipeline();
        REQUIRE(has(p, "test_stage"));
        CHECK(pos(p, "strain_limit") < pos(p, "test_stage"));
        CHECK(pos(p, "test_stage") < pos(p, "springs"));
        for (int n = 0; n < 7; ++n)
            cloth.step(0.001);
        CHECK(stage->runs == 7);
        CHECK(stage->lastDt == 0.001);
        CHECK(stage->stepsSeen == 7u); // runs inside step 8 (count 7 before it completes)
        CHECK(calls(cloth, "test_stage") == 7u);
        CHECK(calls(cloth, "contact_penalty") == 8u); // one refresh after the edit + 7 steps
        cloth.removeStage(stage.get());
        CHECK_FALSE(has(cloth.pipeline(), "test_stage"));
        cloth.step(0.001);
        CHECK(stage->runs == 7);
    }
}

TEST_CASE("Phase timers count calls", "[pipeline][timers]") {
    const int N = 25;
    SECTION("Velocity-Verlet: one force evaluation per step plus the first") {
        Cloth cloth(smallSheet(), basic());
        cloth.pin(0);
        for (int n = 0; n < N; ++n)
            cloth.step(0.001);
        CHECK(calls(cloth, "integrate") == static_cast<std::uint64_t>(N));
        CHECK(calls(cloth, "strain_limit") == static_cast<std::uint64_t>(N));
        CHECK(calls(cloth, "integrate_finish") == static_cast<std::uint64_t>(N));
        CHECK(calls(cloth, "forces_refresh") == 1u);
        CHECK(calls(cloth, "springs") == static_cast<std::uint64_t>(N + 1));
        CHECK(calls(cloth, "gravity") == static_cast<std::uint64_t>(N + 1));
        for (const PhaseTimer& t : cloth.timers().all())
            CHECK(t.seconds >= 0.0);
        // Every phase of the pipeline has a timer that ran on every step.
        for (const auto& name : cloth.pipeline())
            CHECK(calls(cloth, name) >= static_cast<std::uint64_t>(N));
        cloth.timers().reset();
        CHECK(calls(cloth, "integrate") == 0u);
    }
    SECTION("RK4: four force evaluations per step, the first one cached") {
        ClothSettings s = basic();
        s.integrator = IntegratorKind::RungeKutta4;
        Cloth cloth(smallSheet(), s);
        for (int n = 0; n < N; ++n)
            cloth.step(0.001);
        CHECK(calls(cloth, "springs") == static_cast<std::uint64_t>(1 + 4 * N));
    }
    SECTION("an edit between steps refreshes the forces once") {
        Cloth cloth(smallSheet(), basic());
        cloth.step(0.001);
        cloth.setPosition(7, cloth.positions()[7] + Vec3(0, 0, 0.01));
        CHECK(has(cloth.pipeline(), "forces_refresh"));
        cloth.step(0.001);
        CHECK(calls(cloth, "forces_refresh") == 2u);
        CHECK_FALSE(has(cloth.pipeline(), "forces_refresh"));
    }
}

TEST_CASE("Velocity-Verlet evaluates the aerodynamics once a step while nothing changes",
          "[pipeline][timers][aero]") {
    // The closing kick's aerodynamics serve the next opening kick (integrators.cpp): one
    // evaluation per step, plus one at the first step and after each change of the state or
    // the wind, and two per step with a damping flow (which moves the velocity in between).
    ClothSettings s = basic();
    s.relativeDamping = 0.0;
    s.aero.airDensity = 1.2;
    s.aero.wind = Vec3(1.0, 0.0, 0.5);
    Cloth cloth(smallSheet(), s);
    cloth.pin(0);
    for (int k = 0; k < 10; ++k)
        cloth.step(0.002);
    CHECK(calls(cloth, "aero") == 11);
    cloth.setWind(Vec3(2.0, 0.0, 0.5));
    cloth.step(0.002);
    CHECK(calls(cloth, "aero") == 13);
    cloth.setVelocity(3, cloth.velocities()[3]);
    cloth.step(0.002);
    cloth.step(0.002);
    CHECK(calls(cloth, "aero") == 16);
    // The default relative damping acts once per 1/60 s: each time, the next step evaluates
    // both kicks' aerodynamics.
    cloth.setRelativeDamping(kDefaultRelativeDamping);
    cloth.timers().reset();
    const int steps = 50; // 0.1 s: six intervals of the relative damping
    for (int k = 0; k < steps; ++k)
        cloth.step(0.002);
    CHECK(calls(cloth, "aero") >= steps + 6);
    CHECK(calls(cloth, "aero") <= steps + 8);
    s.damping = 1e-3;
    Cloth damped(smallSheet(), s);
    for (int k = 0; k < 10; ++k)
        damped.step(0.002);
    CHECK(calls(damped, "aero") == 20);
}

TEST_CASE("Phase timers measure thread CPU time when asked", "[pipeline][timers]") {
    PhaseTimers timers;
    const std::size_t sleeping = timers.slot("sleeping");
    const std::size_t working = timers.slot("working");
    {
        ScopedPhase p(timers, sleeping);
        std::this_thread::sleep_for(std::chrono::milliseconds(30));
    }
    CHECK(timers.all()[sleeping].seconds >= 0.03);
    CHECK(timers.all()[sleeping].cpuSeconds == 0.0); // off by default
    timers.measureThreadCpuTime(true);
    timers.reset();
    {
        ScopedPhase p(timers, sleeping);
        std::this_thread::sleep_for(std::chrono::milliseconds(30));
    }
    // A sleeping thread uses (almost) no CPU: wall time counts the 30 ms, CPU time does not.
    CHECK(timers.all()[sleeping].seconds >= 0.03);
    CHECK(timers.all()[sleeping].cpuSeconds < 0.01);
    {
        ScopedPhase p(timers, working);
        const double until = threadCpuSeconds() + 0.02; // spin until 20 ms of CPU are used
        volatile double sink = 0.0;
        while (threadCpuSeconds() < until)
            sink = sink + 1.0;
    }
    CHECK(timers.all()[working].cpuSeconds >= 0.02);
    CHECK(timers.all()[working].seconds >= timers.all()[working].cpuSeconds * 0.9);
    // A cloth's own phases: CPU time is counted for each.
    Cloth cloth(smallSheet(), basic());
    cloth.timers().measureThreadCpuTime(true);
    for (int n = 0; n < 20; ++n)
        cloth.step(0.001);
    double cpu = 0.0;
    for (const PhaseTimer& t : cloth.timers().all())
        cpu += t.cpuSeconds;
    CHECK(cpu > 0.0);
}

TEST_CASE("Same input, same output", "[pipeline][determinism]") {
    auto run = [] {
        SheetSpec spec;
        spec.rows = 12;
        spec.cols = 12;
        spec.spacing = 10.0;
        ClothSettings s;
        s.particleMass = 0.5;
        s.springStiffness = 20.0;
        s.gravity = Vec3(0, -9.8, 0);
        auto cloth = std::make_unique<Cloth>(ClothTopology::build(makeSheet(spec)), s);
        cloth->pin(0);
        cloth->pin(11);
        for (int n = 0; n < 100; ++n)
            cloth->step(0.01);
        return cloth;
    };
    const auto a = run(), b = run();
    CHECK(a->positions() == b->positions()); // bit for bit
    CHECK(a->velocities() == b->velocities());
}

namespace {
/// A stage that does nothing: its presence alone makes the step check the strain limit in its
/// own pass instead of inside the force evaluation.
class IdleStage final : public ClothStage {
  public:
    std::string name() const override { return "idle"; }
    void run(Cloth&, double) override {}
};
} // namespace

TEST_CASE("A caller stage that does nothing changes nothing in the step", "[pipeline][limiter]") {
    // Experiment I material on a 12 x 12 sheet: idle limiter at first, then the sheet
    // stretches onto the limit (limiter active). A cloth with an idle caller stage runs the
    // same stages plus that one; both must end in the same state, bit for bit.
    SheetSpec spec;
    spec.rows = 12;
    spec.cols = 12;
    spec.spacing = 10.0;
    spec.vAxis = Vec3(0, -1, 0);
    ClothSettings s;
    s.particleMass = 0.5;
    s.springStiffness = 20.0;
    s.gravity = Vec3(0, -9.8, 0);
    s.damping = 0.05;
    const auto topo = ClothTopology::build(makeSheet(spec));
    Cloth folded(topo, s), separate(topo, s);
    separate.addStage(std::make_shared<IdleStage>());
    for (Cloth* c : {&folded, &separate}) {
        c->pin(sheetIndex(spec, 0, 0));
        c->pin(sheetIndex(spec, 0, 11));
    }
    int idleSteps = 0, activeSteps = 0;
    for (int n = 0; n < 300; ++n) {
        folded.step(0.01);
        separate.step(0.01);
        (folded.lastLimiterStats().rounds == 0 ? idleSteps : activeSteps) += 1;
        REQUIRE(folded.lastLimiterStats().rounds == separate.lastLimiterStats().rounds);
    }
    INFO("idle steps " << idleSteps << ", active steps " << activeSteps);
    CHECK(idleSteps > 10);
    CHECK(activeSteps > 10);
    CHECK(folded.positions() == separate.positions());
    CHECK(folded.velocities() == separate.velocities());
    CHECK(folded.lastLimiterStats().maxStrainBefore == separate.lastLimiterStats().maxStrainBefore);
}
