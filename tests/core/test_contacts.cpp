// Contacts as data (drape/contacts.hpp): the contact force term a cloth evaluates from a
// ContactSet, without any collision engine: a rigid triangle resting or sliding on a fixed
// inclined plane against Coulomb's law, and the forces the set reports for the body.
#include "helpers.hpp"

#include "drape/contacts.hpp"

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
