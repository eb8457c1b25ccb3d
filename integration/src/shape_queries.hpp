// shape_queries.hpp (private to drape::bullet): where is the surface of a Bullet collision
// shape nearest to a point? Analytic for the primitive shapes, Bullet's GJK/EPA for other
// convex shapes, per-triangle for concave shapes (static triangle meshes, height fields),
// recursion for compounds. All in double precision in the body's frame.
#pragma once

#include "pose.hpp"

#include "drape/geometry.hpp"
#include "drape/mesh.hpp"

#include <Eigen/Core>

class btCollisionShape;
class btTransform;

namespace drape::bullet::detail {

/// Nearest surface point of a shape to a query point.
struct SurfaceHit {
    bool valid = false;
    double distance = 0.0;       ///< signed distance from the surface, negative inside [m]
    Vec3 normal = Vec3::UnitY(); ///< outward unit normal at `point` (world frame)
    Vec3 point = Vec3::Zero();   ///< nearest surface point (world frame) [m]
};

/// Counters the queries add to.
struct QueryCounters {
    std::size_t queries = 0;         ///< closest-point queries made (a compound counts each child)
    std::size_t triangleQueries = 0; ///< triangle-shape queries made (each compound child counts)
};

/// The world AABB of `shape` at `transform`, as its surface queries see it: Bullet's getAabb,
/// except for a cylinder whose circle's two half extents differ. Bullet's own AABB of such a
/// cylinder is the box of its half extents, but its collisions (support functions, getRadius)
/// use one of them as the radius of a round cylinder that reaches beyond that box.
void shapeAabb(const btCollisionShape* shape, const btTransform& transform, btVector3& lo,
               btVector3& hi);

/// The program may have changed shapes since the last call (a Bullet sub-step begins): the
/// faces the queries keep of each polyhedral shape (convex hulls, point clouds, convex
/// triangle meshes) are checked against it again, once per thread, at its next query.
void shapesMayHaveChanged();

/// Signed distance of `p` to `shape` placed at `pose`. Only surfaces nearer than `reach` [m]
/// need to be found (concave shapes search triangles within it; the result is invalid if none
/// is). `prev` is where the point was at the previous step: for two-sided surfaces (triangle
/// meshes) it decides which side the point belongs to.
SurfaceHit closestSurface(const btCollisionShape* shape, const Pose& pose, const Vec3& p,
                          const Vec3& prev, double reach, QueryCounters& counters);

/// Where the path from -> to first comes within `inflate` [m] of a sphere or capsule at
/// `pose` (the shape grown by the cloth's thickness; exact, not through Bullet's ray cast):
/// the hit is the shape's own surface point there and its outward normal, `distance` the
/// path's end below the tangent plane there (<= 0). False for other shapes, for a path that
/// starts within it, or that never comes that close.
bool inflatedPathHit(const btCollisionShape* shape, const Pose& pose, const Vec3& from,
                     const Vec3& to, double inflate, SurfaceHit& hit);

/// closestSurface for a box of half extents `half` (with its margin) at `pose`, whose world
/// face normals (R n).normalized() for n = +e_k, -e_k are faceNormal[2k], faceNormal[2k + 1]:
/// the same result, without the shape's virtual calls and, when the nearest feature is a face,
/// without rotating and normalising the normal again.
SurfaceHit boxSurface(const Vec3& half, const Vec3* faceNormal, const Pose& pose, const Vec3& p,
                      QueryCounters& counters);

/// Nearest points between the triangle (a, b, c) (world frame) and a convex shape, or the
/// convex children of a compound, placed at `transform` (Bullet's GJK and EPA, in single
/// precision, relative to a). Invalid for other shapes (planes, concave meshes), and when
/// nothing is nearer than `reach` [m].
TriangleHit closestToTriangle(const btCollisionShape* shape, const btTransform& transform,
                              const Vec3& a, const Vec3& b, const Vec3& c, double reach,
                              QueryCounters& counters);

/// Where a convex body (or a compound of convex children) moving along `path` first comes
/// within `gap` [m] of a cloth triangle moving from `start` to `end` (its corners), both at
/// constant rates in between. Conservative advancement: at each
/// fraction s the nearest points (closestToTriangle) are at least the gap apart, and nothing
/// closes faster than `rate` per unit s (the body's shift, its turn times `radius`, the
/// fastest corner's move), so the next s is s + (distance - gap) / rate.
struct SweptTriangleHit {
    bool valid = false;
    double s = 0.0;   ///< the fraction of the way where it came within the gap, in [0, 1]
    Pose pose;        ///< the body's pose there
    TriangleHit near; ///< the nearest points there (the triangle at its place at s)
};
/// `radius` [m]: the farthest point of the shape from its origin. Within `tolerance` [m] of
/// the gap counts as reaching it. Invalid if it never comes that close, or a shape
/// closestToTriangle does not answer for.
SweptTriangleHit sweepToTriangle(const btCollisionShape* shape, double radius, const PosePath& path,
                                 const Vec3 (&start)[3], const Vec3 (&end)[3], double gap,
                                 double tolerance, QueryCounters& counters);

} // namespace drape::bullet::detail
