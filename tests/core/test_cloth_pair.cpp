// Collision between two cloths (drape::collideCloths): two separate cloths stepped on their
// own, with no Bullet world, keep their particles off each other's triangles.
#include "drape/cloth.hpp"
#include "drape/cloth_pair.hpp"
#include "drape/error.hpp"
#include "drape/geometry.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

using namespace drape;

namespace {

/// A free horizontal sheet of n x n particles 5 cm apart, its corner at `origin`, in a world
/// without gravity, moving at `velocity`.
std::unique_ptr<Cloth> sheet(Index n, const Vec3& origin, const Vec3& velocity) {
    SheetSpec spec;
    spec.rows = n;
    spec.cols = n;
    spec.spacing = 0.05;
    spec.origin = origin;
    spec.uAxis = Vec3::UnitX();
    spec.vAxis = Vec3::UnitZ();
    ClothSettings s;
    s.gravity = Vec3::Zero();
    auto c = std::make_unique<Cloth>(ClothTopology::build(makeSheet(spec)), s);
    for (Index i = 0; i < c->particleCount(); ++i)
        c->setVelocity(i, velocity);
    return c;
}

/// A 9 x 9 sheet in the plane y = 0 and a 7 x 7 sheet `gap` above it, shifted half a cell so
/// that its particles come down onto the lower sheet's triangles, moving down at `speed`.
struct Pair {
    std::unique_ptr<Cloth> lower, upper;
    explicit Pair(double gap, double speed)
        : lower(sheet(9, Vec3::Zero(), Vec3::Zero())),
          upper(sheet(7, Vec3(0.075, gap, 0.075), Vec3(0.0, -speed, 0.0))) {}

    /// A frame of dt: as many equal steps of both as the stiffer needs, each followed (if
    /// `collide`) by the collision between them. Returns the counts summed.
    ClothPairStats step(double dt, bool collide) {
        const int parts = std::max(lower->substepsFor(dt), upper->substepsFor(dt));
        ClothPairStats sum;
        for (int k = 0; k < parts; ++k) {
            const Vec3List lowerStart = lower->positions(), upperStart = upper->positions();
            lower->step(dt / parts);
            upper->step(dt / parts);
            if (!collide) continue;
            const ClothPairStats st = collideCloths(*lower, lowerStart, *upper, upperStart,
                                                    ClothPairSettings{}, dt / parts);
            sum.pairTests += st.pairTests;
            sum.contacts += st.contacts;
            sum.wokeA = sum.wokeA || st.wokeA;
            sum.wokeB = sum.wokeB || st.wokeB;
        }
        return sum;
    }
    /// Particles of the upper sheet on the wrong side of the lower one: over a triangle of it
    /// (their nearest point inside the triangle, not on its rim) and behind it, along the
    /// normal the lower sheet's triangles had up (+y) at the start.
    int wrongSide() const {
        int wrong = 0;
        const auto& x = lower->positions();
        for (const Vec3& p : upper->positions()) {
            double nearest = std::numeric_limits<double>::infinity(), gap = 0.0;
            for (const Triangle& t : lower->topology().triangles()) {
                Vec3 bary;
                const Vec3 q = closestPointOnTriangle(p, x[t[0]], x[t[1]], x[t[2]], bary);
                if ((p - q).norm() >= nearest) continue;
                nearest = (p - q).norm();
                gap = (p - q).dot((x[t[1]] - x[t[0]]).cross(x[t[2]] - x[t[0]]).normalized());
            }
            if (gap < 0.0 && nearest + gap < 1e-6) ++wrong;
        }
        return wrong;
    }
    /// Every particle of the upper sheet over the lower one is on its side.
    bool upperAbove() const { return wrongSide() == 0; }
    Vec3 momentum() const { return lower->momentum() + upper->momentum(); }
    double meanY(const Cloth& c) const {
        double y = 0.0;
        for (const Vec3& p : c.positions())
            y += p.y();
        return y / static_cast<double>(c.particleCount());
    }
};

} // namespace

TEST_CASE("two cloths that meet stay apart and move on together, their momentum kept",
          "[cloth_pair]") {
    const double dt = 1.0 / 60.0, speed = 2.0;
    Pair pair(0.05, speed);
    REQUIRE(pair.upperAbove()); // (the lower sheet's triangles face up)
    const Vec3 before = pair.momentum();
    const double mLower = pair.lower->totalMass(), mUpper = pair.upper->totalMass();
    std::size_t contacts = 0;
    for (int k = 0; k < 15; ++k) {
        contacts += pair.step(dt, true).contacts;
        REQUIRE(pair.upperAbove());
    }
    CHECK(contacts > 0);
    // The two cloths are one closed system: what the contacts move and change, they share.
    CHECK((pair.momentum() - before).norm() <= 1e-9 * before.norm());
    // A perfectly inelastic collision: both move at the speed of their common centre of mass.
    const double common = -speed * mUpper / (mLower + mUpper);
    const double vLower = pair.lower->momentum().y() / mLower;
    const double vUpper = pair.upper->momentum().y() / mUpper;
    CAPTURE(common, vLower, vUpper);
    CHECK(std::abs(vLower - common) < 0.1 * speed);
    CHECK(std::abs(vUpper - common) < 0.1 * speed);
    CHECK(pair.meanY(*pair.upper) > pair.meanY(*pair.lower));

    // Control: without the collision the upper sheet passes through.
    Pair apart(0.05, speed);
    for (int k = 0; k < 15; ++k)
        apart.step(dt, false);
    CHECK_FALSE(apart.upperAbove());
}

TEST_CASE("a cloth that crosses another within one step is put back on its side", "[cloth_pair]") {
    // 30 m/s: the upper sheet moves 0.5 m in the step, ten times the gap, 50 thicknesses.
    const double dt = 1.0 / 60.0;
    Pair pair(0.05, 30.0);
    const Vec3 before = pair.momentum();
    const ClothPairStats st = pair.step(dt, true);
    CHECK(st.contacts > 0);
    CHECK(pair.upperAbove());
    CHECK((pair.momentum() - before).norm() <= 1e-9 * before.norm());
    Pair apart(0.05, 30.0);
    apart.step(dt, false);
    CHECK_FALSE(apart.upperAbove());
}

TEST_CASE("a sleeping cloth holds what rests on it and wakes for what hits it", "[cloth_pair]") {
    const double dt = 1.0 / 60.0;
    for (const double speed : {0.05, 3.0}) {
        Pair pair(0.03, speed);
        pair.lower->setSleep({true, 0.01, 0.05});
        for (int k = 0; k < 10 && !pair.lower->isAsleep(); ++k) {
            const Vec3List start = pair.lower->positions();
            pair.lower->step(dt);
        }
        REQUIRE(pair.lower->isAsleep());
        const Vec3List lowerBefore = pair.lower->positions();
        ClothPairStats st;
        for (int k = 0; k < 40 && !st.wokeA; ++k)
            st = pair.step(dt, true);
        CAPTURE(speed);
        CHECK(pair.upperAbove());
        if (speed < 0.1) {
            // 0.8 mm a step, under the 1 cm sleep distance: it stays asleep, not moved at all.
            CHECK(pair.lower->isAsleep());
            CHECK(pair.lower->positions() == lowerBefore);
            // The upper sheet stopped on it, the thickness above it (within the sheet's own
            // ripples from the pushes, a few millimetres), with no energy from the contact
            // (inelastic, against a cloth that does not give way).
            for (const Vec3& p : pair.upper->positions()) {
                CHECK(p.y() >= 0.999 * ClothPairSettings{}.thickness);
                CHECK(p.y() <= 2.0 * ClothPairSettings{}.thickness);
            }
            CHECK(pair.upper->kineticEnergy() + pair.upper->springEnergy() <=
                  0.5 * pair.upper->totalMass() * speed * speed);
        } else {
            // 5 cm a step: it wakes.
            CHECK(st.wokeA);
            CHECK_FALSE(pair.lower->isAsleep());
        }
    }
}

namespace {

/// Two sheets carried sideways at 3 m/s (a cape and a skirt on a running character: 5 cm a
/// frame, ten times the half thickness a list allows a particle), the upper one coming down
/// onto the lower at 0.1 m/s and moving over it at `slide`, for 60 frames. One collider keeps
/// its lists from call to call; a twin pair is collided by a fresh collider in every call (its
/// lists always built). Both must end every frame bit-identical. Returns the calls in which
/// the kept collider built its lists.
int carriedTogether(const Vec3& slide) {
    const double dt = 1.0 / 60.0;
    const Vec3 carry(3.0, 0.0, 0.0);
    auto make = [&](Pair& p) {
        for (Index i = 0; i < p.lower->particleCount(); ++i)
            p.lower->setVelocity(i, carry);
        for (Index i = 0; i < p.upper->particleCount(); ++i)
            p.upper->setVelocity(i, carry + slide + Vec3(0.0, -0.1, 0.0));
    };
    Pair kept(0.02, 0.0), fresh(0.02, 0.0);
    make(kept);
    make(fresh);
    ClothPairCollider collider;
    int built = 0;
    std::size_t contacts = 0;
    for (int frame = 0; frame < 60; ++frame) {
        for (Pair* p : {&kept, &fresh}) {
            const Vec3List lowerStart = p->lower->positions(), upperStart = p->upper->positions();
            p->lower->step(dt);
            p->upper->step(dt);
            if (p == &kept) {
                const ClothPairStats st = collider.collide(*p->lower, lowerStart, *p->upper,
                                                           upperStart, ClothPairSettings{}, dt);
                built += st.listsBuilt;
                contacts += st.contacts;
            } else {
                collideCloths(*p->lower, lowerStart, *p->upper, upperStart, ClothPairSettings{},
                              dt);
            }
        }
        REQUIRE(kept.upper->positions() == fresh.upper->positions());
        REQUIRE(kept.lower->positions() == fresh.lower->positions());
    }
    CHECK(contacts > 0);
    CHECK(kept.upperAbove());
    CHECK(kept.meanY(*kept.upper) > kept.meanY(*kept.lower));
    return built;
}

} // namespace

TEST_CASE("two cloths carried along together keep their pair lists, and kept lists miss no "
          "contact",
          "[cloth_pair]") {
    SECTION("resting on each other: the lists follow their relative motion, not the carry") {
        const int built = carriedTogether(Vec3::Zero());
        CHECK(built <= 60 / 4);
    }
    SECTION("sliding over each other at 0.4 m/s: lists kept while they hold give the same bits") {
        const int built = carriedTogether(Vec3(0.4, 0.0, 0.0));
        CHECK(built > 0);
    }
}

TEST_CASE("a cloth that came a kilometre in one step is still caught, without a search of every "
          "cell on its way",
          "[cloth_pair]") {
    // The upper sheet's particles came from 1 km away (up and to the side) to 0.5 m below the
    // lower sheet: a path whose box holds 10^13 grid cells, which the search must not walk.
    Pair pair(-0.5, 0.0);
    for (Index i = 0; i < pair.lower->particleCount(); ++i)
        pair.lower->pin(i); // held: the upper sheet alone is put back
    Vec3List upperStart = pair.upper->positions();
    for (Vec3& x : upperStart)
        x += Vec3(1000.0, 1000.5, 1000.0);
    const Vec3List lowerStart = pair.lower->positions();
    const ClothPairStats st = collideCloths(*pair.lower, lowerStart, *pair.upper, upperStart,
                                            ClothPairSettings{}, 1.0 / 60.0);
    CHECK(st.contacts > 0);
    // On the side it came from, the thickness above the held sheet (a little more where the
    // pass also lifted a triangle of it off a held particle below).
    const double h = ClothPairSettings{}.thickness;
    for (const Vec3& x : pair.upper->positions()) {
        CHECK(x.y() >= h * (1.0 - 1e-9));
        CHECK(x.y() <= 1.2 * h);
    }
}

TEST_CASE("a contact whose only free point carries a small share of it is held fast, not "
          "thrown",
          "[cloth_pair]") {
    // A 2 x 2 sheet with three corners held; a held particle of another cloth comes through
    // one of its triangles 1 mm deep next to a held corner, where the free corner's weight is
    // 1 %. The linearised projection alone would move the free corner 1.1 cm / 0.01 = 1.1 m;
    // a contact that cannot move its point without moving another four times as far is left
    // alone, as one between held points.
    SheetSpec spec;
    spec.rows = 2;
    spec.cols = 2;
    spec.spacing = 0.1;
    spec.uAxis = Vec3::UnitX();
    spec.vAxis = Vec3::UnitZ();
    ClothSettings s;
    s.gravity = Vec3::Zero();
    Cloth lower(ClothTopology::build(makeSheet(spec)), s);
    const Index free = 3;
    for (Index i = 0; i < 3; ++i)
        lower.pin(i);
    const Triangle* t = nullptr;
    for (const Triangle& tri : lower.topology().triangles())
        if (tri[0] == free || tri[1] == free || tri[2] == free) t = &tri;
    REQUIRE(t != nullptr);
    Vec3 target = Vec3::Zero();
    const Vec3List& x = lower.positions();
    int heldSeen = 0;
    for (const Index k : *t)
        target += (k == free ? 0.01 : heldSeen++ == 0 ? 0.98 : 0.01) * x[k];
    TriangleMesh probe;
    probe.vertices = {target - Vec3(0.0, 0.001, 0.0), Vec3(-2.0, 0.0, -2.0), Vec3(-2.0, 0.0, -2.1)};
    probe.triangles = {{0, 1, 2}};
    Cloth upper(ClothTopology::build(probe), s);
    for (Index i = 0; i < 3; ++i)
        upper.pin(i);
    Vec3List upperStart = upper.positions();
    upperStart[0] = target + Vec3(0.0, 0.005, 0.0); // it came from above
    const Vec3 before = lower.positions()[free];
    const ClothPairStats st =
        collideCloths(lower, lower.positions(), upper, upperStart, ClothPairSettings{}, 1.0 / 60.0);
    CHECK(st.pairTests > 0);
    CHECK(st.contacts == 0);
    CHECK(lower.positions()[free] == before);
}

TEST_CASE("collideCloths refuses what it cannot do, by name", "[cloth_pair][errors]") {
    Pair pair(0.05, 1.0);
    const Vec3List lower = pair.lower->positions(), upper = pair.upper->positions();
    const double dt = 1.0 / 60.0;
    const auto refuses = [&](const ClothPairSettings& s, const char* what) {
        CHECK_THROWS_WITH(collideCloths(*pair.lower, lower, *pair.upper, upper, s, dt),
                          Catch::Contains(what));
    };
    ClothPairSettings s;
    s.thickness = 0.0;
    refuses(s, "thickness");
    s = {};
    s.thickness = std::nan("");
    refuses(s, "thickness");
    s = {};
    s.friction = -0.1;
    refuses(s, "friction");
    s = {};
    s.iterations = 0;
    refuses(s, "iterations");
    CHECK_THROWS_WITH(collideCloths(*pair.lower, upper, *pair.upper, upper, {}, dt),
                      Catch::Contains("start positions"));
    CHECK_THROWS_WITH(collideCloths(*pair.lower, lower, *pair.lower, lower, {}, dt),
                      Catch::Contains("itself"));
    CHECK_THROWS_WITH(collideCloths(*pair.lower, lower, *pair.upper, upper, {}, 0.0),
                      Catch::Contains("step"));
}
