// Wrong use of drape::bullet's handle that a new user's program makes (bullet_cloth.hpp): the
// world destroyed first, a body removed and deleted while particles hang from it, one cloth
// added twice, an attachment to a body in no world. Each ends in a drape::Error that names
// the problem or in a documented no-op, never in freed memory (the sanitizer run checks that).
#include "world_fixture.hpp"

#include "drape/error.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <utility>

using namespace drape;
using namespace drape::testing;

namespace {

/// A world of its own (not TestWorld): the tests destroy it while handles live.
struct BareWorld {
    btDefaultCollisionConfiguration config;
    btCollisionDispatcher dispatcher{&config};
    btDbvtBroadphase broadphase;
    btSequentialImpulseConstraintSolver solver;
    std::unique_ptr<btDiscreteDynamicsWorld> world =
        std::make_unique<btDiscreteDynamicsWorld>(&dispatcher, &broadphase, &solver, &config);
};

} // namespace

TEST_CASE("a world destroyed before its cloth's handle: the handle notices and stays safe",
          "[world][wrong_use]") {
    BareWorld b;
    auto cloth = makeCloth(horizontalSheet(5, 5, 0.1, 1.0), softCloth());
    auto handle = bullet::addCloth(b.world.get(), cloth);
    b.world->stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0));
    REQUIRE(handle->inWorld());
    b.world.reset(); // the user's mistake
    CHECK_FALSE(handle->inWorld());
    CHECK_THROWS_WITH(handle->stepInWorld(1.0 / 60.0), Catch::Contains("world destroyed"));
    CHECK_THROWS_WITH(handle->attach(0, nullptr, Vec3::Zero()), Catch::Contains("destroyed"));
    handle->remove(); // touches nothing of the gone world
    CHECK_FALSE(handle->inWorld());
    handle.reset();
    // The cloth itself is intact and can join a new world.
    BareWorld again;
    auto second = bullet::addCloth(again.world.get(), cloth);
    CHECK(second->inWorld());
    second.reset();
}

TEST_CASE("one cloth in one world once: a second addCloth is refused until the first leaves",
          "[world][wrong_use]") {
    TestWorld w;
    TestWorld other;
    auto cloth = makeCloth(horizontalSheet(5, 5, 0.1, 1.0), softCloth());
    auto first = bullet::addCloth(&w.world, cloth);
    CHECK_THROWS_WITH(bullet::addCloth(&w.world, cloth), Catch::Contains("already in a world"));
    CHECK_THROWS_WITH(bullet::addCloth(&other.world, cloth), Catch::Contains("already in a world"));
    // The refused calls changed nothing: one handle steps the cloth, its sub-steps once.
    const std::uint64_t before = cloth->stepCount();
    w.world.stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0));
    CHECK(cloth->stepCount() == before + std::uint64_t(first->lastStats().substeps));
    first->remove();
    auto second = bullet::addCloth(&other.world, cloth);
    CHECK(second->inWorld());
}

TEST_CASE("attaching to a body that is not in the cloth's world is refused", "[world][wrong_use]") {
    TestWorld w;
    TestWorld elsewhere;
    auto cloth = makeCloth(horizontalSheet(5, 5, 0.1, 1.0), softCloth());
    auto& handle = w.add(cloth);
    btRigidBody* there =
        elsewhere.body(elsewhere.shape<btSphereShape>(btScalar(0.1)), 1.0, Vec3(0.0, 1.0, 0.0));
    CHECK_THROWS_WITH(handle.attachHere(3, there), Catch::Contains("not in the cloth's world"));
    btSphereShape shape(btScalar(0.1));
    btDefaultMotionState motion;
    btRigidBody loose(btRigidBody::btRigidBodyConstructionInfo(1.0f, &motion, &shape));
    CHECK_THROWS_WITH(handle.attachHere(3, &loose), Catch::Contains("not in the cloth's world"));
    CHECK(handle.attachments().empty());
    CHECK_FALSE(cloth->isPinned(3));
}

TEST_CASE("attaching to a cloth's proxy (a ghost object) is refused", "[world][wrong_use]") {
    TestWorld w;
    auto cloth = makeCloth(horizontalSheet(5, 5, 0.1, 1.0), softCloth());
    auto& handle = w.add(cloth);
    auto other = makeCloth(horizontalSheet(5, 5, 0.1, 2.0), softCloth());
    auto& otherHandle = w.add(other);
    w.world.stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0));
    CHECK_THROWS_WITH(handle.attachHere(3, handle.proxyObject()),
                      Catch::Contains("not a rigid body or collision object"));
    CHECK_THROWS_WITH(handle.attach(3, otherHandle.proxyObject(), Vec3::Zero()),
                      Catch::Contains("not a rigid body or collision object"));
    CHECK(handle.attachments().empty());
    CHECK_FALSE(cloth->isPinned(3));
}

TEST_CASE("a body with a non-finite position or velocity near the cloth is named, and the cloth "
          "keeps its state",
          "[world][wrong_use]") {
    for (int which = 0; which < 2; ++which) {
        TestWorld w;
        auto cloth = makeCloth(horizontalSheet(5, 5, 0.1, 1.0), softCloth());
        w.add(cloth);
        btRigidBody* ball = w.body(w.shape<btSphereShape>(btScalar(0.1)), 1.0, Vec3(0.2, 1.1, 0.2));
        w.world.stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0));
        const Vec3List before = cloth->positions();
        const btScalar nan = std::numeric_limits<btScalar>::quiet_NaN();
        if (which == 0)
            ball->setLinearVelocity(btVector3(0, nan, 0));
        else
            ball->getWorldTransform().setOrigin(btVector3(0.2f, nan, 0.2f));
        INFO((which == 0 ? "velocity" : "position") << " NaN");
        CHECK_THROWS_WITH(w.world.stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0)),
                          Catch::Contains("SPHERE") && Catch::Contains("not finite"));
        for (std::size_t i = 0; i < before.size(); ++i)
            CHECK(cloth->positions()[i] == before[i]);
    }
}

TEST_CASE("a body removed and deleted while particles hang from it: the next step detaches them "
          "and says so",
          "[world][wrong_use]") {
    TestWorld w;
    auto cloth = makeCloth(horizontalSheet(5, 5, 0.1, 1.0), softCloth());
    auto& handle = w.add(cloth);
    btSphereShape shape(btScalar(0.05));
    btDefaultMotionState motion(btTransform(btQuaternion::getIdentity(), btVector3(0, 1, 0)));
    btVector3 inertia;
    shape.calculateLocalInertia(1.0f, inertia);
    auto body = std::make_unique<btRigidBody>(
        btRigidBody::btRigidBodyConstructionInfo(1.0f, &motion, &shape, inertia));
    w.world.addRigidBody(body.get());
    // Bodies after it in the world's list: removing it moves the last one into its place (the
    // step looks the attachment bodies up where it found them last).
    btDefaultMotionState farMotion(btTransform(btQuaternion::getIdentity(), btVector3(5, 1, 0)));
    btRigidBody after(btRigidBody::btRigidBodyConstructionInfo(0.0f, &farMotion, &shape));
    const bool behind = GENERATE(false, true);
    if (behind) w.world.addRigidBody(&after);
    handle.attachHere(0, body.get());
    handle.attachHere(4, body.get());
    w.world.stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0));
    REQUIRE(handle.attachments().size() == 2);
    // Taken out and put back (now later in the list) it is still in the world: no word.
    w.world.removeRigidBody(body.get());
    w.world.addRigidBody(body.get());
    CHECK_NOTHROW(w.world.stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0)));
    CHECK(handle.attachments().size() == 2);
    if (behind) { // moved behind `after`: taken out again, `after` moves into its place
        w.world.removeRigidBody(&after);
        w.world.addRigidBody(&after);
    }
    w.world.removeRigidBody(body.get()); // the user's mistake: no detach first
    body.reset();
    CHECK_THROWS_WITH(w.world.stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0)),
                      Catch::Contains("particle(s) 0, 4") && Catch::Contains("detach"));
    CHECK(handle.attachments().empty());
    CHECK_FALSE(cloth->isPinned(0));
    CHECK_FALSE(cloth->isPinned(4));
    // The world steps on; the freed particles fall.
    const double y0 = cloth->positions()[0].y();
    for (int k = 0; k < 10; ++k)
        w.world.stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0));
    CHECK(cloth->positions()[0].y() < y0);
    if (behind) w.world.removeRigidBody(&after);
}

TEST_CASE("BulletClothSettings::inUnits refuses a unit outside [1e-6, 1e6]",
          "[world][wrong_use][units]") {
    for (double bad : {0.0, -100.0, 1e7, std::numeric_limits<double>::quiet_NaN()})
        CHECK_THROWS_WITH(bullet::BulletClothSettings::inUnits(bad),
                          Catch::Contains("unitsPerMetre must be in [1e-6, 1e6]"));
    const auto cm = bullet::BulletClothSettings::inUnits(100.0);
    CHECK(cm.contact.thickness == Approx(1.0));
    CHECK(cm.selfCollision.thickness == Approx(1.0));
    CHECK(cm.unitsPerMetre == 100.0);
    // Set by hand out of range: addCloth refuses it by name.
    TestWorld w;
    bullet::BulletClothSettings bad;
    bad.unitsPerMetre = 0.0;
    CHECK_THROWS_WITH(w.add(makeCloth(horizontalSheet(3, 3, 0.1, 1.0), softCloth()), bad),
                      Catch::Contains("unitsPerMetre must be in [1e-6, 1e6]"));
}

TEST_CASE("unitsPerMetre set without converting the lengths is refused by name",
          "[world][wrong_use][units]") {
    // A centimetre world that sets only unitsPerMetre would keep a 0.01-unit (0.1 mm) contact
    // thickness: refused, naming inUnits. Starting from inUnits, or setting a length in the
    // world's units, is accepted.
    TestWorld w;
    bullet::BulletClothSettings trap;
    trap.unitsPerMetre = 100.0;
    CHECK_THROWS_WITH(w.add(makeCloth(horizontalSheet(3, 3, 10.0, 100.0), softCloth()), trap),
                      Catch::Contains("inUnits(100)"));
    CHECK_NOTHROW(w.add(makeCloth(horizontalSheet(3, 3, 10.0, 100.0), softCloth()),
                        bullet::BulletClothSettings::inUnits(100.0)));
    // Every length and speed must be in the world's units: with only the thickness set, the
    // teleport speed stayed 50 units/s, 0.5 m/s in centimetres (review 16: a character walking
    // at 1.5 m/s was taken as jumping in every sub-step).
    bullet::BulletClothSettings byHand;
    byHand.unitsPerMetre = 100.0;
    byHand.contact.thickness = 1.0;
    CHECK_THROWS_WITH(w.add(makeCloth(horizontalSheet(3, 3, 10.0, 100.0), softCloth()), byHand),
                      Catch::Contains("teleportSpeed (50)") &&
                          Catch::Contains("contact.depenetrationSpeed") &&
                          !Catch::Contains("contact.thickness"));
    const bullet::BulletClothSettings converted = bullet::BulletClothSettings::inUnits(100.0);
    byHand.contact.depenetrationSpeed = converted.contact.depenetrationSpeed;
    byHand.teleportSpeed = converted.teleportSpeed;
    byHand.selfCollision.thickness = converted.selfCollision.thickness;
    byHand.clothCollision.thickness = converted.clothCollision.thickness;
    CHECK_NOTHROW(w.add(makeCloth(horizontalSheet(3, 3, 10.0, 100.0), softCloth()), byHand));
    // One value equal to its metre default is a choice in the world's unit (a scene in
    // centimetres that gives a 0.01 thickness, 0.1 mm): accepted (review 17).
    bullet::BulletClothSettings thin = bullet::BulletClothSettings::inUnits(100.0);
    thin.contact.thickness = 0.01;
    CHECK_NOTHROW(w.add(makeCloth(horizontalSheet(3, 3, 10.0, 100.0), softCloth()), thin));
}

namespace {
/// A caller stage that runs `act` once, in the cloth's first step after it was added.
struct OnceStage final : ClothStage {
    std::function<void()> act;
    explicit OnceStage(std::function<void()> a) : act(std::move(a)) {}
    std::string name() const override { return "once"; }
    void run(Cloth&, double) override {
        if (act) std::exchange(act, nullptr)();
    }
};
} // namespace

TEST_CASE("a cloth's handle removed or destroyed inside the world's step leaves the world safely",
          "[world][wrong_use]") {
    // A stage of cloth A (running inside stepSimulation) destroys cloth B's handle, removes
    // A's own handle, or destroys it: the handle leaves the world at once, the step's loops
    // pass over it (before: freed memory read, or the stepper freed while it ran), the other
    // cloth steps on, and the world steps on after.
    for (int how = 0; how < 4; ++how) {
        INFO("case " << how);
        BareWorld b;
        b.world->setGravity(btVector3(0, -9.81f, 0));
        auto a = makeCloth(horizontalSheet(5, 5, 0.1, 1.0), softCloth());
        auto c = makeCloth(horizontalSheet(5, 5, 0.1, 1.0, 2.0), softCloth());
        auto ha = bullet::addCloth(b.world.get(), a);
        auto hc = bullet::addCloth(b.world.get(), c);
        std::function<void()> act;
        if (how == 0) act = [&] { hc.reset(); };
        if (how == 1) act = [&] { ha->remove(); };
        if (how == 2) act = [&] { ha.reset(); };
        if (how == 3)
            act = [&] { // removed, then destroyed, in the same step
                ha->remove();
                ha.reset();
            };
        a->addStage(std::make_shared<OnceStage>(act));
        for (int k = 0; k < 5; ++k)
            b.world->stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0));
        // (Cloth steps per world step: lastStats().substeps; the cloths step in the order
        // they were added, so C's first step comes after A's.)
        if (how == 0) {
            CHECK(hc == nullptr);
            CHECK(ha->inWorld());
            CHECK(a->stepCount() == 5u * std::uint64_t(ha->lastStats().substeps)); // stepped on
            CHECK(c->stepCount() == 0); // gone before its first step
        } else {
            CHECK((ha == nullptr || !ha->inWorld()));
            CHECK(hc->inWorld());
            CHECK(c->stepCount() == 5u * std::uint64_t(hc->lastStats().substeps));
            CHECK(a->stepCount() == 1); // the step it left in, then no more
        }
        // The cloths are finite and can join a world again.
        for (const auto& cl : {a, c})
            for (const Vec3& x : cl->positions())
                CHECK(x.allFinite());
        hc.reset();
        ha.reset();
        auto again = bullet::addCloth(b.world.get(), a);
        b.world->stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0));
        CHECK(again->inWorld());
    }
}

TEST_CASE("a hitch in Bullet's variable step beyond the cloth's sub-steps is refused with the "
          "world's remedy",
          "[world][wrong_use]") {
    // A 2 s frame given to stepSimulation with maxSubSteps 0 (Bullet's variable step) is one
    // world sub-step of 2 s: more cloth sub-steps than the cloth allows. The refusal says what
    // to change in the world's stepping (it said "use a smaller dt ... or implicit_euler";
    // review 18), and the remedy it names steps on.
    TestWorld w;
    auto cloth = makeCloth(horizontalSheet(21, 21, 0.05, 1.0), ClothSettings{});
    pinBorder(*cloth, 21);
    w.add(cloth);
    w.world.stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0));
    const double needed = 2.0 / cloth->stableTimeStep();
    REQUIRE(needed > cloth->settings().substeps.maxSubsteps);
    std::string message;
    try {
        w.world.stepSimulation(btScalar(2.0), 0);
    } catch (const Error& e) {
        CHECK(e.code() == ErrorCode::UnstableTimeStep);
        message = e.what();
    }
    INFO(message);
    CHECK_THAT(message, Catch::Contains("fixed sub-step") && Catch::Contains("maxSubSteps >= 1") &&
                            Catch::Contains("IntegratorKind::ImplicitEuler"));
    CHECK(message.find("implicit_euler") == std::string::npos);
    // The remedy: the same hitch as fixed sub-steps (Bullet drops what exceeds maxSubSteps).
    const double t0 = cloth->time();
    CHECK_NOTHROW(w.world.stepSimulation(btScalar(2.0), 10, btScalar(1.0 / 60.0)));
    CHECK(cloth->time() == Approx(t0 + 10.0 / 60.0).epsilon(1e-6));
    for (const Vec3& x : cloth->positions())
        CHECK(x.allFinite());
}

TEST_CASE("a fixed count of cloth steps that the drag's limit refuses is named in the world's "
          "terms",
          "[world][wrong_use][aero]") {
    // ClothSettings::substeps.automatic off, BulletClothSettings::substeps 2, a sheet in water:
    // the cloth's own refusal said "2 sub-steps of this step", not a world setting (review
    // 19). The refusal names the count to set.
    TestWorld w;
    ClothSettings cs;
    cs.totalMass = 0.05;
    cs.springStiffness = 20.0;
    cs.aero.airDensity = 1000.0;
    cs.substeps.automatic = false;
    auto cloth = makeCloth(horizontalSheet(6, 6, 0.1, 1.0), cs);
    bullet::BulletClothSettings s;
    s.substeps = 4;
    w.add(cloth, s);
    REQUIRE(cloth->stableTimeStep() > 1.0 / 240.0);
    std::string message;
    try {
        for (int f = 0; f < 60; ++f)
            w.world.stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0));
    } catch (const Error& e) {
        CHECK(e.code() == ErrorCode::UnstableTimeStep);
        message = e.what();
    }
    INFO(message);
    CHECK_THAT(message, Catch::Contains("BulletClothSettings::substeps to at least") &&
                            Catch::Contains("drag"));
    for (const Vec3& x : cloth->positions())
        CHECK(x.allFinite());
}

TEST_CASE("a fixed world step beyond the cloth's maxSubsteps names the cloth's count, not a hitch",
          "[world][wrong_use]") {
    // At the program's own fixed 1/60 s step, "clamp the frame time a hitch gives it" does not
    // help (review 19): the cloth's maxSubsteps or a smaller fixed step does.
    TestWorld w;
    ClothSettings cs;
    cs.substeps.maxSubsteps = 4;
    auto cloth = makeCloth(horizontalSheet(21, 21, 0.05, 1.0), cs);
    w.add(cloth);
    std::string message;
    try {
        w.world.stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0));
    } catch (const Error& e) {
        message = e.what();
    }
    INFO(message);
    CHECK_THAT(message, Catch::Contains("larger ClothSettings::substeps.maxSubsteps"));
    CHECK(message.find("hitch") == std::string::npos);
}

TEST_CASE("BulletClothSettings::substeps beyond the cloth's maxSubsteps is refused by name",
          "[world][wrong_use]") {
    TestWorld w;
    auto cloth = makeCloth(horizontalSheet(3, 3, 0.1, 1.0), softCloth());
    const int limit = cloth->settings().substeps.maxSubsteps;
    bullet::BulletClothSettings s;
    // 100000 cloth steps per Bullet sub-step used to be accepted (a minute-long world step).
    for (int bad : {limit + 1, 100000}) {
        s.substeps = bad;
        CHECK_THROWS_AS(w.add(cloth, s), Error);
        CHECK_THROWS_WITH(w.add(cloth, s),
                          Catch::Contains("substeps (" + std::to_string(bad)) &&
                              Catch::Contains("substeps.maxSubsteps (" + std::to_string(limit)));
    }
    s.substeps = limit; // the bound itself is allowed
    auto& handle = w.add(cloth, s);
    CHECK(handle.inWorld());
}

TEST_CASE("a count of cloth steps below the stability limit names the count that is stable, "
          "and the cloth's own sub-steps are counted in lastStats",
          "[world][wrong_use][substeps]") {
    // Review 15: with the cloth's automatic sub-steps off, a BulletClothSettings::substeps of
    // 3 was refused with "use 4 sub-steps" (the cloth's steps of the handle's step), 4 with
    // "3", 9 with "2": following the advice led to another refusal. A 31 x 31 sheet at 5 cm
    // (the default cotton) needs 10 steps of a 1/60 s Bullet sub-step.
    auto sheet = [] {
        ClothSettings cs;
        cs.substeps.automatic = false;
        return makeCloth(horizontalSheet(31, 31, 0.05, 1.0), cs);
    };
    const double dt = double(btScalar(1.0 / 60.0)); // what Bullet hands the cloth
    auto step = [](TestWorld& w) {
        w.world.stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0));
    };
    const auto probe = sheet();
    const int needed = static_cast<int>(std::ceil(dt / probe->stableTimeStep()));
    INFO("stable count " << needed);
    REQUIRE(needed > 2);
    for (const std::optional<int> count :
         {std::optional<int>(), std::optional<int>(1), std::optional<int>(needed - 1)}) {
        TestWorld w;
        bullet::BulletClothSettings s;
        s.substeps = count;
        w.add(sheet(), s);
        CHECK_THROWS_WITH(step(w), Catch::Contains("set BulletClothSettings::substeps to at "
                                                   "least " +
                                                   std::to_string(needed)));
    }
    {
        // The count it names is stable.
        TestWorld w;
        bullet::BulletClothSettings s;
        s.substeps = needed;
        auto cloth = sheet();
        auto& handle = w.add(cloth, s);
        for (int f = 0; f < 30; ++f)
            CHECK_NOTHROW(step(w));
        CHECK(handle.lastStats().substeps == needed);
        CHECK(cloth->stepCount() == std::uint64_t(30 * needed));
    }
    {
        // A count beyond the cloth's maxSubsteps: addCloth would refuse it, and the cloth's
        // settings are fixed when it is made; the refusal says so, and a cloth made with a
        // larger maxSubsteps takes that count (review 16: "at least 1169", then "raise
        // maxSubsteps" from addCloth, on the cloth already made).
        ClothSettings stiff;
        stiff.substeps.automatic = false;
        stiff.springStiffness = 1e6;
        const auto first = makeCloth(horizontalSheet(11, 11, 0.05, 1.0), stiff);
        const int count = static_cast<int>(std::ceil(dt / first->stableTimeStep()));
        INFO("stiff count " << count);
        REQUIRE(count > stiff.substeps.maxSubsteps);
        TestWorld w;
        w.add(first);
        CHECK_THROWS_WITH(step(w), Catch::Contains("at least " + std::to_string(count)) &&
                                       Catch::Contains("make it with a larger maxSubsteps"));
        stiff.substeps.maxSubsteps = count;
        bullet::BulletClothSettings s;
        s.substeps = count;
        TestWorld again;
        again.add(makeCloth(horizontalSheet(11, 11, 0.05, 1.0), stiff), s);
        CHECK_NOTHROW(step(again));
    }
    {
        // A given count with the cloth's automatic sub-steps on: the cloth splits each step
        // further, and lastStats says how many steps it took in all.
        TestWorld w;
        bullet::BulletClothSettings s;
        s.substeps = 1;
        auto cloth = makeCloth(horizontalSheet(31, 31, 0.05, 1.0), ClothSettings{});
        auto& handle = w.add(cloth, s);
        auto integrations = [&cloth] {
            const PhaseTimer* t = cloth->timers().find("integrate");
            return t ? t->calls : std::uint64_t(0);
        };
        const std::uint64_t before = integrations();
        step(w);
        CHECK(handle.lastStats().substeps == cloth->substepsFor(dt));
        CHECK(handle.lastStats().substeps > 1);
        CHECK(integrations() - before == std::uint64_t(handle.lastStats().substeps));
    }
}

TEST_CASE("the cloth's proxy taken out of the world by the program: the step says so, the "
          "handle's removal is safe",
          "[world][wrong_use]") {
    // proxyObject() is const for a reason; a program that casts that away and removes the
    // ghost from the world crashed the next step (its box updated outside the broadphase),
    // and the handle's removal then left its stepper in the world, freed.
    TestWorld w;
    w.world.setGravity(btVector3(0, -9.81f, 0));
    auto cloth = makeCloth(horizontalSheet(5, 5, 0.1, 1.0), softCloth());
    auto handle = bullet::addCloth(&w.world, cloth);
    w.world.stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0));
    w.world.removeCollisionObject(const_cast<btCollisionObject*>(handle->proxyObject()));
    CHECK_THROWS_WITH(w.world.stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0)),
                      Catch::Contains("proxy") && Catch::Contains("removeCloth"));
    CHECK_FALSE(handle->inWorld());
    // Said once: until the program removes the handle, the world steps on without the cloth
    // (before, every later step threw, and the world's bodies stopped with it), and the
    // cloth stays where it was.
    btRigidBody* ball = w.body(w.shape<btSphereShape>(btScalar(0.1)), 1.0, Vec3(3, 2, 0));
    const Vec3 before = cloth->positions()[12];
    for (int k = 0; k < 3; ++k)
        CHECK_NOTHROW(w.world.stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0)));
    CHECK(ball->getLinearVelocity().y() < -0.4f); // three steps of falling: -0.49 m/s
    CHECK(cloth->positions()[12] == before);
    CHECK_FALSE(handle->inWorld());
    handle.reset();
    // The world steps on without the cloth; the cloth can join it again.
    for (int k = 0; k < 3; ++k)
        w.world.stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0));
    auto again = bullet::addCloth(&w.world, cloth);
    w.world.stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0));
    CHECK(again->inWorld());
    CHECK(cloth->positions()[12].y() < 1.0);
}
