// Contacts as data (drape/contacts.hpp): the contact force term a cloth evaluates from a
// ContactSet, without any collision engine: a rigid triangle resting or sliding on a fixed
// inclined plane against Coulomb's law, and the forces the set reports for the body.
#include "helpers.hpp"

#include "drape/contacts.hpp"
#include "drape/geometry.hpp"

#include <memory>

using namespace drape;
using drape_test::kPi;

namespace {

/// A triangle of 0.3 m sides lying the thickness h above a plane through the origin tilted by
/// theta about z, with one contact record per particle (the plane does not move, so the
/// records stay valid), penalty off, friction mu.
struct Incline {
    double theta, mu, h = 0.01;
    Vec3 g{0.0, -9.81, 0.0};
    Vec3 n() const { return {-std::sin(theta), std::cos(theta), 0.0}; }
    Vec3 down() const { return {-std::cos(theta), -std::sin(theta), 0.0}; } // along the slope
    std::unique_ptr<Cloth> cloth;
    std::shared_ptr<ContactSet> set = std::make_shared<ContactSet>();

    Incline(double th, double m) : theta(th), mu(m) {
        const Vec3 across(0.0, 0.0, 1.0);
        TriangleMesh mesh;
        mesh.vertices = {h * n(), h * n() + 0.3 * across, h * n() + 0.15 * across - 0.26 * down()};
        mesh.triangles = {Triangle{0, 1, 2}};
        ClothSettings s;
        s.gravity = g;
        s.damping = 0.0;
        s.relativeDamping = 0.0;
        s.limiter.kind = LimiterKind::None;
        cloth = std::make_unique<Cloth>(ClothTopology::build(mesh), s);
        set->thickness = h;
        set->band = h;
        set->dt = 1.0 / 60.0;
        for (Index i = 0; i < 3; ++i) {
            ContactRecord r;
            r.particle = i;
            r.point = Vec3::Zero();
            r.normal = n();
            r.mass = cloth->masses()[i];
            r.mu = mu;
            set->contacts.push_back(r);
        }
        cloth->setContacts(set);
    }
    Vec3 centroid() const {
        const auto& x = cloth->positions();
        return (x[0] + x[1] + x[2]) / 3.0;
    }
};

} // namespace

TEST_CASE("Contact records hold a cloth on an incline below tan(theta) = mu and let it slide "
          "at g (sin theta - mu cos theta) above it",
          "[contacts]") {
    const double mu = 0.5, dt = 1.0 / 60.0, t = 1.0;
    for (const double theta : {0.2, 0.4, 0.6, 0.9}) { // tan: 0.20, 0.42, 0.68, 1.26
        CAPTURE(theta);
        Incline in(theta, mu);
        const Vec3 start = in.centroid();
        for (int k = 0; k < 60; ++k)
            in.cloth->step(dt);
        const Vec3 d = in.centroid() - start;
        const double a = std::max(0.0, 9.81 * (std::sin(theta) - mu * std::cos(theta)));
        // Constant forces: Velocity-Verlet moves the triangle by a t^2 / 2 exactly (to rounding).
        CHECK(d.dot(in.down()) == Approx(0.5 * a * t * t).margin(1e-12));
        CHECK(std::abs(d.dot(in.n())) < 1e-12); // it neither sinks nor lifts off
        // What the set reports for the body: the normal force and friction the particles got.
        Vec3 onCloth = Vec3::Zero();
        for (const ContactRecord& r : in.set->contacts)
            onCloth += r.force * r.normal + r.friction;
        const double weight = in.cloth->totalMass() * 9.81;
        CHECK(onCloth.dot(in.n()) == Approx(weight * std::cos(theta)).epsilon(1e-12));
        CHECK(-onCloth.dot(in.down()) ==
              Approx(weight * std::min(std::sin(theta), mu * std::cos(theta))).epsilon(1e-12));
    }
}

TEST_CASE("A contact never launches a particle that leaves the surface", "[contacts]") {
    Incline in(0.0, 0.5); // a level floor
    const double dt = 1.0 / 60.0;
    for (Index i = 0; i < 3; ++i)
        in.cloth->setVelocity(i, Vec3(0.1, 0.5, 0.0)); // leaving it, and sliding
    in.cloth->step(dt);
    for (const ContactRecord& r : in.set->contacts) {
        CHECK(r.force == 0.0); // no pull back either: gravity alone acts
        CHECK(r.friction == Vec3::Zero());
    }
    for (Index i = 0; i < 3; ++i) {
        CHECK(in.cloth->velocities()[i].y() == Approx(0.5 - 9.81 * dt).epsilon(1e-12));
        CHECK(in.cloth->velocities()[i].x() == Approx(0.1).epsilon(1e-12));
    }
}

TEST_CASE("Removing the contact set removes the term from the pipeline", "[contacts]") {
    Incline in(0.3, 0.5);
    auto has = [&] {
        const auto p = in.cloth->pipeline();
        return std::find(p.begin(), p.end(), "contact_force") != p.end();
    };
    CHECK(has());
    in.cloth->setContacts(nullptr);
    CHECK_FALSE(has());
}

namespace {
/// A "table" y >= h as data: before the limiter, every free particle gets the plane
/// n = +y, offset h (what drape::bullet's contact stage does with the bodies it finds).
class TableStage final : public ClothStage {
  public:
    TableStage(std::shared_ptr<ContactSet> set, double h) : set_(std::move(set)), h_(h) {}
    std::string name() const override { return "table"; }
    void beforeLimit(Cloth& c, double) override {
        set_->planes.reset(c.particleCount());
        for (Index i = 0; i < c.particleCount(); ++i)
            if (c.inverseMasses()[i] != 0.0) set_->planes.set(i, Vec3::UnitY(), h_);
        ++before;
    }
    void run(Cloth& c, double) override {
        // After the limiter: no free particle below the table.
        for (Index i = 0; i < c.particleCount(); ++i)
            if (c.inverseMasses()[i] != 0.0) lowest = std::min(lowest, c.positions()[i].y());
        ++after;
    }
    int before = 0, after = 0;
    double lowest = 1e300;

  private:
    std::shared_ptr<ContactSet> set_;
    double h_;
};
} // namespace

TEST_CASE("Contact planes set before the limiter are kept by the step's one walk, with the "
          "strain bound",
          "[contacts][limiter]") {
    // A 5 x 5 sheet (0.1 m spacing) lying at y = h on a table, its first row pinned 5 cm below
    // the table's top (a cloth pulled down over an edge): the springs to the second row are
    // 11.8 % long, and the limiter pulls that row down towards the pins.
    const double h = 0.01, spacing = 0.1;
    auto make = [&] {
        TriangleMesh m;
        for (int r = 0; r < 5; ++r)
            for (int c = 0; c < 5; ++c)
                m.vertices.push_back(Vec3(spacing * c, h, spacing * r));
        for (int r = 0; r < 4; ++r)
            for (int c = 0; c < 4; ++c) {
                const auto i = static_cast<Index>(5 * r + c);
                m.triangles.push_back(Triangle{i, i + 1, i + 5});
                m.triangles.push_back(Triangle{i + 1, i + 6, i + 5});
            }
        ClothSettings s;
        s.gravity = Vec3::Zero();
        auto cloth = std::make_unique<Cloth>(ClothTopology::build(m), s);
        for (Index c = 0; c < 5; ++c)
            cloth->pin(c, Vec3(spacing * c, h - 0.05, 0.0));
        return cloth;
    };
    const double bound = 0.1 + 1e-3;
    {
        // Without the table, the walk pulls the second row below y = h.
        auto cloth = make();
        cloth->step(1e-3);
        double lowest = 1e300;
        for (Index i = 5; i < 25; ++i)
            lowest = std::min(lowest, cloth->positions()[i].y());
        CHECK(lowest < h - 1e-4); // 0.8 mm below
        CHECK(cloth->maxStrain() <= bound);
    }
    auto cloth = make();
    auto set = std::make_shared<ContactSet>();
    cloth->setContacts(set);
    auto table = std::make_shared<TableStage>(set, h);
    cloth->addStage(table);
    cloth->step(1e-3);
    CHECK(table->before == 1);
    CHECK(table->after == 1);
    // The walk met both: no particle below the table, every spring within the bound (the
    // second row slid back along the table instead).
    CHECK(table->lowest >= h - 1e-12);
    CHECK(cloth->maxStrain() <= bound);
    // And it recorded how far the table pushed (what a body would get as an impulse).
    double pushed = 0.0;
    for (const Vec3& p : set->planes.push)
        pushed += p.y();
    CHECK(pushed > 0.0);
}

// The path test against a box (segmentEntersBox, the contact stage's continuous test for a box
// that does not move): exact slabs, so an entry through a face gives the face's point and
// normal, and a path that passes a corner outside the box (a particle sliding round it in the
// contact thickness) does not enter it.
TEST_CASE("a segment enters a box through the face it crosses, and never past a corner",
          "[contacts][geometry]") {
    const Vec3 half(0.15, 0.15, 0.15);
    double t = -1.0;
    Vec3 n = Vec3::Zero();
    // Straight down onto the top face, from 0.1 above it to 0.1 inside: halfway.
    REQUIRE(segmentEntersBox(Vec3(0.05, 0.25, -0.02), Vec3(0.05, 0.05, -0.02), half, t, n));
    CHECK(t == Approx(0.5).margin(1e-15));
    CHECK(n == Vec3(0.0, 1.0, 0.0));
    // Slanted into the side face x = -0.15: where the line crosses it, x(t) = -0.15.
    const Vec3 o(-0.35, 0.02, 0.04), e(-0.05, 0.12, 0.1);
    REQUIRE(segmentEntersBox(o, e, half, t, n));
    CHECK(t == Approx(0.2 / 0.3).epsilon(1e-14));
    CHECK(n == Vec3(-1.0, 0.0, 0.0));
    CHECK((o + t * (e - o)).x() == Approx(-0.15).epsilon(1e-14));
    // Past a vertical edge, on the line x + z = 0.302 (1.4 mm from the edge at its closest):
    // outside the box all the way. The same path 2 mm nearer (x + z = 0.298) cuts the edge and
    // enters through the face it meets first.
    CHECK_FALSE(segmentEntersBox(Vec3(0.161, 0.1, 0.141), Vec3(0.141, 0.1, 0.161), half, t, n));
    REQUIRE(segmentEntersBox(Vec3(0.16, 0.1, 0.138), Vec3(0.14, 0.1, 0.158), half, t, n));
    CHECK(n == Vec3(1.0, 0.0, 0.0));
    CHECK(t == Approx(0.5).epsilon(1e-12)); // x = 0.15 at t = 1/2, where z = 0.148
    // Starting inside, parallel outside, or stopping short: no entry.
    CHECK_FALSE(segmentEntersBox(Vec3(0.0, 0.0, 0.0), Vec3(1.0, 0.0, 0.0), half, t, n));
    CHECK_FALSE(segmentEntersBox(Vec3(-1.0, 0.2, 0.0), Vec3(1.0, 0.2, 0.0), half, t, n));
    CHECK_FALSE(segmentEntersBox(Vec3(0.0, 0.5, 0.0), Vec3(0.0, 0.16, 0.0), half, t, n));
}
