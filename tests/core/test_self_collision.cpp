// Self-collision in the core (ClothSettings::selfCollision): a cloth stepped on its own, with
// no Bullet world, keeps its particles off its own triangles.
#include "helpers.hpp"

#include "drape/cloth.hpp"
#include "drape/geometry.hpp"

#include <catch2/catch.hpp>

#include <algorithm>

using namespace drape;

namespace {

/// Two sheets in one cloth (two components): a 4 x 4 one `gap` above the middle of a 6 x 6
/// one, shifted by half a cell so that its particles fall onto the lower one's triangles.
TriangleMesh twoSheets(double gap) {
    const double spacing = 0.05;
    SheetSpec spec;
    spec.rows = 6;
    spec.cols = 6;
    spec.spacing = spacing;
    spec.uAxis = Vec3::UnitX();
    spec.vAxis = Vec3::UnitZ();
    TriangleMesh lower = makeSheet(spec);
    spec.rows = 4;
    spec.cols = 4;
    spec.origin = Vec3(1.5 * spacing, gap, 1.5 * spacing);
    const TriangleMesh upper = makeSheet(spec);
    const auto base = static_cast<Index>(lower.vertices.size());
    lower.vertices.insert(lower.vertices.end(), upper.vertices.begin(), upper.vertices.end());
    for (Triangle t : upper.triangles) {
        for (Index& i : t)
            i += base;
        lower.triangles.push_back(t);
    }
    return lower;
}

/// The smallest distance of an upper-sheet particle to a lower-sheet triangle [m].
double closestApproach(const Cloth& c, std::size_t lowerParticles, std::size_t lowerTriangles) {
    double closest = 1e300;
    const auto& x = c.positions();
    const auto& tris = c.topology().triangles();
    for (std::size_t p = lowerParticles; p < x.size(); ++p)
        for (std::size_t t = 0; t < lowerTriangles; ++t) {
            Vec3 bary;
            const Vec3 q =
                closestPointOnTriangle(x[p], x[tris[t][0]], x[tris[t][1]], x[tris[t][2]], bary);
            closest = std::min(closest, (x[p] - q).norm());
        }
    return closest;
}

} // namespace

TEST_CASE("self-collision in the core: a sheet falling onto another part of the same cloth "
          "stays a thickness above it",
          "[self_collision]") {
    const TriangleMesh mesh = twoSheets(0.1);
    const std::size_t lowerParticles = 36, lowerTriangles = 50;
    auto run = [&](bool self) {
        ClothSettings s;
        s.particleMass = 0.001;
        s.selfCollision.enabled = self;
        s.selfCollision.thickness = 0.01;
        Cloth cloth(ClothTopology::build(mesh), s);
        for (Index i = 0; i < lowerParticles; ++i) // the lower sheet is a table
            cloth.pin(i);
        double closest = 1e300;
        std::size_t contacts = 0;
        for (int k = 0; k < 120; ++k) { // 2 s at 60 Hz: the upper sheet falls 0.1 m onto it
            cloth.step(1.0 / 60.0);
            contacts += cloth.lastSelfCollision().contacts;
            closest = std::min(closest, closestApproach(cloth, lowerParticles, lowerTriangles));
        }
        // The upper sheet's particles resting above the lower sheet's plane.
        std::size_t above = 0;
        for (std::size_t p = lowerParticles; p < cloth.particleCount(); ++p)
            above += cloth.positions()[p].y() > 0.0;
        return std::make_tuple(closest, contacts, above);
    };
    const auto [closest, contacts, above] = run(true);
    CHECK(contacts > 0);
    CHECK(closest >= 0.01 * (1.0 - 1e-6)); // the thickness, in every step
    // All 16 particles of the upper sheet rest on the lower one.
    CHECK(above == 16);
    // Without it the upper sheet falls through the lower one.
    const auto [closestOff, contactsOff, aboveOff] = run(false);
    CHECK(contactsOff == 0);
    CHECK(aboveOff == 0);
    (void)closestOff;
    // Its settings are validated when it is on.
    ClothSettings bad;
    bad.selfCollision.enabled = true;
    bad.selfCollision.thickness = -1.0;
    REQUIRE_DRAPE_ERROR(Cloth(ClothTopology::build(mesh), bad), ErrorCode::InvalidArgument,
                        "selfCollision.thickness");
}

TEST_CASE("self-collision leaves a sheet finer than its thickness at rest", "[self_collision]") {
    // A 20 x 20 sheet of 1.2 cm spacing with the default 1 cm thickness: the triangles next to
    // a particle's own lie within the thickness of it in the rest shape. Nothing acts on the
    // sheet (no gravity, no damping schedule): nothing may move. (Before rest-shape neighbours
    // were left out, self-collision pushed them a thickness apart: 83 million contacts, 59 J
    // from nothing, strain 17.)
    SheetSpec spec;
    spec.rows = 20;
    spec.cols = 20;
    spec.spacing = 0.012;
    spec.uAxis = Vec3::UnitX();
    spec.vAxis = Vec3::UnitZ();
    ClothSettings s;
    s.selfCollision.enabled = true;
    s.gravity = Vec3::Zero();
    s.relativeDamping = 0.0;
    Cloth sheet(ClothTopology::build(makeSheet(spec)), s);
    std::size_t contacts = 0;
    for (int k = 0; k < 60; ++k) {
        sheet.step(1.0 / 60.0);
        contacts += sheet.lastSelfCollision().contacts;
    }
    CHECK(contacts == 0);
    CHECK(sheet.kineticEnergy() == 0.0);
    CHECK(sheet.maxStrain() <= 1e-12);
}

TEST_CASE("self-collision catches a layer that arrives from beyond its pair list within one step",
          "[self_collision]") {
    // The upper sheet of twoSheets starts 3 cm above the lower one (beyond the 2 cm its pair
    // list reaches at the step's start) moving down at `speed`: within the first 60 Hz step it
    // would cross the lower sheet. The passes of the step's sub-steps must list the pair on
    // the way (pairsHold) and keep it a thickness above.
    for (const double speed : {1.0, 3.0, 6.0}) {
        const TriangleMesh mesh = twoSheets(0.03);
        const std::size_t lowerParticles = 36, lowerTriangles = 50;
        ClothSettings s;
        s.particleMass = 0.001;
        s.selfCollision.enabled = true;
        s.selfCollision.thickness = 0.01;
        Cloth cloth(ClothTopology::build(mesh), s);
        for (Index i = 0; i < lowerParticles; ++i)
            cloth.pin(i);
        for (Index i = lowerParticles; i < cloth.particleCount(); ++i)
            cloth.setVelocity(i, Vec3(0, -speed, 0));
        double closest = 1e300;
        for (int k = 0; k < 30; ++k) {
            cloth.step(1.0 / 60.0);
            closest = std::min(closest, closestApproach(cloth, lowerParticles, lowerTriangles));
        }
        std::size_t above = 0;
        for (std::size_t p = lowerParticles; p < cloth.particleCount(); ++p)
            above += cloth.positions()[p].y() > 0.0;
        INFO("speed " << speed << " m/s: closest " << closest << " m, above " << above);
        // The projection is linearised in the triangle's corners: within 1e-3 of it.
        CHECK(closest >= 0.01 * (1.0 - 1e-3));
        CHECK(above == 16);
    }
}

TEST_CASE("self-collision thicker than the mesh can show: a sheet folded onto itself rests at "
          "0.4 spacings and gains no energy",
          "[self_collision]") {
    // A 21 x 21 sheet of 5 cm, its left half pinned flat, its right edge carried over a half
    // circle onto the left half in 1 s, then let go. Each pair keeps at most 0.4 times the
    // mesh's spacing there (its shortest rest edge): a thickness near 0.71 spacings (a
    // particle to the far triangle of its own cell) made a folded cloth push its own cells
    // apart. (Before: at 0.7 spacings, 282 J and strain 14, half the sheet through the other;
    // at 1 spacing the same.)
    const Index n = 21;
    const double spacing = 0.05;
    for (const double thickness : {0.035, 0.05}) {
        SheetSpec spec;
        spec.rows = n;
        spec.cols = n;
        spec.spacing = spacing;
        spec.origin = Vec3(-0.5, 0.0, -0.5);
        spec.uAxis = Vec3::UnitX();
        spec.vAxis = Vec3::UnitZ();
        ClothSettings s;
        s.selfCollision.enabled = true;
        s.selfCollision.thickness = thickness;
        Cloth cloth(ClothTopology::build(makeSheet(spec)), s);
        const Index half = (n - 1) / 2;
        for (Index r = 0; r < n; ++r)
            for (Index c = 0; c <= half; ++c)
                cloth.pin(sheetIndex(spec, r, c));
        std::vector<Index> edge;
        for (Index r = 0; r < n; ++r)
            edge.push_back(sheetIndex(spec, r, n - 1));
        const double dt = 1.0 / 60.0;
        std::size_t through = 0; // free particles over the pinned half, below its plane
        double peakEnergy = 0.0;
        for (int f = 0; f < 180; ++f) {
            const double t = cloth.time() + dt;
            if (t <= 1.0 + 1e-9) {
                const double angle = 3.14159265358979 * t;
                for (Index i : edge)
                    cloth.setKinematicTarget(i,
                                             Vec3(0.5 * std::cos(angle), 0.5 * std::sin(angle),
                                                  cloth.positions()[i].z()),
                                             t);
            } else if (cloth.isPinned(edge[0])) {
                for (Index i : edge)
                    cloth.unpin(i);
            }
            cloth.step(dt);
            if (t > 1.0) peakEnergy = std::max(peakEnergy, cloth.kineticEnergy());
            for (Index r = 0; r < n; ++r)
                for (Index c = half + 1; c < n; ++c) {
                    const Vec3& p = cloth.positions()[sheetIndex(spec, r, c)];
                    through += p.x() < -0.03 && p.x() > -0.5 && p.y() < 0.0;
                }
        }
        // Where the folded half rests over the pinned half (away from the fold and the rims).
        double lowest = 1e300, highest = -1e300;
        for (Index r = 2; r + 2 < n; ++r)
            for (Index c = half + 2; c < n; ++c) {
                const Vec3& p = cloth.positions()[sheetIndex(spec, r, c)];
                if (p.x() > -0.05 || p.x() < -0.45) continue;
                lowest = std::min(lowest, p.y());
                highest = std::max(highest, p.y());
            }
        INFO("thickness " << thickness << ": through " << through << ", resting at y in [" << lowest
                          << ", " << highest << "], peak kinetic energy after the "
                          << "release " << peakEnergy << " J, strain " << cloth.maxStrain());
        CHECK(through == 0);
        REQUIRE(lowest < 1e300);
        CHECK(lowest >= 0.4 * spacing * (1.0 - 1e-3)); // what each pair keeps
        CHECK(highest <= 0.4 * spacing + 0.01);        // resting on it, not thrown off
        CHECK(peakEnergy < 0.1);                       // the fold's own swing: 0.035 J
        CHECK(cloth.kineticEnergy() < 1e-3);
        CHECK(cloth.maxStrain() <= s.limiter.maxStrain + 1e-3);
    }
}
