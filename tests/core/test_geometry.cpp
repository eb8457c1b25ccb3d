// Closest-point geometry of drape/geometry.hpp (engine-neutral: the contact stage places these
// shapes with a body's pose). Each result is checked against what defines it: a brute-force
// minimum over a fine sampling of the surface or segment, or a closed form.
#include "helpers.hpp"

#include "drape/cloth.hpp"
#include "drape/geometry.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

using namespace drape;

namespace {

/// Points in the cube [-a, a]^3, reproducibly.
std::vector<Vec3> samplePoints(double a, int count, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-a, a);
    std::vector<Vec3> out;
    for (int k = 0; k < count; ++k)
        out.emplace_back(u(rng), u(rng), u(rng));
    return out;
}

/// Points on the surface of the box |x_k| <= half_k: a grid of `n` x `n` on each face.
std::vector<Vec3> boxSurfaceGrid(const Vec3& half, int n) {
    std::vector<Vec3> out;
    for (int axis = 0; axis < 3; ++axis)
        for (double side : {-1.0, 1.0})
            for (int i = 0; i <= n; ++i)
                for (int j = 0; j <= n; ++j) {
                    Vec3 p;
                    const int a1 = (axis + 1) % 3, a2 = (axis + 2) % 3;
                    p[axis] = side * half[axis];
                    p[a1] = -half[a1] + 2.0 * half[a1] * i / n;
                    p[a2] = -half[a2] + 2.0 * half[a2] * j / n;
                    out.push_back(p);
                }
    return out;
}

double nearestOf(const std::vector<Vec3>& cloud, const Vec3& p) {
    double best = std::numeric_limits<double>::infinity();
    for (const Vec3& q : cloud)
        best = std::min(best, (q - p).norm());
    return best;
}

bool insideBox(const Vec3& half, const Vec3& p) {
    return (p.cwiseAbs().array() < half.array()).all();
}

} // namespace

TEST_CASE("closest points of two segments: the least distance, against a fine sampling",
          "[geometry]") {
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    auto rand3 = [&]() { return Vec3(u(rng), u(rng), u(rng)); };
    for (int trial = 0; trial < 40; ++trial) {
        Vec3 p0 = rand3(), p1 = rand3(), q0 = rand3(), q1 = rand3();
        if (trial == 0) q1 = q0 + 0.7 * (p1 - p0); // parallel
        if (trial == 1) p1 = p0;                   // a point against a segment
        if (trial == 2) q1 = q0;                   // a segment against a point
        if (trial == 3) p1 = p0, q1 = q0;          // two points
        double s = -1.0, t = -1.0;
        closestSegmentSegment(p0, p1, q0, q1, s, t);
        REQUIRE(s >= 0.0);
        REQUIRE(s <= 1.0);
        REQUIRE(t >= 0.0);
        REQUIRE(t <= 1.0);
        const double found = ((p0 + s * (p1 - p0)) - (q0 + t * (q1 - q0))).norm();
        constexpr int kN = 400;
        double brute = std::numeric_limits<double>::infinity();
        for (int i = 0; i <= kN; ++i)
            for (int j = 0; j <= kN; ++j)
                brute = std::min(brute, ((p0 + (double(i) / kN) * (p1 - p0)) -
                                         (q0 + (double(j) / kN) * (q1 - q0)))
                                            .norm());
        // The sampling's grid is at most 2 * 2 sqrt(3) / kN from any pair of points.
        CHECK(found <= brute + 1e-12);
        CHECK(found >= brute - 4.0 * std::sqrt(3.0) / kN);
    }
}

TEST_CASE("the nearest point of a box's surface, inside and out", "[geometry]") {
    const Vec3 half(0.3, 0.1, 0.2);
    const std::vector<Vec3> surface = boxSurfaceGrid(half, 120);
    for (const Vec3& p : samplePoints(0.5, 300, 3)) {
        const SurfacePoint q = closestOnBox(half, p);
        INFO("p = " << p.transpose());
        // On the surface, with p at the signed distance along the unit normal.
        CHECK(q.normal.norm() == Approx(1.0).epsilon(1e-14));
        CHECK((q.point + q.distance * q.normal - p).norm() < 1e-14);
        const Vec3 rel = q.point.cwiseAbs() - half;
        CHECK(std::abs(rel.maxCoeff()) < 1e-15);
        // Negative exactly inside; its size the nearest surface point's distance.
        CHECK((q.distance < 0.0) == insideBox(half, p));
        CHECK(std::abs(q.distance) <= nearestOf(surface, p) + 1e-12);
        CHECK(std::abs(q.distance) >= nearestOf(surface, p) - 0.6 / 120);
        // The signed distance the spring-box test uses is the same function.
        Vec3 g;
        const double d = boxSignedDistance(half, p, g);
        CHECK(d == Approx(q.distance).margin(1e-15));
        CHECK(g.norm() == Approx(1.0).epsilon(1e-14));
        if (q.distance > 0.0) CHECK((g - q.normal).norm() < 1e-14);
    }
}

TEST_CASE("the nearest points of a sphere, a capsule and a cylinder", "[geometry]") {
    const double r = 0.25, hh = 0.4;
    for (const Vec3& p : samplePoints(0.8, 300, 5)) {
        INFO("p = " << p.transpose());
        const SurfacePoint s = closestOnSphere(r, p);
        CHECK(s.distance == Approx(p.norm() - r).margin(1e-15));
        CHECK((s.point.norm() - r) == Approx(0.0).margin(1e-15));
        CHECK((s.point + s.distance * s.normal - p).norm() < 1e-14);
        for (int axis = 0; axis < 3; ++axis) {
            // Capsule: the distance to its core segment, less r (the segment sampled finely).
            const SurfacePoint c = closestOnCapsule(axis, hh, r, p);
            double core = std::numeric_limits<double>::infinity();
            for (int i = 0; i <= 4000; ++i) {
                Vec3 a = Vec3::Zero();
                a[axis] = -hh + 2.0 * hh * i / 4000;
                core = std::min(core, (p - a).norm());
            }
            CHECK(c.distance == Approx(core - r).margin(2.0 * hh / 4000));
            CHECK((c.point + c.distance * c.normal - p).norm() < 1e-14);
            // Cylinder: inside, the nearer of wall and cap; outside, the distance to the solid
            // (the radial and axial excesses are orthogonal).
            const SurfacePoint y = closestOnCylinder(axis, r, hh, p);
            Vec3 radial = p;
            radial[axis] = 0.0;
            const double dr = radial.norm() - r, da = std::abs(p[axis]) - hh;
            const double expect = dr <= 0.0 && da <= 0.0
                                      ? std::max(dr, da)
                                      : std::hypot(std::max(dr, 0.0), std::max(da, 0.0));
            CHECK(y.distance == Approx(expect).margin(1e-14));
            CHECK(y.normal.norm() == Approx(1.0).epsilon(1e-14));
            CHECK((y.point + y.distance * y.normal - p).norm() < 1e-14);
        }
    }
    // On a capsule's axis and at a sphere's centre the normal is still a unit vector.
    CHECK(closestOnSphere(r, Vec3::Zero()).normal.norm() == 1.0);
    CHECK(closestOnCapsule(1, hh, r, Vec3(0.0, 0.1, 0.0)).distance == -r);
}

TEST_CASE("the nearest point of a cone", "[geometry]") {
    // Against the cone's surface sampled finely: in the plane through the axis and p, the
    // slant from the apex (0, hh) to the rim (r, -hh) and the base from (0, -hh) to the rim.
    const double r = 0.3, hh = 0.35;
    const int n = 4000;
    for (const Vec3& p : samplePoints(0.8, 300, 7)) {
        for (int axis = 0; axis < 3; ++axis) {
            INFO("p = " << p.transpose() << ", axis " << axis);
            const SurfacePoint c = closestOnCone(axis, r, hh, p);
            Vec3 radial = p;
            radial[axis] = 0.0;
            const double rho = radial.norm(), y = p[axis];
            double nearest = std::numeric_limits<double>::infinity();
            for (int i = 0; i <= n; ++i) {
                const double t = double(i) / n;
                nearest = std::min(nearest, std::hypot(rho - t * r, y - (hh - 2.0 * hh * t)));
                nearest = std::min(nearest, std::hypot(rho - t * r, y + hh));
            }
            const bool inside = y >= -hh && y <= hh && rho <= r * (hh - y) / (2.0 * hh);
            CHECK((c.distance < 0.0) == inside);
            CHECK(std::abs(c.distance) == Approx(nearest).margin(2.0 * hh / n));
            CHECK(c.normal.norm() == Approx(1.0).epsilon(1e-14));
            CHECK((c.point + c.distance * c.normal - p).norm() < 1e-14);
            // The point lies on the surface: on the base disk or on the slant.
            Vec3 pr = c.point;
            pr[axis] = 0.0;
            const double onBase = std::abs(c.point[axis] + hh) + std::max(pr.norm() - r, 0.0);
            const double onSlant = std::abs(pr.norm() - r * (hh - c.point[axis]) / (2.0 * hh));
            CHECK(std::min(onBase, onSlant) < 1e-14);
        }
    }
    // On the axis the normal is a unit vector; the apex's side points up, the base's down.
    CHECK(closestOnCone(1, r, hh, Vec3(0.0, 0.5, 0.0)).normal.y() == 1.0);
    CHECK(closestOnCone(1, r, hh, Vec3(0.0, -0.5, 0.0)).normal.y() == -1.0);
    CHECK(closestOnCone(1, r, hh, Vec3(0.0, -0.3, 0.0)).distance == Approx(-0.05));
}

TEST_CASE("the nearest point of the hull of two spheres", "[geometry]") {
    // Against its surface sampled finely: in the half-plane through the axis and p (x radial,
    // y along the axis from c0), the profile is sphere 0's arc, the tangent segment and sphere
    // 1's arc; p is inside where some ball between the two (centre and radius interpolated)
    // holds it (the hull of two balls is the union of those).
    struct Case {
        Vec3 c0;
        double r0;
        Vec3 c1;
        double r1;
    };
    const std::vector<Case> cases = {
        {Vec3(-0.15, 0.0, 0.0), 0.25, Vec3(0.15, 0.0, 0.0), 0.2}, // overlapping, unequal
        {Vec3(0.1, -0.2, 0.05), 0.05, Vec3(-0.1, 0.3, 0.2), 0.3}, // a cone-like hull
        {Vec3(0.0, 0.1, 0.0), 0.2, Vec3(0.0, -0.1, 0.1), 0.2},    // equal: a capsule
        {Vec3(0.0, 0.0, 0.0), 0.4, Vec3(0.05, 0.05, 0.0), 0.1}};  // one inside the other
    const int n = 4000;
    for (const Case& k : cases) {
        const Vec3 axis = k.c1 - k.c0;
        const double d = axis.norm();
        const Vec3 u = axis / d;
        const bool contained = d <= std::abs(k.r0 - k.r1);
        const double b = (k.r0 - k.r1) / d, a = contained ? 0.0 : std::sqrt(1.0 - b * b);
        for (const Vec3& p : samplePoints(0.8, 300, 11)) {
            INFO("p = " << p.transpose() << ", spheres " << k.c0.transpose() << " " << k.r0 << ", "
                        << k.c1.transpose() << " " << k.r1);
            const SurfacePoint c = closestOnSphereHull(k.c0, k.r0, k.c1, k.r1, p);
            const double y = (p - k.c0).dot(u), x = (p - k.c0 - y * u).norm();
            double nearest = std::numeric_limits<double>::infinity(), inside = 1.0;
            for (int i = 0; i <= n; ++i) {
                const double t = double(i) / n, phi = -M_PI / 2.0 + M_PI * t;
                inside = std::min(inside, std::hypot(x, y - t * d) - (k.r0 + t * (k.r1 - k.r0)));
                const double x0 = k.r0 * std::cos(phi), y0 = k.r0 * std::sin(phi);
                const double x1 = k.r1 * std::cos(phi), y1 = d + k.r1 * std::sin(phi);
                if (contained) {
                    const bool big0 = k.r0 >= k.r1;
                    nearest = std::min(nearest, big0 ? std::hypot(x - x0, y - y0)
                                                     : std::hypot(x - x1, y - y1));
                    continue;
                }
                if (-b * x0 + a * y0 <= 0.0)
                    nearest = std::min(nearest, std::hypot(x - x0, y - y0));
                if (-b * x1 + a * y1 >= d * a)
                    nearest = std::min(nearest, std::hypot(x - x1, y - y1));
                const double sx = k.r0 * a + t * (k.r1 - k.r0) * a;
                const double sy = k.r0 * b + t * (d + (k.r1 - k.r0) * b);
                nearest = std::min(nearest, std::hypot(x - sx, y - sy));
            }
            CHECK((c.distance < 0.0) == (inside < 0.0));
            CHECK(std::abs(c.distance) == Approx(nearest).margin(4.0 * M_PI * 0.4 / n));
            CHECK(c.normal.norm() == Approx(1.0).epsilon(1e-12));
            CHECK((c.point + c.distance * c.normal - p).norm() < 1e-12);
        }
    }
}

TEST_CASE("a box's regions: one face's prism is where the distance is linear", "[geometry]") {
    const Vec3 half(0.3, 0.1, 0.2);
    CHECK(boxRegion(half, Vec3(0.0, 0.0, 0.0)) == 0);
    const int top = boxRegion(half, Vec3(0.1, 0.5, -0.1));
    CHECK(isBoxFaceRegion(top));
    CHECK(boxRegion(half, Vec3(-0.2, 0.2, 0.15)) == top);
    CHECK(boxRegion(half, Vec3(-0.2, -0.2, 0.15)) != top); // the bottom face's
    const int edge = boxRegion(half, Vec3(0.4, 0.5, 0.0));
    CHECK_FALSE(isBoxFaceRegion(edge));
    CHECK(edge != top);
    CHECK_FALSE(isBoxFaceRegion(boxRegion(half, Vec3(0.4, 0.5, 0.3)))); // a corner's
    // Along a segment within the top face's prism the signed distance is its height above
    // the face: linear.
    const Vec3 a(-0.25, 0.3, 0.1), b(0.2, 0.15, -0.18);
    REQUIRE(boxRegion(half, a) == top);
    REQUIRE(boxRegion(half, b) == top);
    Vec3 g;
    for (double t : {0.0, 0.3, 0.77, 1.0})
        CHECK(boxSignedDistance(half, a + t * (b - a), g) ==
              Approx((1.0 - t) * (a.y() - half.y()) + t * (b.y() - half.y())).margin(1e-15));
}

TEST_CASE("the deepest point of a segment against a box, against a fine sampling", "[geometry]") {
    const Vec3 half(0.3, 0.1, 0.2);
    auto check = [&](const Vec3& pa, const Vec3& pb) {
        Vec3 ga, gb, g;
        boxSignedDistance(half, pa, ga);
        boxSignedDistance(half, pb, gb);
        const SegmentDeepest deep = deepestOnSegment(half, pa, pb, ga, gb);
        constexpr int kN = 20000;
        double brute = std::numeric_limits<double>::infinity();
        for (int i = 0; i <= kN; ++i)
            brute = std::min(brute, boxSignedDistance(half, pa + (double(i) / kN) * (pb - pa), g));
        INFO("pa = " << pa.transpose() << ", pb = " << pb.transpose());
        CHECK(deep.t >= 0.0);
        CHECK(deep.t <= 1.0);
        CHECK(deep.d == Approx(boxSignedDistance(half, pa + deep.t * (pb - pa), g)).margin(0.0));
        // Never deeper than the deepest sample, to the sampling's step.
        CHECK(deep.d >= brute - 1e-9 - (pb - pa).norm() / kN);
        // A segment that enters the box: a point inside it. One that stays outside: its least
        // distance, beyond the search's tolerance (1e-5 of the way; the distance is
        // 1-Lipschitz).
        if (brute < 0.0) CHECK(deep.d < 0.0);
        if (deep.d >= 0.0) CHECK(deep.d <= brute + 1e-5 * (pb - pa).norm());
    };
    // Over the top-right edge (ends above the top face and beside the right face): the point
    // nearest to the edge.
    check(Vec3(0.2, 0.12, 0.05), Vec3(0.33, -0.05, 0.08));
    // Cutting the edge (the middle inside the box).
    check(Vec3(0.25, 0.11, -0.1), Vec3(0.31, 0.05, 0.1));
    // Over a corner, ends beside two faces that share an edge and a third.
    check(Vec3(0.28, 0.13, 0.21), Vec3(0.35, 0.02, 0.19));
    // Ends beside opposite faces (a spring across the box, its middle deepest): the search.
    check(Vec3(-0.35, 0.0, 0.02), Vec3(0.36, 0.03, -0.05));
    check(Vec3(-0.1, 0.15, 0.0), Vec3(0.1, -0.15, 0.01));
    // Random pairs near the box.
    const std::vector<Vec3> ends = samplePoints(0.45, 60, 9);
    for (std::size_t k = 0; k + 1 < ends.size(); k += 2)
        check(ends[k], ends[k + 1]);
}

TEST_CASE("where a path enters a sphere", "[geometry]") {
    const Vec3 c(0.5, -0.2, 0.1);
    // Head on from 2 away along x, radius 1: a quarter of the way along a path of 4.
    CHECK(sphereEntry(c + Vec3(-2.0, 0.0, 0.0), Vec3(4.0, 0.0, 0.0), c, 1.0) ==
          Approx(0.25).epsilon(1e-15));
    // Off the centre by 0.6: it enters where x = -0.8, at (2 - 0.8) / 4 of the way.
    CHECK(sphereEntry(c + Vec3(-2.0, 0.6, 0.0), Vec3(4.0, 0.0, 0.0), c, 1.0) ==
          Approx(0.3).epsilon(1e-14));
    // Missing it, moving away, starting inside, stopping short: none.
    CHECK(sphereEntry(c + Vec3(-2.0, 1.01, 0.0), Vec3(4.0, 0.0, 0.0), c, 1.0) == -1.0);
    CHECK(sphereEntry(c + Vec3(-2.0, 0.0, 0.0), Vec3(-4.0, 0.0, 0.0), c, 1.0) == -1.0);
    CHECK(sphereEntry(c + Vec3(-0.5, 0.0, 0.0), Vec3(4.0, 0.0, 0.0), c, 1.0) == -1.0);
    CHECK(sphereEntry(c + Vec3(-2.0, 0.0, 0.0), Vec3(0.9, 0.0, 0.0), c, 1.0) == -1.0);
}

TEST_CASE("a capsule against a triangle: the nearest points, against a fine sampling",
          "[geometry]") {
    std::mt19937 rng(21);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    auto rand3 = [&]() { return Vec3(u(rng), u(rng), u(rng)); };
    const Vec3 a(0.0, 0.0, 0.0), b(1.0, 0.1, 0.0), c(0.2, 0.9, 0.1);
    const double r = 0.05;
    Vec3 bary;
    for (int trial = 0; trial < 60; ++trial) {
        Vec3 p0 = rand3(), p1 = rand3();
        if (trial % 5 == 0) p1 = p0; // a sphere
        const TriangleHit h = capsuleTriangle(p0, p1, r, a, b, c, 10.0);
        REQUIRE(h.valid);
        // The distance from the core segment to the triangle, sampled along the segment (each
        // sample's nearest triangle point exact), less r. Where the segment pierces the
        // triangle the distance is 0 and the hit reports the depth -r.
        constexpr int kN = 4000;
        double core = std::numeric_limits<double>::infinity();
        for (int i = 0; i <= kN; ++i) {
            const Vec3 q = p0 + (double(i) / kN) * (p1 - p0);
            core = std::min(core, (closestPointOnTriangle(q, a, b, c, bary) - q).norm());
        }
        INFO("p0 = " << p0.transpose() << ", p1 = " << p1.transpose());
        CHECK(h.distance == Approx(core - r).margin((p1 - p0).norm() / kN + 1e-12));
        CHECK(h.normal.norm() == Approx(1.0).epsilon(1e-12));
        CHECK(h.barycentric.minCoeff() >= -1e-12);
        CHECK(h.barycentric.sum() == Approx(1.0).epsilon(1e-12));
        // Not piercing: the body's point is on the capsule, r from its core segment.
        // (Piercing: r from the crossing along the triangle's normal, the depth r.)
        if (h.distance > -r) {
            double s = 0.0, t = 0.0;
            closestSegmentSegment(p0, p1, h.bodyPoint, h.bodyPoint, s, t);
            CHECK((p0 + s * (p1 - p0) - h.bodyPoint).norm() == Approx(r).margin(1e-9));
        }
        // Apart: the triangle's nearest point is the body's point moved out by the distance.
        if (h.distance > 0.0) {
            const Vec3 tri = h.barycentric.x() * a + h.barycentric.y() * b + h.barycentric.z() * c;
            CHECK((tri - (h.bodyPoint + h.distance * h.normal)).norm() < 1e-9);
        }
    }
    // Out of reach, or a triangle without area: no hit.
    CHECK_FALSE(capsuleTriangle(Vec3(0.3, 0.3, 2.0), Vec3(0.4, 0.3, 2.0), r, a, b, c, 1.0).valid);
    CHECK_FALSE(
        capsuleTriangle(Vec3(0.3, 0.3, 0.2), Vec3(0.4, 0.3, 0.2), r, a, b, 2.0 * b, 1.0).valid);
}

TEST_CASE("a triangle over a box's face: the nearest points, against a fine sampling",
          "[geometry]") {
    // A box of half extents (0.4, 0.1, 0.3) rounded by 0.04 at its edges and corners; its
    // distance from a point is the inner box's (half - 0.04) less 0.04.
    const Vec3 half(0.4, 0.1, 0.3);
    const double rounding = 0.04;
    auto roundedDistance = [&](const Vec3& p) {
        return closestOnBox(half - Vec3::Constant(rounding), p).distance - rounding;
    };
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    int found = 0;
    for (int trial = 0; trial < 300; ++trial) {
        // Corners over a random face's flat part, up to 5 cm above it (some on it).
        const int k = trial % 3;
        const double side = trial % 2 == 0 ? 1.0 : -1.0;
        Vec3 v[3];
        for (Vec3& p : v) {
            for (int j = 0; j < 3; ++j)
                p[j] = (2.0 * u(rng) - 1.0) * (half[j] - rounding);
            p[k] = side * (half[k] + (trial % 7 == 0 ? 0.0 : 0.05 * u(rng)));
        }
        TriangleHit h;
        REQUIRE(triangleOverBoxFace(half, rounding, v[0], v[1], v[2], 1e-12, h));
        ++found;
        constexpr int kN = 300;
        double least = std::numeric_limits<double>::infinity();
        for (int i = 0; i <= kN; ++i)
            for (int j = 0; i + j <= kN; ++j) {
                const double s = double(i) / kN, t = double(j) / kN;
                least =
                    std::min(least, roundedDistance(v[0] + s * (v[1] - v[0]) + t * (v[2] - v[0])));
            }
        INFO("trial " << trial);
        // A corner is a sample: the sampled least is exact for these linear heights.
        CHECK(h.distance == Approx(least).margin(1e-12));
        const Vec3 onTriangle =
            h.barycentric.x() * v[0] + h.barycentric.y() * v[1] + h.barycentric.z() * v[2];
        CHECK(roundedDistance(onTriangle) == Approx(h.distance).margin(1e-12));
        CHECK(h.barycentric.minCoeff() >= 0.0);
        CHECK(h.barycentric.sum() == Approx(1.0).epsilon(1e-12));
        CHECK(h.normal[k] == side);
        CHECK(h.normal.norm() == 1.0);
        CHECK((onTriangle - (h.bodyPoint + h.distance * h.normal)).norm() < 1e-12);
        CHECK(roundedDistance(h.bodyPoint) == Approx(0.0).margin(1e-12));
    }
    CHECK(found == 300);
    // A triangle parallel to the top face is pushed as a whole: its centre.
    TriangleHit flat;
    REQUIRE(triangleOverBoxFace(half, rounding, Vec3(0.0, 0.11, 0.0), Vec3(0.1, 0.11, 0.0),
                                Vec3(0.0, 0.11, 0.1), 1e-9, flat));
    CHECK((flat.barycentric - Vec3::Constant(1.0 / 3.0)).norm() < 1e-15);
    CHECK(flat.distance == Approx(0.01).margin(1e-15));
    // Not over one face's flat part: a corner over the rounded edge, a corner inside the box,
    // corners over two faces. The caller asks a general query there.
    TriangleHit none;
    CHECK_FALSE(triangleOverBoxFace(half, rounding, Vec3(0.0, 0.12, 0.0), Vec3(0.38, 0.12, 0.0),
                                    Vec3(0.0, 0.12, 0.1), 1e-9, none));
    CHECK_FALSE(triangleOverBoxFace(half, rounding, Vec3(0.0, 0.09, 0.0), Vec3(0.1, 0.12, 0.0),
                                    Vec3(0.0, 0.12, 0.1), 1e-9, none));
    CHECK_FALSE(triangleOverBoxFace(half, rounding, Vec3(0.0, 0.12, 0.0), Vec3(0.45, 0.0, 0.0),
                                    Vec3(0.0, 0.12, 0.1), 1e-9, none));
    CHECK_FALSE(none.valid);
}

TEST_CASE("where a path first comes within reach of a capsule's core, against a fine sampling",
          "[geometry]") {
    std::mt19937 rng(31);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    auto rand3 = [&]() { return Vec3(u(rng), u(rng), u(rng)); };
    const double R = 0.3;
    int entered = 0, missed = 0;
    for (int trial = 0; trial < 200; ++trial) {
        const int axis = trial % 3;
        const double hh = trial % 4 == 0 ? 0.0 : 0.4; // every fourth a sphere
        const Vec3 o = 1.5 * rand3(), e = 1.5 * rand3();
        auto toCore = [&](const Vec3& p) {
            Vec3 c = Vec3::Zero();
            c[axis] = std::clamp(p[axis], -hh, hh);
            return (p - c).norm();
        };
        // The first sample of the path within R of the core.
        constexpr int kN = 20000;
        double first = -1.0;
        for (int i = 0; i <= kN && first < 0.0; ++i)
            if (toCore(o + (double(i) / kN) * (e - o)) <= R) first = double(i) / kN;
        double t = -1.0;
        const bool hit = segmentEntersCapsule(o, e, axis, hh, R, t);
        INFO("o = " << o.transpose() << ", e = " << e.transpose() << ", axis " << axis);
        if (toCore(o) <= R) {
            CHECK_FALSE(hit); // starts within reach: not an entry
            continue;
        }
        // Where the sampling finds the path within reach, the test does, at most a step
        // earlier (a path that only grazes the reach between two samples may be found alone).
        if (first >= 0.0) {
            REQUIRE(hit);
            CHECK(t <= first + 1e-12);
            CHECK(t >= first - 1.0 / kN);
            CHECK(toCore(o + t * (e - o)) == Approx(R).epsilon(1e-9));
            ++entered;
        } else if (hit) {
            CHECK(toCore(o + t * (e - o)) == Approx(R).epsilon(1e-9));
        } else {
            ++missed;
        }
    }
    CHECK(entered > 20); // the trials cover both outcomes
    CHECK(missed > 20);
}

TEST_CASE("Cloth::rayCast finds where a segment first crosses the cloth", "[geometry][query]") {
    // An 11 x 11 sheet in the x-z plane (y = 0, spacing 0.1 m from the origin along +x and
    // +z): a vertical segment through (0.23, 0.37) crosses it halfway, at that point, in a
    // triangle whose corners' weights give the point back; the nearest corner is (0.2, 0.4).
    SheetSpec spec;
    spec.rows = 11;
    spec.cols = 11;
    spec.spacing = 0.1;
    spec.uAxis = Vec3::UnitX();
    spec.vAxis = Vec3::UnitZ();
    const TriangleMesh mesh = makeSheet(spec);
    Cloth cloth(ClothTopology::build(mesh), ClothSettings{});
    const auto hit = cloth.rayCast(Vec3(0.23, 1.0, 0.37), Vec3(0.23, -1.0, 0.37));
    REQUIRE(hit);
    CHECK(hit->fraction == Approx(0.5).epsilon(1e-12));
    CHECK((hit->point - Vec3(0.23, 0.0, 0.37)).norm() < 1e-12);
    const Triangle& t = cloth.topology().triangles()[hit->triangle];
    const Vec3 back = hit->barycentric[0] * cloth.positions()[t[0]] +
                      hit->barycentric[1] * cloth.positions()[t[1]] +
                      hit->barycentric[2] * cloth.positions()[t[2]];
    CHECK((back - hit->point).norm() < 1e-12);
    CHECK(hit->barycentric.minCoeff() >= 0.0);
    CHECK(hit->barycentric.sum() == Approx(1.0).epsilon(1e-12));
    CHECK((cloth.positions()[hit->particle] - Vec3(0.2, 0.0, 0.4)).norm() < 1e-12);
    CHECK((hit->normal - Vec3::UnitY()).norm() < 1e-12); // facing the segment's start
    // From below: the same point, the normal facing down.
    const auto below = cloth.rayCast(Vec3(0.23, -1.0, 0.37), Vec3(0.23, 3.0, 0.37));
    REQUIRE(below);
    CHECK(below->fraction == Approx(0.25).epsilon(1e-12));
    CHECK((below->normal + Vec3::UnitY()).norm() < 1e-12);
    // Segments that stop short, pass beside the sheet or run in its plane cross nothing.
    CHECK(!cloth.rayCast(Vec3(0.23, 1.0, 0.37), Vec3(0.23, 0.01, 0.37)));
    CHECK(!cloth.rayCast(Vec3(1.5, 1.0, 0.37), Vec3(1.5, -1.0, 0.37)));
    CHECK(!cloth.rayCast(Vec3(-1.0, 0.0, 0.37), Vec3(2.0, 0.0, 0.37)));
    // The first layer along the way: with the sheet's left part moved down by 0.5 m, a slanted
    // segment from above the right part crosses it first (at x = 0.6), the left part after.
    for (Index i = 0; i < cloth.particleCount(); ++i) {
        Vec3 p = cloth.positions()[i];
        if (p.x() < 0.45) cloth.setPosition(i, p - Vec3(0, 0.5, 0));
    }
    const auto first = cloth.rayCast(Vec3(1.0, 1.0, 0.55), Vec3(0.2, -1.0, 0.55));
    REQUIRE(first);
    CHECK(first->fraction == Approx(0.5).epsilon(1e-12));
    CHECK(first->point.x() == Approx(0.6).epsilon(1e-12));
    // The nearest corner by distance, not by weight: in the unit right triangle (0,0), (1,0),
    // (0,1), the point (0.35, 0.35) weighs the right-angle corner least (0.3 against 0.35 each)
    // but lies nearest to it (0.495 against 0.738).
    TriangleMesh one;
    one.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 0, 1)};
    one.triangles = {{0, 1, 2}};
    Cloth single(ClothTopology::build(one), ClothSettings{});
    const auto corner = single.rayCast(Vec3(0.35, 1.0, 0.35), Vec3(0.35, -1.0, 0.35));
    REQUIRE(corner);
    CHECK(corner->particle == 0);
    // A non-finite end is refused by name.
    REQUIRE_DRAPE_ERROR(cloth.rayCast(Vec3(std::nan(""), 0, 0), Vec3::Zero()), ErrorCode::NonFinite,
                        "rayCast");
}
