// Self-collision: a cloth folded onto itself keeps its layers apart when self-collision is on
// (and, as a control, falls through itself when it is off).
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

constexpr double kSpacing = 0.05;
constexpr Index kCols = 11;       // across the strip (x)
constexpr Index kLayerRows = 11;  // rows in each flat layer (along z)
constexpr double kGap = 0.1;      // distance between the layers: the fold's diameter
constexpr double kBottom = 0.014; // bottom layer height: resting on the ground's contact band

/// A strip folded over itself: a bottom layer at y = kBottom from z = 0 to 0.5, a half circle
/// of diameter kGap at z = 0.5, and a top layer at y = kBottom + kGap back to z = 0. Rows
/// follow the strip's length; returns the mesh and, per row, its layer (-1 bottom, +1 top,
/// 0 fold).
TriangleMesh foldedStrip(std::vector<int>& layerOfRow) {
    std::vector<Vec3> path; // centre line of the strip in the y-z plane, spaced kSpacing apart
    for (Index r = 0; r < kLayerRows; ++r)
        path.emplace_back(0.0, kBottom, r * kSpacing);
    layerOfRow.assign(kLayerRows, -1);
    const double zEnd = (kLayerRows - 1) * kSpacing, radius = kGap / 2.0;
    const int foldSteps = int(std::round(M_PI * radius / kSpacing)); // 3 arcs of ~0.052
    for (int k = 1; k < foldSteps; ++k) {
        const double a = M_PI * k / foldSteps;
        path.emplace_back(0.0, kBottom + radius - radius * std::cos(a),
                          zEnd + radius * std::sin(a));
        layerOfRow.push_back(0);
    }
    for (Index r = 0; r < kLayerRows; ++r) {
        path.emplace_back(0.0, kBottom + kGap, zEnd - r * kSpacing);
        layerOfRow.push_back(+1);
    }
    // The rows next to the fold belong to it rather than to a flat layer.
    layerOfRow[kLayerRows - 1] = 0;
    layerOfRow[kLayerRows + std::size_t(foldSteps) - 1] = 0;
    TriangleMesh m;
    const auto rows = Index(path.size());
    for (Index r = 0; r < rows; ++r)
        for (Index c = 0; c < kCols; ++c)
            m.vertices.push_back(path[r] + Vec3((c - 0.5 * (kCols - 1)) * kSpacing, 0, 0));
    for (Index r = 0; r + 1 < rows; ++r) {
        for (Index c = 0; c + 1 < kCols; ++c) {
            const Index a = r * kCols + c, b = a + 1, d = a + kCols, e = d + 1;
            if ((r + c) % 2 == 0) {
                m.triangles.push_back({a, b, e});
                m.triangles.push_back({a, e, d});
            } else {
                m.triangles.push_back({a, b, d});
                m.triangles.push_back({b, e, d});
            }
        }
    }
    return m;
}

struct FoldResult {
    double worstSeparation = std::numeric_limits<double>::infinity(); ///< min over time [m]
    double finalSeparation = 0.0;
    std::size_t selfContacts = 0;
    std::size_t selfPairTests = 0;
};

/// Separation of the layers: the lowest top-layer particle minus the highest bottom-layer
/// particle (both layers lie flat, one over the other).
FoldResult dropFold(bool selfCollision, double thickness) {
    TestWorld w;
    w.body(w.shape<btStaticPlaneShape>(btVector3(0, 1, 0), btScalar(0.0)), 0.0, Vec3::Zero());
    std::vector<int> layer;
    const TriangleMesh mesh = foldedStrip(layer);
    ClothSettings s;
    s.particleMass = 0.002;
    s.springStiffness = 20.0;
    s.damping = 0.004;
    auto cloth = makeCloth(mesh, s);
    bullet::BulletClothSettings bs;
    bs.contact.thickness = 0.01;
    bs.selfCollision.enabled = selfCollision;
    bs.selfCollision.thickness = thickness;
    auto& handle = w.add(cloth, bs);
    FoldResult r;
    for (int step = 0; step < 360; ++step) { // 1.5 s: the top layer falls 0.1 m in ~0.15 s
        w.world.stepSimulation(btScalar(1.0 / 240.0), 1, btScalar(1.0 / 240.0));
        double topLow = std::numeric_limits<double>::infinity(), bottomHigh = -topLow;
        for (Index i = 0; i < cloth->particleCount(); ++i) {
            const int l = layer[i / kCols];
            if (l > 0) topLow = std::min(topLow, cloth->positions()[i].y());
            if (l < 0) bottomHigh = std::max(bottomHigh, cloth->positions()[i].y());
        }
        r.worstSeparation = std::min(r.worstSeparation, topLow - bottomHigh);
        r.finalSeparation = topLow - bottomHigh;
    }
    r.selfContacts = handle.totalStats().selfContacts;
    r.selfPairTests = handle.totalStats().selfPairTests;
    return r;
}

} // namespace

TEST_CASE("a cloth folded onto itself keeps its layers apart with self-collision on", "[self]") {
    const double thickness = 0.01;
    const FoldResult on = dropFold(true, thickness);
    const FoldResult off = dropFold(false, thickness);
    INFO(measured("self-collision: layer separation on %.4f m (worst %.4f), off %.4f m; %zu "
                  "contacts, %zu pair tests",
                  on.finalSeparation, on.worstSeparation, off.finalSeparation, on.selfContacts,
                  on.selfPairTests));
    INFO("separation with self-collision " << on.finalSeparation << " (worst " << on.worstSeparation
                                           << "), without " << off.finalSeparation);
    // With it: the top layer lies on the bottom one and never crosses it. Every particle is
    // kept `thickness` from the triangles of the other layer; the measure compares the lowest
    // top particle with the highest bottom particle anywhere, which undercounts that local
    // gap by the layers' unevenness, so it is held to half the thickness.
    CHECK(on.worstSeparation >= 0.5 * thickness);
    CHECK(on.finalSeparation <= 3.0 * thickness); // and it did fall onto it
    CHECK(on.selfContacts > 0);
    // Without it: the top layer falls through the bottom one to the ground's contact band,
    // where both layers end level (the control shows the check above can fail).
    CHECK(off.finalSeparation < 0.5 * thickness);
    CHECK(off.selfPairTests == 0); // and self-collision costs nothing when it is off
}
