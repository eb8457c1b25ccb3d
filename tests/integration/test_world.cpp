// The cloth in a Bullet world: one call in, one call out, stepped inside stepSimulation in
// every internal sub-step, bad input rejected with drape::Error, and the broadphase used.
#include "measured.hpp"
#include "world_fixture.hpp"

#include "drape/error.hpp"
#include "drape/snapshot.hpp"

#include <catch2/catch.hpp>

#include <oneapi/tbb/info.h>

#include <algorithm>
#include <atomic>
#include <limits>

using namespace drape;
using namespace drape::testing;

TEST_CASE("addCloth and removeCloth put the cloth into stepSimulation and take it out", "[world]") {
    TestWorld w;
    auto cloth = makeCloth(horizontalSheet(5, 5, 0.1, 1.0), softCloth());
    auto handle = bullet::addCloth(&w.world, cloth);
    REQUIRE(handle->inWorld());
    // Bullet's default gravity is replaced by the world's: the cloth uses -9.81 too.
    CHECK(cloth->settings().gravity.y() == Approx(-9.81).epsilon(1e-6));

    // stepSimulation(1/60, 10, 1/240) makes exactly 4 internal sub-steps of 1/240 s; the
    // cloth must take one step in each.
    const double fixed = 1.0 / 240.0;
    w.world.stepSimulation(btScalar(1.0 / 60.0), 10, btScalar(fixed));
    CHECK(cloth->stepCount() == 4);
    CHECK(cloth->time() == Approx(4 * fixed).epsilon(1e-5));
    // Free fall over those 4 steps: y drops by g t^2 / 2 (Velocity-Verlet is exact for a
    // constant force; float time steps limit the agreement to ~1e-6 relative).
    const double t = 4 * fixed;
    CHECK(cloth->positions()[0].y() == Approx(1.0 - 0.5 * 9.81 * t * t).epsilon(1e-6));

    bullet::removeCloth(*handle);
    CHECK_FALSE(handle->inWorld());
    w.world.stepSimulation(btScalar(1.0 / 60.0), 10, btScalar(fixed));
    CHECK(cloth->stepCount() == 4); // no longer stepped
    // The proxy left the broadphase.
    CHECK(w.world.getNumCollisionObjects() == 0);
}

TEST_CASE("bad input gets a drape::Error naming the problem", "[world][errors]") {
    TestWorld w;
    auto cloth = makeCloth(horizontalSheet(3, 3, 0.1, 1.0), softCloth());
    auto code = [](auto&& f) {
        try {
            f();
        } catch (const Error& e) {
            return e.code();
        }
        return ErrorCode::SimulationFailure; // "no error" marker, never expected below
    };
    CHECK(code([&] { bullet::addCloth(nullptr, cloth); }) == ErrorCode::InvalidArgument);
    CHECK(code([&] { bullet::addCloth(&w.world, nullptr); }) == ErrorCode::InvalidArgument);
    bullet::BulletClothSettings bad;
    bad.contact.thickness = -0.01;
    CHECK_THROWS_WITH(bullet::addCloth(&w.world, cloth, bad), Catch::Contains("thickness"));
    bad = {};
    bad.substeps = 0;
    CHECK_THROWS_WITH(bullet::addCloth(&w.world, cloth, bad), Catch::Contains("substeps"));
    bad = {};
    bad.contact.frictionScale = std::nan("");
    CHECK_THROWS_WITH(bullet::addCloth(&w.world, cloth, bad), Catch::Contains("frictionScale"));
    bad = {};
    bad.contact.penaltyForce = -1.0;
    CHECK_THROWS_WITH(bullet::addCloth(&w.world, cloth, bad), Catch::Contains("penaltyForce"));
    bad = {};
    bad.contact.broadphaseMargin = std::nan("");
    CHECK_THROWS_WITH(bullet::addCloth(&w.world, cloth, bad), Catch::Contains("broadphaseMargin"));
    bad = {};
    bad.timeStep = 0.0;
    CHECK_THROWS_WITH(bullet::addCloth(&w.world, cloth, bad), Catch::Contains("timeStep"));

    auto& handle = w.add(cloth);
    auto* box = w.body(w.shape<btBoxShape>(btVector3(0.1f, 0.1f, 0.1f)), 0.0, Vec3(0, 0, 0));
    CHECK(code([&] { handle.attach(9, box, Vec3::Zero()); }) == ErrorCode::IndexOutOfRange);
    CHECK_THROWS_WITH(handle.attach(9, box, Vec3::Zero()), Catch::Contains("particle 9"));
    CHECK(code([&] { handle.attach(0, nullptr, Vec3::Zero()); }) == ErrorCode::InvalidArgument);
    CHECK(code([&] { handle.attach(0, box, Vec3(std::nan(""), 0, 0)); }) == ErrorCode::NonFinite);
    CHECK(code([&] { handle.stepInWorld(-1.0); }) == ErrorCode::InvalidArgument);
    CHECK_THROWS_WITH(handle.setTimeStep(-0.01), Catch::Contains("timeStep"));
    CHECK_FALSE(handle.settings().timeStep.has_value()); // unchanged by the refused value

    // A body under the cloth with a negative Coulomb coefficient: the step refuses it by name,
    // and the cloth keeps its state.
    auto* under = w.body(w.shape<btBoxShape>(btVector3(0.5f, 0.1f, 0.5f)), 0.0, Vec3(0, 0.85, 0));
    under->setFriction(-0.2f);
    const Vec3List before = cloth->positions();
    CHECK_THROWS_WITH(handle.stepInWorld(0.005),
                      Catch::Contains("friction -0.2") && Catch::Contains("Box"));
    CHECK(cloth->positions() == before);
    under->setFriction(0.5f);
    CHECK_NOTHROW(handle.stepInWorld(0.005));
}

TEST_CASE("the cloth's candidates come from the broadphase: far bodies cost nothing",
          "[world][broadphase]") {
    // Same cloth, same fall, in three worlds: empty; with 1000 static and dynamic bodies far
    // away; with one box right under it. The counts of narrow-phase work must be identical
    // for the first two (zero: no rigid collider near, no collision work) and non-zero for
    // the third (so the counts do measure something).
    auto run = [](int farBodies, bool nearBox, bool triangles = false) {
        TestWorld w;
        auto* small = w.shape<btSphereShape>(btScalar(0.5));
        for (int k = 0; k < farBodies; ++k) {
            const double x = 100.0 + 3.0 * (k % 10), y = 3.0 * ((k / 10) % 10), z = 3.0 * (k / 100);
            w.body(small, (k % 2) ? 1.0 : 0.0, Vec3(x, y, z));
        }
        if (nearBox) w.body(w.shape<btBoxShape>(btVector3(1, 0.1f, 1)), 0.0, Vec3(0, 0.5, 0));
        auto cloth = makeCloth(horizontalSheet(10, 10, 0.1, 1.0), softCloth());
        bullet::BulletClothSettings bs;
        bs.substeps = 3; // 1/60 s is beyond this cloth's stability limit; 1/180 s is not
        bs.contact.triangles = triangles;
        auto& h = w.add(cloth, bs);
        bullet::ContactStats sum;
        for (int s = 0; s < 60; ++s) {
            w.world.stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0));
            sum.candidateBodies += h.lastStats().candidateBodies;
            sum.particleBoxTests += h.lastStats().particleBoxTests;
            sum.narrowphaseQueries += h.lastStats().narrowphaseQueries;
            sum.triangleQueries += h.lastStats().triangleQueries;
        }
        return sum;
    };
    const auto empty = run(0, false);
    const auto crowded = run(1000, false);
    const auto near = run(0, true);
    CHECK(empty.candidateBodies == 0);
    CHECK(empty.particleBoxTests == 0);
    CHECK(empty.narrowphaseQueries == 0);
    CHECK(crowded.candidateBodies == empty.candidateBodies);
    CHECK(crowded.particleBoxTests == empty.particleBoxTests);
    CHECK(crowded.narrowphaseQueries == empty.narrowphaseQueries);
    CHECK(near.candidateBodies > 0);
    CHECK(near.narrowphaseQueries > 0);
    // Triangle contacts too: nothing when no body is near, work when one is, none when off.
    const auto crowdedTriangles = run(1000, false, true);
    CHECK(crowdedTriangles.candidateBodies == 0);
    CHECK(crowdedTriangles.triangleQueries == 0);
    CHECK(near.triangleQueries == 0);
    CHECK(run(0, true, true).triangleQueries > 0);
}

TEST_CASE("collision filter groups and masks keep a body and the cloth apart, however fast they "
          "move",
          "[world][broadphase][filter]") {
    // The cloth's proxy is in group 1 with a mask without group 2 (BulletClothSettings::
    // collisionGroup, collisionMask): a body of group 2 is never touched, whether the
    // broadphase pairs it with the proxy (slow), the proxy's direct query finds it (a cloth
    // moving past its box) or the fast-body search does (a body crossing the box between two
    // sub-steps). Each case runs unfiltered too: the same motion is then stopped, so the
    // checks can fail.
    constexpr int kBodyGroup = 2;
    auto inGroup = [](TestWorld& w, btRigidBody* b) {
        w.world.removeRigidBody(b);
        w.world.addRigidBody(b, kBodyGroup, -1);
    };
    bullet::BulletClothSettings filtered;
    filtered.collisionMask = ~kBodyGroup;
    const bullet::BulletClothSettings unfiltered;

    SECTION("a ball thrown through a pinned net") {
        for (double speed : {1.0, 20.0}) {
            auto run = [&](const bullet::BulletClothSettings& bs) {
                TestWorld w(Vec3::Zero());
                auto cloth = makeCloth(horizontalSheet(21, 21, 0.05, 1.0), ClothSettings{});
                pinBorder(*cloth, 21);
                auto& h = w.add(cloth, bs);
                btRigidBody* ball = w.body(w.shape<btSphereShape>(btScalar(0.05)), 0.5,
                                           Vec3(0.0, 1.0 + 0.02 + 0.05 + speed / 60.0, 0.0));
                inGroup(w, ball);
                ball->setLinearVelocity(btVector3(0, btScalar(-speed), 0));
                std::size_t contacts = 0;
                for (int f = 0; f < 30; ++f) {
                    w.world.stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0));
                    contacts += h.lastStats().contacts;
                }
                return std::make_pair(double(ball->getLinearVelocity().y()), contacts);
            };
            const auto [free, freeContacts] = run(filtered);
            const auto [caught, caughtContacts] = run(unfiltered);
            INFO(speed << " m/s: filtered, leaves at " << free << " m/s after " << freeContacts
                       << " contacts; unfiltered " << caught << " m/s, " << caughtContacts);
            CHECK(freeContacts == 0);
            CHECK(free == Approx(-speed).epsilon(1e-6));
            CHECK(caughtContacts > 0);
            CHECK(caught > -0.9 * speed);
        }
    }
    SECTION("a cloth thrown onto a floor") {
        auto run = [&](const bullet::BulletClothSettings& bs) {
            TestWorld w;
            btRigidBody* floor =
                w.body(w.shape<btBoxShape>(btVector3(2, 0.1f, 2)), 0.0, Vec3(0.0, -0.1, 0.0));
            inGroup(w, floor);
            auto cloth = makeCloth(horizontalSheet(11, 11, 0.05, 0.5), ClothSettings{});
            for (Vec3& v : cloth->mutableVelocities())
                v = Vec3(0.0, -30.0, 0.0); // past the proxy's box in one sub-step
            auto& h = w.add(cloth, bs);
            std::size_t contacts = 0;
            for (int f = 0; f < 6; ++f) {
                w.world.stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0));
                contacts += h.lastStats().contacts;
            }
            double highest = -std::numeric_limits<double>::infinity();
            for (const Vec3& x : cloth->positions())
                highest = std::max(highest, x.y());
            return std::make_pair(highest, contacts);
        };
        const auto [through, throughContacts] = run(filtered);
        const auto [held, heldContacts] = run(unfiltered);
        INFO("filtered: highest particle " << through << " m after " << throughContacts
                                           << " contacts; unfiltered " << held << " m, "
                                           << heldContacts);
        CHECK(throughContacts == 0);
        CHECK(through < -0.2); // through the floor's 0.2 m
        CHECK(heldContacts > 0);
        CHECK(held > -0.01);
    }
}

TEST_CASE("sleeping nets in a world of many bodies catch a fast ball, and a game's trigger knows "
          "their proxies",
          "[world][broadphase][sleep]") {
    // The world's moving bodies are listed once per sub-step for all its cloths (review 18: a
    // pass over the world's objects per cloth made ten sleeping curtains in a level cost 1.7
    // ms a frame). A ball fast enough to cross a net's box between two sub-steps is still
    // found for whichever net it crosses, asleep or not, among static and resting bodies.
    TestWorld w(Vec3::Zero());
    // The broadphase's box of a dynamic body then covers its end only: the ball crossing the
    // net's box between two sub-steps is found by the look at the world's moving bodies.
    w.world.getDispatchInfo().m_useContinuous = false;
    auto* small = w.shape<btBoxShape>(btVector3(0.2f, 0.2f, 0.2f));
    for (int k = 0; k < 200; ++k) // far away: static and resting dynamic ones
        w.body(small, k % 2 ? 1.0 : 0.0, Vec3(50.0 + k, 0.0, 0.0));
    std::vector<std::shared_ptr<Cloth>> nets;
    std::vector<bullet::BulletCloth*> handles;
    for (int n = 0; n < 2; ++n) {
        auto cloth = makeCloth(horizontalSheet(21, 21, 0.05, 1.0), ClothSettings{});
        for (Vec3& x : cloth->mutablePositions())
            x.x() += 3.0 * n;
        pinBorder(*cloth, 21);
        handles.push_back(&w.add(cloth));
        nets.push_back(cloth);
    }
    for (int f = 0; f < 240 && !(nets[0]->isAsleep() && nets[1]->isAsleep()); ++f)
        w.world.stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0));
    REQUIRE(nets[0]->isAsleep());
    REQUIRE(nets[1]->isAsleep());
    // Each proxy's user pointer is its handle (a game's trigger can tell it from its own).
    for (bullet::BulletCloth* h : handles)
        CHECK(h->proxyObject()->getUserPointer() == h);
    const double speed = 60.0; // 1 m a sub-step, across the net's box between two of them
    btRigidBody* ball = w.body(w.shape<btSphereShape>(btScalar(0.05)), 0.5,
                               Vec3(3.0, 1.0 + 0.02 + 0.05 + 1.5 * speed / 60.0, 0.0));
    ball->setLinearVelocity(btVector3(0, btScalar(-speed), 0));
    for (int f = 0; f < 30; ++f)
        w.world.stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0));
    INFO("ball at y " << ball->getWorldTransform().getOrigin().y() << " m, v "
                      << ball->getLinearVelocity().y() << " m/s");
    CHECK(ball->getWorldTransform().getOrigin().y() > 0.5); // caught by the second net
    CHECK(ball->getLinearVelocity().y() > -0.9 * speed);
    CHECK_FALSE(nets[1]->isAsleep());
    CHECK(nets[0]->isAsleep()); // the other net was not touched
}

TEST_CASE("the README example runs as written", "[world][readme]") {
    TestWorld w;
    btDiscreteDynamicsWorld* world = &w.world;
    btRigidBody* pole =
        w.kinematic(w.shape<btCapsuleShapeX>(btScalar(0.02), btScalar(1.0)), Vec3(0, 1.5, 0));

    // --- README: "Putting a cloth into a Bullet world" ---------------------------------
    drape::SheetSpec sheet; // a 1 m x 1 m curtain in the x-y plane
    sheet.rows = 21;
    sheet.cols = 21;
    sheet.spacing = 0.05;            // m
    sheet.origin = {-0.5, 1.5, 0.0}; // top-left corner, m
    drape::ClothSettings settings;
    settings.totalMass = 0.3;        // kg
    settings.springStiffness = 20.0; // N/m
    auto cloth = std::make_shared<drape::Cloth>(
        drape::ClothTopology::build(drape::makeSheet(sheet)), settings);

    drape::bullet::BulletClothSettings options;
    options.contact.thickness = 0.005;                            // m
    options.substeps = 2;                                         // cloth steps per Bullet sub-step
    auto handle = drape::bullet::addCloth(world, cloth, options); // one call in
    for (drape::Index c = 0; c < sheet.cols; ++c)
        handle->attachHere(c, pole); // hang it

    for (int frame = 0; frame < 60; ++frame) {
        world->stepSimulation(1.0f / 60.0f, 10, 1.0f / 240.0f); // bodies and cloth together
        const std::vector<drape::Vec3>& x = cloth->positions(); // render from here
        (void)x;
    }
    drape::bullet::removeCloth(*handle); // one call out
    // -------------------------------------------------------------------------------------
    CHECK(cloth->stepCount() == 60 * 4 * 2);
    CHECK(cloth->positions()[20 * 21].y() < 1.5 - 0.9); // the curtain hangs down ~1 m
}

TEST_CASE("two cloths in one world, and a collider removed while the cloth lies on it", "[world]") {
    TestWorld w;
    btRigidBody* table =
        w.body(w.shape<btBoxShape>(btVector3(1, 0.05f, 1)), 0.0, Vec3(0, -0.05, 0));
    ClothSettings s = softCloth();
    s.damping = 0.01;
    auto a = makeCloth(horizontalSheet(5, 5, 0.1, 0.1, -0.5), s);
    auto b = makeCloth(horizontalSheet(5, 5, 0.1, 0.1, 0.5), s);
    bullet::BulletClothSettings bs;
    bs.substeps = 2;
    auto& ha = w.add(a, bs);
    auto& hb = w.add(b, bs);
    for (int k = 0; k < 120; ++k)
        w.world.stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0));
    // Each lies on the table (top at y = 0) in its contact band; neither sees the other's
    // proxy as a collider (only the table is a candidate).
    CHECK(a->positions()[12].y() > 0.0);
    CHECK(b->positions()[12].y() > 0.0);
    CHECK(a->positions()[12].y() < 0.03);
    CHECK(ha.lastStats().candidateBodies == 1);
    CHECK(hb.lastStats().candidateBodies == 1);
    // Take the table away: the broadphase drops it from both proxies, the cloths fall.
    w.world.removeRigidBody(table);
    for (int k = 0; k < 30; ++k)
        w.world.stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0));
    CHECK(ha.lastStats().candidateBodies == 0);
    CHECK(a->positions()[12].y() < -0.5); // 0.5 s of free fall: 1.2 m
    w.world.addRigidBody(table);          // back, so the fixture can remove it
}

TEST_CASE("same scene, same result: two runs are bit-identical", "[world][determinism]") {
    auto run = [] {
        TestWorld w;
        w.body(w.shape<btSphereShape>(btScalar(0.2)), 0.0, Vec3(0, 0, 0));
        btRigidBody* ball =
            w.body(w.shape<btSphereShape>(btScalar(0.1)), 0.3, Vec3(0.05, 0.6, 0.0));
        ball->setActivationState(DISABLE_DEACTIVATION);
        ClothSettings s = softCloth();
        auto cloth = makeCloth(horizontalSheet(9, 9, 0.05, 0.3), s);
        bullet::BulletClothSettings bs;
        bs.substeps = 3;
        bs.selfCollision.enabled = true;
        w.add(cloth, bs);
        for (int k = 0; k < 90; ++k)
            w.world.stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0));
        std::vector<Vec3> state = cloth->positions();
        state.push_back(eig(ball->getCenterOfMassPosition()));
        return state;
    };
    const auto a = run();
    const auto b = run();
    REQUIRE(a.size() == b.size());
    for (std::size_t i = 0; i < a.size(); ++i)
        CHECK(a[i] == b[i]); // exact equality
}

TEST_CASE("the cloths of a world stepped on several threads end bit-identical to one thread",
          "[world][determinism][threads]") {
    // Four cloths: two falling on a static sphere, two on a dynamic ball they share (its
    // impulses from both arrive in the cloths' order whatever the threads), one with
    // self-collision. threads = 1, 2 and 3 must give the same bits, ball included.
    auto run = [](int threads) {
        TestWorld w;
        w.body(w.shape<btSphereShape>(btScalar(0.2)), 0.0, Vec3(0, 0, 0));
        btRigidBody* ball =
            w.body(w.shape<btSphereShape>(btScalar(0.15)), 0.3, Vec3(2.0, 0.0, 0.0));
        ball->setActivationState(DISABLE_DEACTIVATION);
        ball->setGravity(btVector3(0, 0, 0));
        std::vector<std::shared_ptr<Cloth>> cloths;
        const Vec3 where[4] = {Vec3(0.05, 0.3, 0), Vec3(-0.05, 0.5, 0.02), Vec3(1.9, 0.3, 0),
                               Vec3(2.1, 0.35, 0.05)};
        for (int k = 0; k < 4; ++k) {
            auto cloth = makeCloth(
                horizontalSheet(9, 9, 0.05, where[k].y(), where[k].x(), where[k].z()), softCloth());
            bullet::BulletClothSettings bs;
            bs.threads = threads;
            bs.selfCollision.enabled = k == 1;
            w.add(cloth, bs);
            cloths.push_back(cloth);
        }
        for (int k = 0; k < 90; ++k)
            w.world.stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0));
        std::vector<Vec3> state;
        for (const auto& c : cloths) {
            state.insert(state.end(), c->positions().begin(), c->positions().end());
            state.insert(state.end(), c->velocities().begin(), c->velocities().end());
        }
        state.push_back(eig(ball->getCenterOfMassPosition()));
        state.push_back(eig(ball->getLinearVelocity()));
        return state;
    };
    const auto one = run(1);
    // The shared ball moved: the cloths pushed it.
    REQUIRE(one.back().norm() > 0.0);
    for (int threads : {2, 3}) {
        const auto many = run(threads);
        REQUIRE(many.size() == one.size());
        std::size_t differ = 0;
        for (std::size_t i = 0; i < one.size(); ++i)
            differ += one[i] != many[i]; // exact equality
        INFO(threads << " threads: " << differ << " of " << one.size() << " vectors differ");
        CHECK(differ == 0);
    }
}

namespace {
/// A program's own executor: runs every loop as one call on the calling thread, and counts.
class CountingExecutor final : public Executor {
  public:
    int concurrency() const override { return 1; }
    void parallelFor(std::size_t n, std::size_t, const Body& body) override {
        ++loops;
        if (n > 0) body(0, n);
    }
    std::atomic<std::size_t> loops{0};
};
} // namespace

TEST_CASE("cloths that ask for threads run their loops on the world's threads, same bits",
          "[world][determinism][threads]") {
    // Two 120 x 120 cloths that ask for threads (their loops split: drape/executor.hpp's
    // grain, nested in the per-cloth tasks) falling on a sphere, and a small one whose program
    // gave it an executor of its own, which the world must leave in place.
    const bool machineHasTwo = tbb::info::default_concurrency() > 1;
    auto run = [&](int threads) {
        TestWorld w;
        w.body(w.shape<btSphereShape>(btScalar(0.5)), 0.0, Vec3(0, 0, 0));
        ClothSettings cs = softCloth();
        cs.particleMass = 1e-3;
        cs.threads = threads;
        bullet::BulletClothSettings bs;
        bs.threads = threads;
        std::vector<std::shared_ptr<Cloth>> cloths;
        for (double cx : {-0.3, 0.3}) {
            cloths.push_back(makeCloth(horizontalSheet(120, 120, 0.005, 0.52, cx), cs));
            CHECK(cloths.back()->executor() == nullptr); // no pool before its first step
            w.add(cloths.back(), bs);
        }
        auto own = std::make_shared<CountingExecutor>();
        auto small = makeCloth(horizontalSheet(9, 9, 0.05, 0.6, 0.0, 0.5), cs);
        small->setExecutor(own);
        w.add(small, bs);
        for (int k = 0; k < 3; ++k)
            w.world.stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0));
        CHECK(small->executor() == own.get());
        CHECK(own->loops > 0);
        for (const auto& c : cloths) {
            // The world's arena, one set of threads for both levels (the cloth's own pool was
            // never started); none on one thread.
            CHECK(c->hasCallerExecutor() == (threads > 1 && machineHasTwo));
            if (c->hasCallerExecutor()) CHECK(c->executor()->concurrency() == threads);
            if (threads == 1) CHECK(c->executor() == nullptr);
        }
        CHECK(w.cloths.front()->lastStats().candidateBodies > 0); // it met the sphere
        std::vector<Vec3> state;
        for (const auto& c : cloths) {
            state.insert(state.end(), c->positions().begin(), c->positions().end());
            state.insert(state.end(), c->velocities().begin(), c->velocities().end());
        }
        // Taken out of the world, the cloths go back to their own pools (started by their
        // next step); the program's executor stays.
        w.cloths.clear();
        for (const auto& c : cloths) {
            CHECK_FALSE(c->hasCallerExecutor());
            c->step(1e-3);
            CHECK((c->executor() != nullptr) == (threads > 1));
        }
        CHECK(small->executor() == own.get());
        return state;
    };
    const auto one = run(1);
    const auto two = run(2);
    REQUIRE(one.size() == two.size());
    std::size_t differ = 0;
    for (std::size_t i = 0; i < one.size(); ++i)
        differ += one[i] != two[i]; // exact equality
    CHECK(differ == 0);
}

TEST_CASE("a cloth that fails in a parallel world step: the others step, its error is thrown",
          "[world][threads][errors]") {
    TestWorld w(Vec3(0, -9.81, 0));
    btRigidBody* holder = w.body(w.shape<btSphereShape>(btScalar(0.05)), 0.0, Vec3(0, 1, 0));
    std::vector<std::shared_ptr<Cloth>> cloths;
    std::vector<bullet::BulletCloth*> handles;
    for (int k = 0; k < 3; ++k) {
        auto cloth = makeCloth(horizontalSheet(5, 5, 0.05, 0.9, 1.0 * k), softCloth());
        bullet::BulletClothSettings bs;
        bs.threads = 2;
        handles.push_back(&w.add(cloth, bs));
        cloths.push_back(cloth);
    }
    handles[1]->attachHere(0, holder); // the middle cloth hangs from the holder
    w.world.stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0));
    // The holder leaves the world without its particles being detached first: the middle
    // cloth's next step detaches them and throws (test_wrong_use.cpp); the others step on.
    w.world.removeRigidBody(holder);
    const double t0 = cloths[0]->time(), t2 = cloths[2]->time();
    CHECK_THROWS_AS(w.world.stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0)), Error);
    CHECK(cloths[0]->time() > t0);
    CHECK(cloths[2]->time() > t2);
    CHECK(handles[1]->attachments().empty());
    w.world.addRigidBody(holder); // (the fixture removes it again)
}

TEST_CASE("timeStep: stepSimulation's btScalar sub-step becomes the cloth's exact double dt",
          "[world][determinism]") {
    // Bullet hands the sub-step to the cloth as a float: 1/120 s arrives as 0.008333334. With
    // BulletClothSettings::timeStep = 1/120 the cloth steps with the double 1/120 instead, so
    // a world stepped by stepSimulation follows stepInWorld(1/120) bit for bit; without it the
    // two runs part (the float step is 4e-8 relatively longer).
    const double dt = 1.0 / 120.0;
    auto run = [dt](bool throughWorld, bool exact, bool setLater = false) {
        TestWorld w;
        w.body(w.shape<btBoxShape>(btVector3(0.3f, 0.05f, 0.3f)), 0.0, Vec3(0, 0, 0));
        ClothSettings s = softCloth();
        s.springStiffness = 10.0; // stable at 120 Hz
        auto cloth = makeCloth(horizontalSheet(7, 7, 0.05, 0.4), s);
        bullet::BulletClothSettings bs;
        if (exact && !setLater) bs.timeStep = dt;
        auto& handle = w.add(cloth, bs);
        if (exact && setLater) handle.setTimeStep(dt);
        for (int k = 0; k < 30; ++k) { // 0.25 s: falling 0.31 m onto the box
            if (throughWorld) {
                w.world.stepSimulation(btScalar(dt), 0);
            } else {
                w.world.getBroadphase()->calculateOverlappingPairs(w.world.getDispatcher());
                handle.stepInWorld(dt);
            }
        }
        return stateHash(*cloth);
    };
    const std::uint64_t alone = run(false, false);
    CHECK(run(true, true) == alone);
    CHECK(run(true, true, true) == alone); // set on the handle after it joined the world
    CHECK(run(true, false) != alone);
}

// A world in centimetres (every size times 100) with ClothSettings::inUnits(100) and
// BulletClothSettings::inUnits(100) is the same scene as in metres: a 1 m cloth of 25 x 25
// with default settings falls 0.5 m flat onto the floor (Bullet's default gravity, -10 and
// -1000: exact in float), lands, rests at the contact thickness (1 cm) and falls asleep, on the
// same frame and 100 times as far from everything. Left in SI units the centimetre cloth
// weighs 2,000 kg, keeps 0.1 mm from the floor and never sleeps. (Draped over a box the two
// part after the landing: folds amplify the float rounding of the box's size, 1e-8 m at first
// contact, centimetres a second later, as any two slightly different drops do.)
TEST_CASE("a cloth in a centimetre world with inUnits(100) lands as the same cloth in metres",
          "[world][units]") {
    struct Run {
        std::vector<Vec3> x; // positions every 10 frames, in metres
        int substeps = 0, asleepAt = -1;
        std::size_t contacts = 0;
    };
    auto run = [](double unit) {
        TestWorld w(Vec3(0.0, -10.0 * unit, 0.0));
        w.body(w.shape<btStaticPlaneShape>(btVector3(0, 1, 0), btScalar(0)), 0.0, Vec3::Zero());
        ClothSettings cs = unit == 1.0 ? ClothSettings{} : ClothSettings::inUnits(unit);
        bullet::BulletClothSettings bs = unit == 1.0 ? bullet::BulletClothSettings{}
                                                     : bullet::BulletClothSettings::inUnits(unit);
        auto cloth = makeCloth(horizontalSheet(25, 25, (1.0 / 24.0) * unit, 0.5 * unit), cs);
        auto& handle = w.add(cloth, bs);
        Run r;
        for (int f = 0; f < 240; ++f) {
            w.world.stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0));
            r.substeps = std::max(r.substeps, handle.lastStats().substeps);
            r.contacts += handle.lastStats().contacts;
            if (r.asleepAt < 0 && cloth->isAsleep()) r.asleepAt = f;
            if (f % 10 == 9)
                for (const Vec3& x : cloth->positions())
                    r.x.push_back(x / unit);
        }
        return r;
    };
    const Run m = run(1.0), cm = run(100.0);
    double worst = 0.0, lowest = 1.0;
    for (std::size_t i = 0; i < m.x.size(); ++i) {
        worst = std::max(worst, (cm.x[i] - m.x[i]).norm());
        lowest = std::min(lowest, cm.x[i].y());
    }
    UNSCOPED_INFO(measured("centimetres against metres: sub-steps %d and %d, contacts %zu and "
                           "%zu, asleep at frames %d and %d, largest difference %.3g m, lowest "
                           "particle %.6f m",
                           cm.substeps, m.substeps, cm.contacts, m.contacts, cm.asleepAt,
                           m.asleepAt, worst, lowest));
    CHECK(cm.substeps == m.substeps);
    CHECK(m.contacts > 0);
    CHECK(cm.contacts == m.contacts);
    CHECK(m.asleepAt > 0);
    CHECK(cm.asleepAt == m.asleepAt);
    CHECK(lowest == Approx(0.01).margin(1e-6)); // resting at the thickness: 1 cm, not 0.1 mm
    CHECK(worst < 1e-9);
}

namespace {
/// A debug drawer that counts the lines it is given, in the mode it is set to.
class CountingDrawer : public btIDebugDraw {
  public:
    int lines = 0;
    int mode = 0;
    void drawLine(const btVector3&, const btVector3&, const btVector3&) override { ++lines; }
    void drawContactPoint(const btVector3&, const btVector3&, btScalar, int,
                          const btVector3&) override {}
    void reportErrorWarning(const char*) override {}
    void draw3dText(const btVector3&, const char*) override {}
    void setDebugMode(int m) override { mode = m; }
    int getDebugMode() const override { return mode; }
};
} // namespace

TEST_CASE("a cloth's debug drawing follows the drawer's debug mode, as Bullet's bodies do",
          "[world]") {
    TestWorld w;
    auto cloth = makeCloth(horizontalSheet(5, 5, 0.1, 1.0), ClothSettings{});
    auto& handle = w.add(cloth);
    CountingDrawer drawer;
    w.world.setDebugDrawer(&drawer);
    drawer.setDebugMode(btIDebugDraw::DBG_NoDebug);
    handle.debugDraw(&drawer);
    w.world.debugDrawWorld();
    CHECK(drawer.lines == 0);
    drawer.setDebugMode(btIDebugDraw::DBG_DrawWireframe);
    handle.debugDraw(&drawer);
    CHECK(drawer.lines == int(cloth->topology().springCount()));
    drawer.lines = 0;
    w.world.debugDrawWorld(); // the world draws every cloth (and its bodies: none here)
    CHECK(drawer.lines == int(cloth->topology().springCount()));
    w.world.setDebugDrawer(nullptr);
}

TEST_CASE("replays from one snapshot in a world are bit-identical to the first run",
          "[world][snapshot]") {
    // Review 20: an editor's "play from snapshot" with a ball thrown into a curtain gave a new
    // state at every replay: the contact records of the run before (which the contact force
    // term reads when the first step evaluates the forces) were left in the cloth's
    // ContactSet; restoring a state now clears them, as in a cloth just added to its world.
    TestWorld w;
    SheetSpec spec;
    spec.rows = 15;
    spec.cols = 15;
    spec.spacing = 0.05;
    spec.origin = Vec3(-0.35, 1.0, 0.0);
    auto cloth = makeCloth(makeSheet(spec), ClothSettings{});
    for (Index c = 0; c < spec.cols; ++c)
        cloth->pin(c);
    for (auto& x : cloth->mutablePositions())
        x.z() += 0.001 * std::sin(37.0 * x.x() + 11.0 * x.y());
    w.add(cloth);
    btRigidBody* ball = w.body(w.shape<btSphereShape>(0.1f), 1.0, Vec3(0.0, 0.7, 0.6));
    ball->setGravity(btVector3(0, 0, 0));
    const auto throwBall = [&] {
        btTransform t;
        t.setIdentity();
        t.setOrigin(btVector3(0.0f, 0.7f, 0.6f));
        ball->setWorldTransform(t);
        ball->setInterpolationWorldTransform(t);
        ball->setLinearVelocity(btVector3(0, 0, -3));
        ball->setAngularVelocity(btVector3(0, 0, 0));
        ball->setInterpolationLinearVelocity(btVector3(0, 0, -3));
        ball->setInterpolationAngularVelocity(btVector3(0, 0, 0));
        ball->clearForces();
        ball->activate(true);
    };
    throwBall();
    const std::vector<unsigned char> start = saveSnapshot(*cloth);
    std::uint64_t first = 0;
    for (int run = 0; run < 3; ++run) {
        if (run > 0) {
            loadSnapshot(*cloth, start);
            throwBall();
        }
        for (int f = 0; f < 40; ++f)
            w.world.stepSimulation(1.0f / 60.0f, 1, 1.0f / 60.0f);
        if (run == 0) {
            first = stateHash(*cloth);
            // The ball reached the curtain and pushed it.
            REQUIRE(cloth->positions()[7 * 15 + 7].z() < -0.01);
        }
        INFO("run " << run);
        CHECK(stateHash(*cloth) == first);
    }
}

TEST_CASE("a kinematic body set elsewhere before the first step carries the cloth attached to "
          "it there",
          "[world][attachments]") {
    // Review 21: a game creates an NPC's body, attaches a cape, then places the body where it
    // belongs. Set 0.4 m away before the first step (24 m/s at 60 Hz, below teleportSpeed) it
    // dragged the cape there as motion: 14 ms a cape in that frame. It is a placement: the
    // cape arrives with its shape, at rest. A move slower than a fifth of teleportSpeed (a
    // hand that picks the cloth up and walks on: 0.05 m, 3 m/s) stays motion.
    for (const float move : {0.4f, 0.05f}) {
        TestWorld w;
        btRigidBody* box =
            w.kinematic(w.shape<btBoxShape>(btVector3(0.3f, 0.05f, 0.1f)), Vec3(0.24, 2.0, 0.0));
        SheetSpec spec;
        spec.rows = 19;
        spec.cols = 13;
        spec.spacing = 0.04;
        spec.origin = Vec3(0.0, 1.95, -0.11);
        auto cloth = makeCloth(makeSheet(spec), ClothSettings{});
        auto& handle = w.add(cloth);
        for (Index c = 0; c < spec.cols; ++c)
            handle.attachHere(sheetIndex(spec, 0, c), box);
        const Vec3List start = cloth->positions();
        btTransform t = box->getWorldTransform();
        t.setOrigin(t.getOrigin() + btVector3(move, 0.0f, 0.0f));
        box->getMotionState()->setWorldTransform(t);
        box->setWorldTransform(t);
        w.world.stepSimulation(1.0f / 60.0f, 1, 1.0f / 60.0f);
        double fastest = 0.0, offShape = 0.0;
        for (Index i = 0; i < cloth->particleCount(); ++i) {
            fastest = std::max(fastest, cloth->velocities()[i].norm());
            offShape = std::max(
                offShape, (cloth->positions()[i] - start[i] - Vec3(double(move), 0.0, 0.0)).norm());
        }
        INFO("moved " << move << " m: fastest " << fastest << " m/s, off its shape by " << offShape
                      << " m");
        if (move > 0.1f) {
            // Carried; the free particles then fall one frame (millimetres).
            CHECK(handle.lastStats().teleports == 1);
            CHECK(fastest < 0.5);
            CHECK(offShape < 0.005);
            // A body moved after a first step is motion, as before.
            t.setOrigin(t.getOrigin() + btVector3(0.4f, 0.0f, 0.0f));
            box->getMotionState()->setWorldTransform(t);
            w.world.stepSimulation(1.0f / 60.0f, 1, 1.0f / 60.0f);
            CHECK(handle.lastStats().teleports == 0);
        } else {
            CHECK(handle.lastStats().teleports == 0); // dragged: the top row moves at 3 m/s
            CHECK(fastest > 1.0);
        }
    }
}
