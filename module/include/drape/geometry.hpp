// drape/geometry.hpp: closest-point geometry the cloth's contacts share (self-collision in the
// core; particle, spring and triangle contacts in drape::bullet). Engine-neutral: points and
// shapes in their own frame, no collision library; drape::bullet places them with a body's
// pose.
#pragma once

#include "drape/mesh.hpp"

#include <cmath>
#include <limits>

namespace drape {

/// Closest point to p on triangle (a, b, c) [m]; `barycentric` gets its weights on a, b, c
/// (non-negative, summing to 1). Degenerate triangles give a point of the triangle too.
Vec3 closestPointOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c,
                            Vec3& barycentric);

/// Where the segment from o to e first enters the box |x_k| <= half_k (centred at the origin,
/// along the axes: a box's own frame): true when o is outside the box and the segment reaches
/// it, with `t` in [0, 1] the entry's fraction of the way and `normal` the outward unit normal
/// of the face it enters through (the lowest axis's, for an entry exactly through an edge or
/// corner).
/// Exact: a path that slides past a corner outside the box does not enter it.
bool segmentEntersBox(const Vec3& o, const Vec3& e, const Vec3& half, double& t, Vec3& normal);

/// Where the segment from o to e crosses triangle (a, b, c), from either side: true with `t`
/// in [0, 1] its fraction of the way and `barycentric` the crossing's weights on a, b, c. A
/// segment in the triangle's plane, or a degenerate triangle, crosses nothing.
bool segmentCrossesTriangle(const Vec3& o, const Vec3& e, const Vec3& a, const Vec3& b,
                            const Vec3& c, double& t, Vec3& barycentric);

/// Closest points of segments p0-p1 and q0-q1: s, t in [0, 1] their fractions of the way (the
/// usual clamped solution of the 2 x 2 system, degenerate segments included).
void closestSegmentSegment(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1,
                           double& s, double& t);

/// The nearest point of a shape's surface to a point, in the shape's own frame.
struct SurfacePoint {
    double distance = 0.0;       ///< signed: negative inside the shape [m]
    Vec3 normal = Vec3::UnitY(); ///< unit, outward, at `point`
    Vec3 point = Vec3::Zero();   ///< on the surface [m]
};

/// Box |x_k| <= half_k. Outside: the nearest point is p clamped to the box and the normal
/// points from it to p (a face's, an edge's or a corner's direction). Inside: the nearest face
/// (least half_k - |p_k|, the lowest axis on a tie), a negative distance.
inline SurfacePoint closestOnBox(const Vec3& half, const Vec3& p) {
    const Vec3 q = p.cwiseMax(-half).cwiseMin(half);
    const Vec3 d = p - q;
    const double dist = d.norm();
    if (dist > 0.0) return {dist, d / dist, q};
    int axis = 0;
    double best = std::numeric_limits<double>::infinity();
    for (int k = 0; k < 3; ++k) {
        const double depth = half[k] - std::abs(p[k]);
        if (depth < best) {
            best = depth;
            axis = k;
        }
    }
    Vec3 n = Vec3::Zero();
    n[axis] = p[axis] >= 0.0 ? 1.0 : -1.0;
    Vec3 s = p;
    s[axis] = n[axis] * half[axis];
    return {-best, n, s};
}
/// Sphere of radius r about the origin (at its centre: the normal +y).
SurfacePoint closestOnSphere(double r, const Vec3& p);
/// Capsule: the segment from -halfHeight to +halfHeight along `axis` (0, 1, 2), grown by r
/// (on its core segment: the normal along the next axis).
SurfacePoint closestOnCapsule(int axis, double halfHeight, double r, const Vec3& p);
/// Cylinder of radius r along `axis`, from -halfHeight to +halfHeight. Inside: the nearer of
/// the side wall and the cap on p's side.
SurfacePoint closestOnCylinder(int axis, double r, double halfHeight, const Vec3& p);
/// Solid cone along `axis`: its apex at +halfHeight, its base a disk of radius r at
/// -halfHeight (Bullet's btConeShape without its margin). Outside: the nearest point of the
/// slanted side or the base, the normal from it to p; inside: the nearer of the two, its
/// face's normal. On the axis the radial direction is the next axis.
SurfacePoint closestOnCone(int axis, double r, double halfHeight, const Vec3& p);
/// The convex hull of two spheres (centres c0, c1, radii r0, r1 >= 0): their two caps and the
/// cone touching both (a capsule with unequal ends; Bullet's btMultiSphereShape of two
/// spheres). Exact inside and out; where one sphere holds the other, that sphere. In the
/// half-plane through the axis and p, with b = (r0 - r1) / |c1 - c0| and a = sqrt(1 - b^2),
/// the side's outward normal is (a radial, b axial) and the tangent points split the
/// half-plane into the two caps' regions and the side's.
SurfacePoint closestOnSphereHull(const Vec3& c0, double r0, const Vec3& c1, double r1,
                                 const Vec3& p);

/// Signed distance of p from the box |x_k| <= half_k (negative inside), and its outward unit
/// gradient: from the nearest point outside, the nearest face's normal inside.
inline double boxSignedDistance(const Vec3& half, const Vec3& p, Vec3& gradient) {
    const Vec3 q = p.cwiseAbs() - half;
    const Vec3 outside = q.cwiseMax(0.0);
    const double out = outside.norm();
    if (out > 0.0) {
        gradient = outside.cwiseProduct(p.cwiseSign()) / out;
        return out;
    }
    int k = 0;
    q.maxCoeff(&k);
    gradient = Vec3::Zero();
    gradient[k] = p[k] < 0.0 ? -1.0 : 1.0;
    return q[k];
}

/// Set in a region code (boxRegion) when exactly one axis is beyond the box: a face's prism.
inline constexpr int kBoxFaceRegion = 32;
/// The region of space around the box |x_k| <= half_k that p is in: per axis 0 (within the
/// box's extent), 1 (beyond the + face) or 2 (beyond the - face), as base-3 digits (0 inside),
/// with kBoxFaceRegion set for a face's prism. Two points are in one region when their codes are
/// equal; the box's signed distance is linear on a segment within one face's prism.
inline int boxRegion(const Vec3& half, const Vec3& p) {
    int code = 0, beyond = 0;
    for (int k = 2; k >= 0; --k) {
        const int digit = p[k] > half[k] ? 1 : p[k] < -half[k] ? 2 : 0;
        code = 3 * code + digit;
        beyond += digit != 0;
    }
    return beyond == 1 ? code | kBoxFaceRegion : code;
}
/// A face's prism: exactly one axis beyond the box.
inline bool isBoxFaceRegion(int code) {
    return (code & kBoxFaceRegion) != 0;
}

/// The point of a segment deepest in (or nearest to) a box: its fraction t of the way, and
/// the box's signed distance d and gradient g there.
struct SegmentDeepest {
    double t = 0.0, d = 0.0;
    Vec3 g = Vec3::Zero();
};
/// Where along the segment pa pb the signed distance of the box |x_k| <= half_k is least, given
/// the ends' outward gradients ga and gb (boxSignedDistance). First the point nearest to an
/// edge shared by the faces the two ends see (one or a few edges, each a segment-segment
/// closest point), kept when it is inside the box (the segment cuts that edge: a point inside,
/// not necessarily the deepest) or when no point 1e-6 of the way to either side is deeper (the
/// signed distance is convex along the segment: then it is the least). Otherwise, and for ends
/// seeing opposite faces or no common edge, a golden-section search of the signed distance, to
/// about 1e-5 of the segment. So a segment that enters the box gets a point inside it, and one
/// that stays outside gets its least distance.
SegmentDeepest deepestOnSegment(const Vec3& half, const Vec3& pa, const Vec3& pb, const Vec3& ga,
                                const Vec3& gb);

/// The smallest t in [0, 1] at which o + t d enters the sphere of radius R about c, for an o
/// outside it moving toward it; -1 if it does not.
double sphereEntry(const Vec3& o, const Vec3& d, const Vec3& c, double R);

/// Nearest points of a cloth triangle and a body's surface.
struct TriangleHit {
    bool valid = false;
    double distance = 0.0;           ///< signed, negative when they overlap [m]
    Vec3 normal = Vec3::UnitY();     ///< unit, from the body toward the triangle
    Vec3 bodyPoint = Vec3::Zero();   ///< on the body's surface [m]
    Vec3 barycentric = Vec3::Zero(); ///< the triangle's nearest point, in its weights
};
/// A capsule (core segment p0-p1, radius r; a sphere when p0 = p1) against triangle (a, b, c):
/// the nearest pair among the segment's ends against the triangle and the triangle's edges
/// against the segment (exact unless the segment pierces the triangle; then the triangle's
/// normal, facing away from the segment's middle, and the depth r). Invalid when nothing is
/// nearer than `reach` [m], or the triangle has no area.
TriangleHit capsuleTriangle(const Vec3& p0, const Vec3& p1, double r, const Vec3& a, const Vec3& b,
                            const Vec3& c, double reach);

/// A triangle over the flat part of a box's face: the box |x_k| <= half_k with its edges and
/// corners rounded by `rounding` (Bullet's box with its collision margin: a box of half extents
/// half - rounding grown by a sphere of that radius), in the box's own frame. True when all
/// three corners lie in one face's prism over its flat part (at or beyond the face's plane,
/// within half_j - rounding across it): then the nearest points are exact, from the corners
/// alone (the distance to the face's plane is linear over the triangle): `hit` gets the least
/// of the corners' heights, the face's outward normal, the triangle's nearest point as the
/// mean of the corners within `tie` [m] of the least (a triangle parallel to the face pushed
/// out as a whole) and the point below it on the face, all in the box's frame. False (hit
/// untouched) otherwise: a corner beside an edge or a corner of the box, or inside it, which a
/// general query must answer.
bool triangleOverBoxFace(const Vec3& half, double rounding, const Vec3& a, const Vec3& b,
                         const Vec3& c, double tie, TriangleHit& hit);

/// Where the segment from o to e first comes within R of a capsule's core: the segment from
/// -halfHeight to +halfHeight along `axis` (0, 1, 2; a point when halfHeight is 0). True when
/// o is farther than R from the core and the segment comes that near, with `t` in [0, 1] the
/// fraction of the way there.
bool segmentEntersCapsule(const Vec3& o, const Vec3& e, int axis, double halfHeight, double R,
                          double& t);

} // namespace drape
