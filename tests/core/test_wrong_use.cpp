// Wrong use of a cloth's API gets a drape::Error that names the problem and the fix, never a
// crash, a hang or a silent NaN: resized state vectors, calls from inside the cloth's own step,
// snapshot files that are not regular files, values out of an enum's range.
#include "helpers.hpp"

#include "drape/cloth.hpp"
#include "drape/snapshot.hpp"

#include <functional>
#include <limits>
#include <memory>

using namespace drape;
using namespace drape_test;

namespace {

constexpr double kDt = 1.0 / 60.0;

std::unique_ptr<Cloth> smallSheet(const ClothSettings& s = {}) {
    SheetSpec spec;
    spec.rows = 6;
    spec.cols = 6;
    spec.spacing = 0.1;
    return std::make_unique<Cloth>(ClothTopology::build(makeSheet(spec)), s);
}

} // namespace

TEST_CASE("Resized positions or velocities are refused by step and saveSnapshot, by name",
          "[errors][wrong-use]") {
    auto c = smallSheet();
    c->step(kDt);
    const std::size_t n = c->particleCount();
    REQUIRE(n == 36);

    SECTION("positions shrunk, cleared or grown") {
        const Vec3List keep = c->positions();
        for (std::size_t size : {std::size_t(3), std::size_t(0), std::size_t(200)}) {
            c->mutablePositions().resize(size, Vec3::Zero());
            CHECK(c->particleCount() == n);
            REQUIRE_DRAPE_ERROR(c->step(kDt), ErrorCode::InvalidArgument, "positions");
            REQUIRE_DRAPE_ERROR(c->step(kDt), ErrorCode::InvalidArgument, "mutablePositions()");
            REQUIRE_DRAPE_ERROR(c->stepPart(kDt, 2), ErrorCode::InvalidArgument, "resize it back");
            REQUIRE_DRAPE_ERROR(saveSnapshot(*c), ErrorCode::InvalidArgument, "positions");
            c->mutablePositions() = keep;
        }
    }
    SECTION("velocities shrunk or grown") {
        const Vec3List keep = c->velocities();
        for (std::size_t size : {std::size_t(3), std::size_t(0), std::size_t(200)}) {
            c->mutableVelocities().resize(size, Vec3::Zero());
            REQUIRE_DRAPE_ERROR(c->step(kDt), ErrorCode::InvalidArgument, "mutableVelocities()");
            REQUIRE_DRAPE_ERROR(saveSnapshot(*c), ErrorCode::InvalidArgument, "velocities");
            c->mutableVelocities() = keep;
        }
    }
    SECTION("a stage that resizes them fails the step, which is then undone") {
        struct Resizer : ClothStage {
            bool on = true;
            std::string name() const override { return "resizer"; }
            void run(Cloth& cloth, double) override {
                if (on) cloth.mutablePositions().resize(3);
            }
        };
        auto stage = std::make_shared<Resizer>();
        c->addStage(stage);
        const std::uint64_t before = stateHash(*c);
        REQUIRE_DRAPE_ERROR(c->step(kDt), ErrorCode::InvalidArgument, "stage 'resizer'");
        CHECK(c->positions().size() == n);
        CHECK(stateHash(*c) == before);
        stage->on = false;
    }
    // Once the size is back, the cloth steps and saves as before.
    for (int k = 0; k < 3; ++k)
        c->step(kDt);
    CHECK(c->stepCount() == 4);
    for (const Vec3& x : c->positions())
        CHECK(x.allFinite());
    auto copy = smallSheet();
    loadSnapshot(*copy, saveSnapshot(*c));
    CHECK(stateHash(*copy) == stateHash(*c));
}

namespace {

/// A stage that runs a function of the cloth.
struct FnStage : ClothStage {
    explicit FnStage(std::string n, std::function<void(Cloth&)> f)
        : label(std::move(n)), fn(std::move(f)) {}
    std::string name() const override { return label; }
    void run(Cloth& cloth, double) override {
        ++runs;
        if (fn) fn(cloth);
    }
    std::string label;
    std::function<void(Cloth&)> fn;
    int runs = 0;
};

} // namespace

TEST_CASE("Calls that replace the state are refused from inside the cloth's own step",
          "[errors][wrong-use][stages]") {
    auto c = smallSheet();
    c->step(kDt);
    const auto saved = saveSnapshot(*c);
    const ClothState state = c->state();
    const std::vector<double> warm(c->limiter().warmStartState().begin(),
                                   c->limiter().warmStartState().end());
    int attempt = 0;
    auto stage = std::make_shared<FnStage>("reentrant", [&](Cloth& cloth) {
        CHECK(cloth.inStep());
        if (attempt == 1) cloth.step(kDt / 10); // used to recurse until the stack overflowed
        if (attempt == 2) cloth.stepPart(kDt / 10, 2);
        if (attempt == 3) loadSnapshot(cloth, saved); // used to be accepted mid-step
        if (attempt == 4) cloth.restoreState(state, warm);
        if (attempt == 5) cloth.setExecutor(nullptr);
    });
    c->addStage(stage);
    const char* names[] = {
        "", "Cloth::step", "Cloth::step", "loadSnapshot", "restoreState", "setExecutor"};
    for (attempt = 1; attempt <= 5; ++attempt) {
        INFO("attempt " << attempt);
        const std::uint64_t before = stateHash(*c);
        const std::uint64_t steps = c->stepCount();
        REQUIRE_DRAPE_ERROR(c->step(kDt), ErrorCode::InvalidArgument, names[attempt]);
        REQUIRE_DRAPE_ERROR(c->step(kDt), ErrorCode::InvalidArgument,
                            "not allowed during the cloth's own step (from a stage)");
        // The failed step is undone, and the cloth steps on once the stage behaves.
        CHECK(stateHash(*c) == before);
        CHECK(c->stepCount() == steps);
        CHECK_FALSE(c->inStep());
    }
    attempt = 0;
    c->step(kDt);
    CHECK(c->stepCount() == 2);
    CHECK_FALSE(c->inStep());
    // Outside a step the same calls are fine.
    loadSnapshot(*c, saved);
    CHECK(c->stepCount() == 1);
    c->restoreState(state, warm);
}

TEST_CASE("A stage that removes itself during the step does not make the next stage skip",
          "[wrong-use][stages]") {
    auto c = smallSheet();
    const int n = c->substepsFor(kDt); // a stage runs once per sub-step
    REQUIRE(n >= 1);
    // A's only owner is the cloth: removing itself used to free it while it ran, and the loop
    // skipped B for that step.
    auto b = std::make_shared<FnStage>("B", nullptr);
    {
        auto a = std::make_shared<FnStage>(
            "A", [](Cloth& cloth) { cloth.removeStage(cloth.stages().front().get()); });
        c->addStage(a);
    }
    c->addStage(b);
    c->step(kDt);
    CHECK(b->runs == n);
    REQUIRE(c->stages().size() == 1);
    CHECK(c->stages().front().get() == b.get());
    c->step(kDt);
    CHECK(b->runs == 2 * n);

    // A stage that removes a later one: that one does not run in the step.
    auto d = std::make_shared<FnStage>("D", nullptr);
    auto e = std::make_shared<FnStage>("E", nullptr);
    auto killer =
        std::make_shared<FnStage>("killer", [&](Cloth& cloth) { cloth.removeStage(d.get()); });
    c->addStage(killer);
    c->addStage(d);
    c->addStage(e);
    c->step(kDt);
    CHECK(b->runs == 3 * n);
    CHECK(d->runs == 0);
    CHECK(e->runs == n);
    CHECK(c->stages().size() == 3);
    CHECK(c->pipeline().size() > 0);
}
