// Wrong use of a cloth's API gets a drape::Error that names the problem and the fix, never a
// crash, a hang or a silent NaN: resized state vectors, calls from inside the cloth's own step,
// snapshot files that are not regular files, values out of an enum's range.
#include "helpers.hpp"

#include "drape/cloth.hpp"
#include "drape/snapshot.hpp"

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
