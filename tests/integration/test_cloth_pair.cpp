// Two cloths in one world keep apart (BulletClothSettings::collideWithCloths): a towel dropped
// on a tablecloth lying on a table rests on it, a cloth thrown into a net does not pass
// through it; with the collision off, or filtered out, they pass through each other.
#include "world_fixture.hpp"

#include "drape/geometry.hpp"

#include <catch2/catch.hpp>

#include <cmath>
#include <limits>

using namespace drape;
using namespace drape::testing;

namespace {

/// The sign of each particle of `p` against the cloth `t`: +1 or -1 for the side of its
/// nearest triangle (along that triangle's normal as wound) when the nearest point is inside
/// the triangle, 0 when it lies on its rim (beside the cloth, not over it).
std::vector<int> sides(const Cloth& p, const Cloth& t) {
    std::vector<int> out;
    const auto& x = t.positions();
    for (const Vec3& q : p.positions()) {
        double nearest = std::numeric_limits<double>::infinity(), gap = 0.0;
        for (const Triangle& tri : t.topology().triangles()) {
            Vec3 bary;
            const Vec3 c = closestPointOnTriangle(q, x[tri[0]], x[tri[1]], x[tri[2]], bary);
            if ((q - c).norm() >= nearest) continue;
            nearest = (q - c).norm();
            gap = (q - c).dot((x[tri[1]] - x[tri[0]]).cross(x[tri[2]] - x[tri[0]]).normalized());
        }
        out.push_back(std::abs(gap) + 1e-6 < nearest ? 0 : (gap >= 0.0 ? 1 : -1));
    }
    return out;
}

/// Particles of `p` over the cloth `t` on the other side than `side`.
int onOtherSide(const Cloth& p, const Cloth& t, int side) {
    int n = 0;
    for (const int s : sides(p, t))
        n += s == -side;
    return n;
}

/// A 1 m tablecloth (41 x 41) lying on a 0.8 m table and a 0.4 m towel (17 x 17) dropped on
/// it from 0.3 m, off centre; default settings (the towel's collision with other cloths as
/// `towelSettings` says).
struct Table {
    TestWorld w;
    std::shared_ptr<Cloth> tablecloth, towel;
    bullet::BulletCloth *clothHandle = nullptr, *towelHandle = nullptr;
    explicit Table(const bullet::BulletClothSettings& towelSettings,
                   const bullet::BulletClothSettings& clothSettings = {}) {
        w.body(w.shape<btBoxShape>(btVector3(0.4f, 0.4f, 0.4f)), 0.0, Vec3(0, 0.4, 0));
        tablecloth = makeCloth(horizontalSheet(41, 41, 0.025, 0.82), ClothSettings{});
        towel = makeCloth(horizontalSheet(17, 17, 0.025, 1.12, 0.1, 0.05), ClothSettings{});
        clothHandle = &w.add(tablecloth, clothSettings);
        towelHandle = &w.add(towel, towelSettings);
    }
};

} // namespace

TEST_CASE("a towel dropped on a tablecloth rests on it, and both fall asleep", "[cloth_pair]") {
    Table table{bullet::BulletClothSettings{}};
    REQUIRE(onOtherSide(*table.towel, *table.tablecloth, 1) == 0); // above: +y
    int crossed = 0;
    double lowest = std::numeric_limits<double>::infinity();
    for (int f = 0; f < 360; ++f) {
        table.w.world.stepSimulation(1.0f / 60.0f, 1, 1.0f / 60.0f);
        if (f % 10 == 9)
            crossed = std::max(crossed, onOtherSide(*table.towel, *table.tablecloth, 1));
    }
    for (const Vec3& x : table.towel->positions())
        lowest = std::min(lowest, x.y());
    CHECK(crossed == 0);
    CHECK(table.towelHandle->totalStats().clothContacts > 0);
    CHECK(table.clothHandle->totalStats().clothContacts ==
          table.towelHandle->totalStats().clothContacts);
    // On the tablecloth (its particles 1 cm above the table's top at 0.8 m, the towel's 1 cm
    // above its triangles), not on the table.
    CHECK(lowest > 0.8 + 0.018);
    CHECK(lowest < 0.8 + 0.03);
    // At rest: both asleep within 6 s.
    CHECK(table.towel->isAsleep());
    CHECK(table.tablecloth->isAsleep());

    // Control: without the collision the towel falls through onto the table.
    bullet::BulletClothSettings off;
    off.collideWithCloths = false;
    Table through{off};
    for (int f = 0; f < 120; ++f)
        through.w.world.stepSimulation(1.0f / 60.0f, 1, 1.0f / 60.0f);
    CHECK(onOtherSide(*through.towel, *through.tablecloth, 1) > 100);
    CHECK(through.towelHandle->totalStats().clothContacts == 0);
}

TEST_CASE("cloths whose collision filters exclude each other pass through each other",
          "[cloth_pair]") {
    bullet::BulletClothSettings filtered;
    filtered.collisionGroup = 4; // a group of the program's
    filtered.collisionMask = ~1; // not the tablecloth's group 1 (the static table's is 2)
    Table table{filtered};
    for (int f = 0; f < 120; ++f)
        table.w.world.stepSimulation(1.0f / 60.0f, 1, 1.0f / 60.0f);
    CHECK(onOtherSide(*table.towel, *table.tablecloth, 1) > 100);
    CHECK(table.towelHandle->totalStats().clothContacts == 0);
}

TEST_CASE("a cloth thrown into a net does not pass through it and pushes it", "[cloth_pair]") {
    // The net (1 m, pinned on all four edges) is larger than the thrown cloth (0.4 m), so the
    // cloth cannot go round it: a particle behind it went through.
    for (const double speed : {4.0, 8.0, 16.0}) {
        TestWorld w;
        SheetSpec spec;
        spec.rows = 21;
        spec.cols = 21;
        spec.spacing = 0.05;
        spec.origin = Vec3(-0.5, 0.0, 0.0);
        spec.uAxis = Vec3::UnitX();
        spec.vAxis = Vec3::UnitY();
        auto curtain = makeCloth(makeSheet(spec), ClothSettings{});
        pinBorder(*curtain, 21);
        spec.rows = 9;
        spec.cols = 9;
        spec.origin = Vec3(-0.2, 0.3, -0.3);
        auto thrown = makeCloth(makeSheet(spec), ClothSettings{});
        for (Index i = 0; i < thrown->particleCount(); ++i)
            thrown->setVelocity(i, Vec3(0.0, 0.0, speed));
        const bullet::BulletCloth& netHandle = w.add(curtain);
        const bullet::BulletCloth& thrownHandle = w.add(thrown);
        const std::vector<int> start = sides(*thrown, *curtain);
        const int side = start[40]; // the thrown cloth's middle, in front of the curtain
        REQUIRE(side != 0);
        const double thrownMomentum = thrown->momentum().z();
        int crossed = 0;
        double pushed = 0.0; // the curtain's largest momentum along the throw
        for (int f = 0; f < 60; ++f) {
            w.world.stepSimulation(1.0f / 60.0f, 1, 1.0f / 60.0f);
            crossed = std::max(crossed, onOtherSide(*thrown, *curtain, side));
            pushed = std::max(pushed, curtain->momentum().z());
        }
        CAPTURE(speed, pushed, thrownMomentum, thrown->momentum().z());
        CHECK(crossed == 0);
        // The throw's momentum went into the net (and through its pins): the net carried at
        // least a fifth of it at some time, and the thrown cloth kept less than a half.
        CHECK(pushed > 0.2 * thrownMomentum);
        CHECK(thrown->momentum().z() < 0.5 * thrownMomentum);
        // Each frame ends within the strain bound: the pairs are kept apart before the cloth
        // steps, whose limiter follows (kept apart after them, the net at 16 m/s ended 3
        // frames at 0.113).
        CHECK(netHandle.totalStats().boundBroken == 0);
        CHECK(thrownHandle.totalStats().boundBroken == 0);
    }
}

TEST_CASE("cloths that collide end bit-identical on one thread and on two, beside a cloth alone",
          "[cloth_pair][determinism][threads]") {
    // The towel and the tablecloth step as one group (one task); a third cloth far away steps
    // as its own task, in parallel with them on two threads.
    const auto run = [](int threads) {
        bullet::BulletClothSettings bs;
        bs.threads = threads;
        Table table{bs, bs};
        auto alone = makeCloth(horizontalSheet(21, 21, 0.05, 1.0, 5.0, 0.0), ClothSettings{});
        alone->pin(0);
        table.w.add(alone, bs);
        for (int f = 0; f < 45; ++f)
            table.w.world.stepSimulation(1.0f / 60.0f, 1, 1.0f / 60.0f);
        CHECK(table.towelHandle->totalStats().clothContacts > 0);
        std::vector<Vec3> state;
        for (const Cloth* c : {table.tablecloth.get(), table.towel.get(), alone.get()}) {
            state.insert(state.end(), c->positions().begin(), c->positions().end());
            state.insert(state.end(), c->velocities().begin(), c->velocities().end());
        }
        return state;
    };
    const auto one = run(1), two = run(2);
    REQUIRE(one.size() == two.size());
    std::size_t differ = 0;
    for (std::size_t i = 0; i < one.size(); ++i)
        differ += one[i] != two[i];
    CHECK(differ == 0);
}

TEST_CASE("two curtain panels hung edge to edge, their edge particles on each other, stay whole",
          "[cloth_pair]") {
    // Found by a review: the panels' shared column pinned at the top, a free particle's
    // contact with a triangle whose other corners were held moved its free corner by the
    // violation over its barycentric weight, 1e14 m, and the next pair search never ended.
    TestWorld w;
    std::vector<std::shared_ptr<Cloth>> panels;
    for (const double x0 : {-0.6, 0.0}) {
        SheetSpec spec;
        spec.rows = 49;
        spec.cols = 25;
        spec.spacing = 0.025;
        spec.origin = Vec3(x0, 2.0, 0.0);
        spec.uAxis = Vec3::UnitX();
        spec.vAxis = -Vec3::UnitY();
        panels.push_back(makeCloth(makeSheet(spec), ClothSettings{}));
        for (Index c = 0; c < 25; ++c)
            panels.back()->pin(c); // the top row
        w.add(panels.back());
    }
    double worst = 0.0;
    for (int f = 0; f < 90; ++f) {
        w.world.stepSimulation(1.0f / 60.0f, 1, 1.0f / 60.0f);
        for (const auto& p : panels) {
            REQUIRE(std::isfinite(p->maxStrain()));
            worst = std::max(worst, p->maxStrain());
            for (const Vec3& x : p->positions())
                REQUIRE(x.norm() < 10.0);
        }
    }
    CAPTURE(worst);
    CHECK(worst < 1.0);
}

TEST_CASE("a towel asleep on a tablecloth wakes and falls to the table when the tablecloth is "
          "removed",
          "[cloth_pair][sleep]") {
    Table table{bullet::BulletClothSettings{}};
    for (int f = 0; f < 360; ++f)
        table.w.world.stepSimulation(1.0f / 60.0f, 1, 1.0f / 60.0f);
    REQUIRE(table.towel->isAsleep());
    const auto lowestOf = [](const Cloth& c) {
        double lowest = std::numeric_limits<double>::infinity();
        for (const Vec3& x : c.positions())
            lowest = std::min(lowest, x.y());
        return lowest;
    };
    double clothAt = -std::numeric_limits<double>::infinity(); // its top, over the table
    for (const Vec3& x : table.tablecloth->positions())
        clothAt = std::max(clothAt, x.y());
    const double onCloth = lowestOf(*table.towel);
    bullet::removeCloth(*table.clothHandle);
    CHECK_FALSE(table.towel->isAsleep());
    for (int f = 0; f < 120; ++f)
        table.w.world.stepSimulation(1.0f / 60.0f, 1, 1.0f / 60.0f);
    // On the table now, where the tablecloth lay (the table's contact thickness above it),
    // not the cloths' thickness higher.
    CAPTURE(onCloth, clothAt);
    CHECK(lowestOf(*table.towel) == Approx(clothAt).margin(1e-3));
    CHECK(lowestOf(*table.towel) < onCloth - 0.003);
}
