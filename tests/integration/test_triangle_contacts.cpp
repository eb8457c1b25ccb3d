// Triangle-body contacts (ContactSettings::triangles): a body feature thinner than the
// particle spacing, which particle contacts alone let through between two particles, is caught
// by the cloth's triangles: a thin rod holds up a falling sheet, a thin rod swept through a
// hanging curtain pushes it, and a box's knife edge stays under a sheet dropped on it. Each check
// also runs without triangle contacts, where the rod must pass (so the check can fail), and the
// mode costs nothing when it is off.
#include "measured.hpp"
#include "world_fixture.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

using namespace drape;
using namespace drape::testing;

namespace {

constexpr double kStep = 1.0 / 240.0;
constexpr double kThickness = 0.005;

/// Distance in a plane (coordinates u, v) from point (pu, pv) to segment a-b.
double segmentDistance2d(double pu, double pv, double au, double av, double bu, double bv) {
    const double du = bu - au, dv = bv - av;
    const double len2 = du * du + dv * dv;
    const double t =
        len2 > 0.0 ? std::clamp(((pu - au) * du + (pv - av) * dv) / len2, 0.0, 1.0) : 0.0;
    return std::hypot(pu - (au + t * du), pv - (av + t * dv));
}

/// Adds a floor and a 9 x 9 sheet (spacing 5 cm, 0.162 kg, k 5 N/m) at height y whose two
/// middle columns lie at x = -0.025 and +0.025 (a feature along z at x = 0 falls between
/// them), with triangle contacts on or off; returns its handle.
/// `boxEdges` off unless asked: "particles only" below means particle contacts alone.
bullet::BulletCloth& addSheetOverFloor(TestWorld& w, double y, bool triangles,
                                       bool boxEdges = false) {
    w.body(w.shape<btStaticPlaneShape>(btVector3(0, 1, 0), btScalar(0.0)), 0.0, Vec3::Zero());
    ClothSettings s;
    s.particleMass = 0.002;
    s.springStiffness = 5.0;
    s.damping = 0.01;
    bullet::BulletClothSettings bs;
    bs.contact.thickness = kThickness;
    bs.contact.triangles = triangles;
    bs.contact.boxEdges = boxEdges;
    return w.add(makeCloth(horizontalSheet(9, 9, 0.05, y, 0.025), s), bs);
}

double lowestParticle(const Cloth& cloth) {
    double lowest = std::numeric_limits<double>::infinity();
    for (const auto& x : cloth.positions())
        lowest = std::min(lowest, x.y());
    return lowest;
}

/// Which contacts a thin moving rod meets: particle contacts alone (no swept tests), the
/// defaults (a moving body thinner than the spacing is swept against the triangles,
/// ContactSolver::sweepBodies), or triangle contacts on top of them.
enum class Mode { ParticlesOnly, Default, Triangles };
const char* modeName(Mode m) {
    return m == Mode::ParticlesOnly ? "particles only"
                                    : (m == Mode::Default ? "defaults" : "triangle contacts");
}
void applyMode(bullet::BulletClothSettings& bs, Mode m) {
    bs.contact.continuous = m != Mode::ParticlesOnly;
    bs.contact.triangles = m == Mode::Triangles;
}

struct RodDrop {
    double lowest = 0.0;  ///< lowest particle at the end [m]
    double closest = 0.0; ///< closest spring to the rod's axis (x-y plane) [m]
    std::size_t triangleQueries = 0, triangleContacts = 0;
};

/// A 9 x 9 sheet (spacing 5 cm) falls 9 cm onto a static rod (a capsule along z, radius 1 cm,
/// a fifth of the spacing) that lies between two columns of particles, 30 cm above a floor.
RodDrop dropOnRod(bool triangles) {
    TestWorld w;
    const double radius = 0.01, axisY = 0.3;
    w.body(w.shape<btCapsuleShapeZ>(btScalar(radius), btScalar(0.6)), 0.0, Vec3(0, axisY, 0));
    auto& handle = addSheetOverFloor(w, 0.4, triangles);
    const std::shared_ptr<Cloth> cloth = handle.clothPtr();
    for (int k = 0; k < 360; ++k)
        w.world.stepSimulation(btScalar(kStep), 1, btScalar(kStep));
    RodDrop r;
    r.lowest = lowestParticle(*cloth);
    r.closest = std::numeric_limits<double>::infinity();
    for (const auto& sp : cloth->topology().springs()) {
        const Vec3& a = cloth->positions()[sp.a];
        const Vec3& b = cloth->positions()[sp.b];
        if (std::abs(a.z()) > 0.3 || std::abs(b.z()) > 0.3) continue; // beyond the rod's length
        r.closest = std::min(r.closest, segmentDistance2d(0.0, axisY, a.x(), a.y(), b.x(), b.y()));
    }
    r.triangleQueries = handle.totalStats().triangleQueries;
    r.triangleContacts = handle.totalStats().triangleContacts;
    UNSCOPED_INFO(measured(
        "sheet dropped on a rod of radius 1 cm (spacing 5 cm), triangle contacts %s: "
        "lowest particle %.4f m, closest spring to the axis %.5f m (radius + thickness %.3f), "
        "%zu triangle queries",
        triangles ? "on" : "off", r.lowest, r.closest, radius + kThickness, r.triangleQueries));
    return r;
}

} // namespace

TEST_CASE("a thin rod under a falling sheet holds it up with triangle contacts",
          "[contacts][triangles]") {
    const RodDrop off = dropOnRod(false);
    // Particles alone: every particle is 2.5 cm from the axis, beyond the reach of the
    // 1 cm rod (radius + thickness + band = 2 cm): the sheet falls through onto the floor.
    CHECK(off.lowest < 0.02);
    CHECK(off.triangleQueries == 0); // the mode costs nothing when it is off
    const RodDrop on = dropOnRod(true);
    // Triangles: it hangs over the rod, its sides (17.5 and 22.5 cm, at most 10 % longer)
    // clear of the floor, and no spring passes nearer the axis than the radius plus the
    // thickness (the rod's pose is single precision: 1e-7 m).
    CHECK(on.lowest > 0.03);
    CHECK(on.closest >= 0.01 + kThickness - 1e-7);
    CHECK(on.triangleContacts > 0);
}

namespace {

struct Draped {
    Vec3 centreAt6 = Vec3::Zero(), centreAt12 = Vec3::Zero(); ///< mean particle position [m]
    bool asleep = false;
};

/// A towel (17 x 17, spacing 3 cm, 0.15 kg, default settings) dropped from 3 cm above onto a
/// static clothesline (a capsule along x, radius 1.2 cm: under half the spacing), centred 1.5
/// cm off a row (between two rows), triangle contacts on, 60 Hz, 12 s.
Draped drapeOverLine(double friction) {
    TestWorld w;
    w.body(w.shape<btStaticPlaneShape>(btVector3(0, 1, 0), btScalar(0.0)), 0.0, Vec3::Zero());
    btRigidBody* line =
        w.body(w.shape<btCapsuleShapeX>(btScalar(0.012), btScalar(2.0)), 0.0, Vec3(0.0, 1.45, 0.0));
    line->setFriction(btScalar(friction));
    ClothSettings s;
    s.totalMass = 0.15;
    bullet::BulletClothSettings bs;
    bs.contact.triangles = true;
    auto& handle = w.add(makeCloth(horizontalSheet(17, 17, 0.03, 1.48, 0.0, 0.015), s), bs);
    const Cloth& cloth = handle.cloth();
    auto centre = [&cloth]() {
        Vec3 sum = Vec3::Zero();
        for (const Vec3& x : cloth.positions())
            sum += x;
        return Vec3(sum / double(cloth.particleCount()));
    };
    Draped d;
    for (int k = 1; k <= 720; ++k) {
        w.world.stepSimulation(btScalar(1.0 / 60.0), 1, btScalar(1.0 / 60.0));
        if (k == 360) d.centreAt6 = centre();
    }
    d.centreAt12 = centre();
    d.asleep = cloth.isAsleep();
    UNSCOPED_INFO(measured("towel draped over a 1.2 cm line, friction %.1f: centre at 6 s (%.4f, "
                           "%.4f) m, at 12 s (%.4f, %.4f) m (y, z), %s",
                           friction, d.centreAt6.y(), d.centreAt6.z(), d.centreAt12.y(),
                           d.centreAt12.z(), d.asleep ? "asleep" : "awake"));
    return d;
}

} // namespace

TEST_CASE("a towel draped over a thin line with triangle contacts rests on it with friction and "
          "slides off without",
          "[contacts][triangles][friction]") {
    // With friction 0.8 the towel, nearly balanced, is held (a rope over a rod holds tensions
    // in a ratio up to exp(mu pi) = 12): it comes to rest on the line and stays. The triangles'
    // pushes out of the line are positions; without friction on them the towel crept down one
    // side 2 cm/s and slid off within 9 s.
    const Draped held = drapeOverLine(0.8);
    CHECK(held.centreAt12.y() > 1.3);
    CHECK((held.centreAt12 - held.centreAt6).norm() < 2e-3);
    CHECK(held.asleep);
    // Without friction the slightest imbalance takes it off the line onto the floor.
    const Draped slid = drapeOverLine(0.0);
    CHECK(slid.centreAt12.y() < 0.1);
}

namespace {

struct Sweep {
    double worstLead =
        0.0; ///< smallest (cloth z - rod z) at the rod's height over the rod's length
    double peakStrain = 0.0;
};

/// An 11 x 11 curtain (spacing 5 cm, top row pinned) hangs in the x-y plane; a kinematic rod
/// (a capsule along x, radius 1 cm, 30 cm long) between two rows sweeps through it along z
/// at 2 m/s, from 5 cm behind to 10 cm in front.
Sweep sweepRod(Mode mode) {
    TestWorld w;
    const double radius = 0.01, rodY = 0.725, speed = 2.0;
    double rodZ = -0.05;
    btRigidBody* rod =
        w.kinematic(w.shape<btCapsuleShapeX>(btScalar(radius), btScalar(0.3)), Vec3(0, rodY, rodZ));
    ClothSettings s;
    s.particleMass = 0.005;
    s.springStiffness = 40.0;
    s.damping = 0.005;
    SheetSpec spec;
    spec.rows = 11;
    spec.cols = 11;
    spec.spacing = 0.05;
    spec.origin = Vec3(-0.25, 1.0, 0.0);
    auto cloth = makeCloth(makeSheet(spec), s);
    for (Index c = 0; c < spec.cols; ++c)
        cloth->pin(c);
    bullet::BulletClothSettings bs;
    bs.contact.thickness = kThickness;
    applyMode(bs, mode);
    w.add(cloth, bs);
    Sweep r;
    r.worstLead = std::numeric_limits<double>::infinity();
    const int steps = int(std::lround(0.15 / speed / kStep));
    for (int k = 1; k <= steps; ++k) {
        rodZ += speed * kStep;
        rod->getMotionState()->setWorldTransform(
            btTransform(btQuaternion::getIdentity(), btVector3(0, btScalar(rodY), btScalar(rodZ))));
        w.world.stepSimulation(btScalar(kStep), 1, btScalar(kStep));
        r.peakStrain = std::max(r.peakStrain, cloth->maxStrain());
    }
    // Where each column within the rod's length crosses the rod's height, the cloth must be
    // in front of the rod (pushed), not behind it (passed through).
    for (Index c = 0; c < spec.cols; ++c) {
        for (Index row = 0; row + 1 < spec.rows; ++row) {
            const Vec3& a = cloth->positions()[row * spec.cols + c];
            const Vec3& b = cloth->positions()[(row + 1) * spec.cols + c];
            if (std::abs(a.x()) > 0.15 || a.y() < rodY || b.y() > rodY) continue;
            const double t = (a.y() - rodY) / (a.y() - b.y());
            r.worstLead = std::min(r.worstLead, a.z() + t * (b.z() - a.z()) - rodZ);
            break;
        }
    }
    UNSCOPED_INFO(measured("rod swept through a curtain at 2 m/s, %s: cloth %.4f m in front of the "
                           "rod's axis at its height (worst column), peak strain %.4f",
                           modeName(mode), r.worstLead, r.peakStrain));
    return r;
}

} // namespace

TEST_CASE("a thin rod swept through a hanging curtain pushes it, by default and with triangle "
          "contacts",
          "[contacts][triangles][kinematic]") {
    // Particles alone: the rod passes between two rows; the curtain stays behind it.
    CHECK(sweepRod(Mode::ParticlesOnly).worstLead < 0.0);
    // The defaults (the rod, thinner than the spacing, is swept against the triangles) and
    // triangle contacts: every column is in front of the rod by its radius plus the thickness
    // (to the float pose of the rod, 1e-6 m, and the sweep's tolerance, 5 % of the
    // thickness), and the strain bound (10 % plus the limiter's tolerance) holds in every step.
    for (Mode mode : {Mode::Default, Mode::Triangles}) {
        const Sweep on = sweepRod(mode);
        CHECK(on.worstLead >= 0.01 + 0.95 * kThickness - 1e-6);
        CHECK(on.peakStrain <= 0.1 + 1e-3 + 1e-12);
    }
}

namespace {

/// Zero gravity: a dynamic rod (capsule along z, radius 1 cm, 0.2 kg) at 2 m/s hits a free
/// 11 x 11 sheet (0.242 kg, spacing 5 cm) between two columns. Returns the cloth's and the
/// rod's momentum along y after 0.5 s, and the initial total.
struct RodHit {
    double cloth = 0.0, rod = 0.0, total0 = 0.0;
};
RodHit rodThroughFreeSheet(Mode mode) {
    TestWorld w(Vec3::Zero());
    const double rodMass = 0.2;
    btRigidBody* rod =
        w.body(w.shape<btCapsuleShapeZ>(btScalar(0.01), btScalar(0.6)), rodMass, Vec3(0, 0.1, 0));
    rod->setLinearVelocity(btVector3(0, -2, 0));
    rod->setActivationState(DISABLE_DEACTIVATION);
    ClothSettings s;
    s.particleMass = 0.002;
    s.springStiffness = 20.0;
    auto cloth = makeCloth(horizontalSheet(11, 11, 0.05, 0.0, 0.025), s);
    bullet::BulletClothSettings bs;
    bs.contact.thickness = kThickness;
    applyMode(bs, mode);
    w.add(cloth, bs);
    RodHit r;
    r.total0 = rodMass * -2.0;
    for (int k = 0; k < 120; ++k)
        w.world.stepSimulation(btScalar(kStep), 1, btScalar(kStep));
    for (std::size_t i = 0; i < cloth->particleCount(); ++i)
        r.cloth += cloth->masses()[i] * cloth->velocities()[i].y();
    r.rod = rodMass * double(rod->getLinearVelocity().y());
    UNSCOPED_INFO(measured("dynamic rod through a free sheet, %s: momentum cloth %.6f, rod %.6f, "
                           "total %.6f (before %.6f) N s",
                           modeName(mode), r.cloth, r.rod, r.cloth + r.rod, r.total0));
    return r;
}

} // namespace

TEST_CASE("a dynamic rod thinner than the spacing exchanges momentum with the sheet and "
          "conserves it, by default and with triangle contacts",
          "[contacts][triangles][coupling]") {
    const RodHit off = rodThroughFreeSheet(Mode::ParticlesOnly);
    CHECK(off.cloth == Approx(0.0).margin(1e-9)); // it passed between the particles untouched
    for (Mode mode : {Mode::Default, Mode::Triangles}) {
        const RodHit on = rodThroughFreeSheet(mode);
        // The rod carried the sheet along: a good part of its momentum went to the cloth, and
        // the total is what it was (Bullet's velocities are single precision: 1e-5 relative).
        CHECK(on.cloth < 0.3 * on.total0);
        CHECK(std::abs(on.cloth + on.rod - on.total0) <= 1e-5 * std::abs(on.total0));
    }
}

namespace {

struct EdgeDrop {
    double worstClearance =
        0.0; ///< smallest height of a spring above the ridge where it crosses it [m]
    double finalClearance = 0.0; ///< the same in the last step [m]
    double lowest = 0.0;         ///< lowest particle at the end [m]
};

/// A 9 x 9 sheet (spacing 5 cm) falls onto the ridge of a static box turned 45 degrees about z
/// (a knife edge along z, 30 cm above a floor), the ridge between two columns of particles.
EdgeDrop dropOnEdge(bool triangles, bool boxEdges = false) {
    TestWorld w;
    const double half = 0.05, ridgeY = 0.3;
    const double centreY = ridgeY - half * std::sqrt(2.0);
    w.body(w.shape<btBoxShape>(btVector3(btScalar(half), btScalar(half), btScalar(0.3))), 0.0,
           Vec3(0, centreY, 0),
           btQuaternion(btVector3(0, 0, 1), btScalar(0.25 * 3.14159265358979323846)));
    const std::shared_ptr<Cloth> cloth = addSheetOverFloor(w, 0.36, triangles, boxEdges).clothPtr();
    EdgeDrop r;
    r.worstClearance = std::numeric_limits<double>::infinity();
    for (int k = 0; k < 360; ++k) {
        w.world.stepSimulation(btScalar(kStep), 1, btScalar(kStep));
        r.finalClearance = std::numeric_limits<double>::infinity();
        // Every spring crossing the ridge's plane x = 0 within the box's length and not below
        // the box (the box spans x = 0 from its bottom corner up to the ridge, so a crossing at
        // those heights is inside it): its height above the ridge there.
        for (const auto& sp : cloth->topology().springs()) {
            const Vec3& a = cloth->positions()[sp.a];
            const Vec3& b = cloth->positions()[sp.b];
            if ((a.x() > 0.0) == (b.x() > 0.0) || std::abs(a.z()) > 0.25) continue;
            const double t = a.x() / (a.x() - b.x());
            const double y = a.y() + t * (b.y() - a.y());
            if (y < centreY - half * std::sqrt(2.0)) continue; // under the box
            r.worstClearance = std::min(r.worstClearance, y - ridgeY);
            r.finalClearance = std::min(r.finalClearance, y - ridgeY);
        }
    }
    r.lowest = lowestParticle(*cloth);
    UNSCOPED_INFO(measured(
        "sheet dropped on a knife-edge box ridge (spacing 5 cm), triangle contacts %s, box "
        "edges %s: "
        "smallest height of a spring above the ridge %.5f m over the run, %.5f m at the end "
        "(thickness %.3f), lowest particle %.4f m",
        triangles ? "on" : "off", boxEdges ? "on" : "off", r.worstClearance, r.finalClearance,
        kThickness, r.lowest));
    return r;
}

} // namespace

TEST_CASE("a sheet dropped on a knife-edge box ridge drapes over it with triangle contacts",
          "[contacts][triangles]") {
    // Particles alone: the particles next to the ridge land on the box's slopes, and the ridge
    // pokes up between them through the springs that cross it.
    const EdgeDrop off = dropOnEdge(false);
    CHECK(off.worstClearance < 0.0);
    // Triangles: no spring ever passes below the ridge (at the impact the cloth comes closer
    // than the thickness: measured 2 mm of the 5, at 1.1 m/s and 240 Hz), it rests at the
    // thickness (less the box's single-precision query, 0.5 mm), and the sheet drapes over
    // the ridge, its sides lower than the ridge but clear of the floor.
    const EdgeDrop on = dropOnEdge(true);
    CHECK(on.worstClearance > 0.0);
    CHECK(on.finalClearance >= kThickness - 5e-4);
    CHECK(on.lowest < 0.3 - 0.05);
    CHECK(on.lowest > 0.02);
}

TEST_CASE("a box's knife edge stays under a sheet dropped on it with the default box-edge "
          "contacts",
          "[contacts][edges]") {
    // ContactSettings::boxEdges (on by default): the springs that cross the ridge are kept the
    // thickness above it along their length, without triangle contacts. (Particles alone:
    // the ridge pokes through, the test above.)
    const EdgeDrop edges = dropOnEdge(false, true);
    CHECK(edges.worstClearance > 0.0);
    CHECK(edges.finalClearance >= kThickness - 5e-4);
    CHECK(edges.lowest < 0.3 - 0.05);
    CHECK(edges.lowest > 0.02);
}

TEST_CASE("a box's knife edge raised under a sheet at rest is kept under it with the default "
          "box-edge contacts",
          "[contacts][edges]") {
    // In zero gravity a sheet pinned on its border (9 x 9, spacing 5 cm) rests 2 cm above the
    // ridge of a static box turned 45 degrees about z, the ridge between its two middle
    // columns: the springs across the ridge are clear of it. Then the box is moved 2.2 cm up
    // in one world step (a static body set to a new pose): the ridge is 2 mm above the sheet's
    // particles, none of which touches the box (its slopes stay more than the thickness below
    // them), so only the box-edge test of those springs can lift the sheet over it. (A ridge
    // more than the thickness above them is a deep impact, which the box-edge test leaves.)
    TestWorld w(Vec3::Zero());
    const double half = 0.05, ridgeY = 0.28;
    auto centreAt = [&](double ridge) { return Vec3(0, ridge - half * std::sqrt(2.0), 0); };
    const btQuaternion turned(btVector3(0, 0, 1), btScalar(0.25 * 3.14159265358979323846));
    btRigidBody* box =
        w.body(w.shape<btBoxShape>(btVector3(btScalar(half), btScalar(half), btScalar(0.3))), 0.0,
               centreAt(ridgeY), turned);
    bullet::BulletCloth& handle = addSheetOverFloor(w, ridgeY + 0.02, false, true);
    Cloth& cloth = handle.cloth();
    for (Index i = 0; i < 9; ++i)
        for (Index j : {Index(0), Index(8)}) {
            cloth.pin(i * 9 + j);
            cloth.pin(j * 9 + i);
        }
    // The smallest height above the ridge of a spring between two free particles crossing the
    // ridge's plane x = 0 (the pinned border cannot rise over it).
    auto clearance = [&](double ridge) {
        double least = std::numeric_limits<double>::infinity();
        for (const auto& sp : cloth.topology().springs()) {
            if (cloth.isPinned(sp.a) || cloth.isPinned(sp.b)) continue;
            const Vec3& a = cloth.positions()[sp.a];
            const Vec3& b = cloth.positions()[sp.b];
            if ((a.x() > 0.0) == (b.x() > 0.0) || std::abs(a.z()) > 0.25) continue;
            const double t = a.x() / (a.x() - b.x());
            least = std::min(least, a.y() + t * (b.y() - a.y()) - ridge);
        }
        return least;
    };
    for (int k = 0; k < 120; ++k)
        w.world.stepSimulation(btScalar(kStep), 1, btScalar(kStep));
    const double before = clearance(ridgeY);
    CHECK(before == Approx(0.02).margin(1e-9)); // untouched so far
    const double raised = ridgeY + 0.022;
    box->setWorldTransform(btTransform(turned, bt(centreAt(raised))));
    box->getMotionState()->setWorldTransform(box->getWorldTransform());
    w.world.updateSingleAabb(box);
    double after = 0.0;
    for (int k = 0; k < 60; ++k) {
        w.world.stepSimulation(btScalar(kStep), 1, btScalar(kStep));
        after = clearance(raised);
    }
    UNSCOPED_INFO(measured("ridge raised 2.2 cm under a sheet resting 2 cm above it: springs "
                           "%.5f m above the ridge at the end (thickness %.3f)",
                           after, kThickness));
    CHECK(after >= kThickness - 5e-4);
}
