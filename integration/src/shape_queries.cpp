// Closest surface points of Bullet collision shapes (see shape_queries.hpp).
#include "shape_queries.hpp"

#include <BulletCollision/CollisionShapes/btBox2dShape.h>
#include <BulletCollision/CollisionShapes/btConvexHullShape.h>
#include <BulletCollision/CollisionShapes/btConvexPointCloudShape.h>
#include <BulletCollision/CollisionShapes/btConvexTriangleMeshShape.h>
#include <BulletCollision/CollisionShapes/btMultiSphereShape.h>
#include <BulletCollision/CollisionShapes/btTriangleShape.h>
#include <BulletCollision/CollisionShapes/btUniformScalingShape.h>
#include <BulletCollision/NarrowPhaseCollision/btGjkEpaPenetrationDepthSolver.h>
#include <BulletCollision/NarrowPhaseCollision/btGjkPairDetector.h>
#include <BulletCollision/NarrowPhaseCollision/btPointCollector.h>
#include <BulletCollision/NarrowPhaseCollision/btVoronoiSimplexSolver.h>
#include <LinearMath/btConvexHullComputer.h>
#include <btBulletCollisionCommon.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <optional>
#include <unordered_map>
#include <vector>

namespace drape::bullet::detail {

namespace {
/// The half extent Bullet takes as a cylinder's radius (btCylinderShape::getRadius, its support
/// functions): the y half extent of an x cylinder, the x half extent of a y or z one; the third
/// is not used.
int cylinderRadiusAxis(int upAxis) {
    return upAxis == 0 ? 1 : 0;
}
} // namespace

void shapeAabb(const btCollisionShape* shape, const btTransform& transform, btVector3& lo,
               btVector3& hi) {
    if (shape->getShapeType() != CYLINDER_SHAPE_PROXYTYPE) {
        shape->getAabb(transform, lo, hi);
        return;
    }
    const auto* cyl = static_cast<const btCylinderShape*>(shape);
    const int axis = cyl->getUpAxis();
    btVector3 half = cyl->getHalfExtentsWithMargin();
    const btScalar radius = half[cylinderRadiusAxis(axis)];
    for (int k = 0; k < 3; ++k)
        if (k != axis) half[k] = radius;
    btTransformAabb(half, btScalar(0), transform, lo, hi);
}

namespace {

/// Fills a hit from a local-frame result.
SurfaceHit makeHit(const Pose& pose, double distance, const Vec3& localNormal,
                   const Vec3& localPoint) {
    SurfaceHit h;
    h.valid = true;
    h.distance = distance;
    // A body's rotation comes from single precision: its columns are unit to ~1e-7 only, and
    // a contact force along a normal that is not unit would cancel a load only to that
    // fraction (a resting particle would keep a residual acceleration).
    h.normal = (pose.R * localNormal).normalized();
    h.point = pose.toWorld(localPoint);
    return h;
}

/// makeHit for a box, whose world face normals faceNormal[2k], faceNormal[2k + 1] (for the
/// local normals +e_k, -e_k; see boxSurface) were made by makeHit's own expression: a local
/// normal that is a face's (+-1 along one axis, +0 on the others, as boxQuery gives when the
/// nearest feature is a face) takes its world normal from the table.
SurfaceHit boxHit(const Pose& pose, double distance, const Vec3& localNormal,
                  const Vec3& localPoint, const Vec3* faceNormal) {
    if (faceNormal) {
        for (int k = 0; k < 3; ++k) {
            const Vec3& n = localNormal;
            if ((n[k] == 1.0 || n[k] == -1.0) && n[(k + 1) % 3] == 0.0 && n[(k + 2) % 3] == 0.0) {
                SurfaceHit h;
                h.valid = true;
                h.distance = distance;
                h.normal = faceNormal[2 * k + (n[k] < 0.0 ? 1 : 0)];
                h.point = pose.toWorld(localPoint);
                return h;
            }
        }
    }
    return makeHit(pose, distance, localNormal, localPoint);
}

// The primitives' nearest surface points (drape/geometry.hpp), placed at the pose.
SurfaceHit boxQuery(const Vec3& e, const Vec3& p, const Pose& pose,
                    const Vec3* faceNormal = nullptr) {
    const SurfacePoint q = closestOnBox(e, p);
    return boxHit(pose, q.distance, q.normal, q.point, faceNormal);
}

SurfaceHit placed(const Pose& pose, const SurfacePoint& q) {
    return makeHit(pose, q.distance, q.normal, q.point);
}

SurfaceHit planeQuery(const btStaticPlaneShape* plane, const Vec3& p, const Pose& pose) {
    const Vec3 n = toVec(plane->getPlaneNormal()).normalized();
    const double dist = n.dot(p) - double(plane->getPlaneConstant());
    return makeHit(pose, dist, n, p - dist * n);
}

// Any other convex shape: Bullet's GJK (distance outside) and EPA (depth inside) between the
// shape, margin included as Bullet's rigid bodies see it, and a point (a zero-radius sphere).
SurfaceHit convexQuery(const btConvexShape* shape, const Vec3& p, const Pose& pose) {
    btSphereShape point(0.0f);
    btVoronoiSimplexSolver simplex;
    btGjkEpaPenetrationDepthSolver epa;
    btGjkPairDetector gjk(&point, shape, &simplex, &epa);
    btGjkPairDetector::ClosestPointInput in;
    in.m_transformA.setIdentity();
    in.m_transformA.setOrigin(toBt(p));
    in.m_transformB.setIdentity();
    btPointCollector out;
    gjk.getClosestPoints(in, out, nullptr);
    if (!out.m_hasResult) return {};
    Vec3 n = toVec(out.m_normalOnBInWorld);
    const double len = n.norm();
    if (!(len > 0.0) || !std::isfinite(len)) return {};
    n /= len;
    return makeHit(pose, double(out.m_distance), n, toVec(out.m_pointInWorld));
}

/// A polyhedral convex shape's faces as planes n . x = d (outward unit n, local frame, scaled
/// points, margin not included) and as polygons, built once per shape and kept while its
/// corners stay as they were (polyhedronFaces).
struct HullFaces {
    std::vector<btVector3> points; ///< the shape's scaled corners when built (the key)
    /// The gShapeGeneration at which `points` were last found to be the shape's.
    std::uint64_t checkedAt = 0;
    std::vector<Vec3> normal;
    std::vector<double> offset;
    /// Face f's corners are corner[first[f]] ... corner[first[f + 1] - 1], counter-clockwise
    /// seen from outside (along -normal[f]).
    std::vector<std::size_t> first;
    std::vector<Vec3> corner;
    /// The face across rim k of face f (from corner[first[f] + k] to the next): across[first[f]
    /// + k]. Filled only when every rim has one (`walkable`).
    std::vector<std::uint32_t> across;
    bool walkable = false; ///< the faces close up: a query may walk from face to face
    /// A flat hull: two faces, one polygon seen from either side (flatQuery measures it).
    bool flat = false;
    double size = 0.0; ///< the hull's largest extent [m]
    /// The face this thread's last query found nearest, tried first by the next (particles
    /// are queried in index order, so neighbours follow each other). Only a start: the answer
    /// is the same from any face.
    mutable std::size_t lastFace = 0;
};

/// Builds the faces of the hull of `points` (btConvexHullComputer): at least four, or the
/// two sides of a flat one (`flat`); none for fewer points or no area (then the queries keep
/// using GJK).
void buildFaces(const std::vector<btVector3>& points, HullFaces& out) {
    out.normal.clear();
    out.offset.clear();
    out.first.assign(1, 0);
    out.corner.clear();
    out.across.clear();
    out.walkable = false;
    out.flat = false;
    btConvexHullComputer hull;
    hull.compute(&points[0].x(), int(sizeof(btVector3)), int(points.size()), 0, 0);
    if (hull.faces.size() < 2) return;
    Vec3 centre = Vec3::Zero(), lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
    for (int k = 0; k < hull.vertices.size(); ++k) {
        const Vec3 v = toVec(hull.vertices[k]);
        centre += v;
        lo = lo.cwiseMin(v);
        hi = hi.cwiseMax(v);
    }
    centre /= double(hull.vertices.size());
    out.size = (hi - lo).maxCoeff();
    std::vector<int> cornerVertex; // the hull's vertex at each corner
    for (int f = 0; f < hull.faces.size(); ++f) {
        // Newell's normal of the face polygon, through its vertices' mean.
        const btConvexHullComputer::Edge* first = &hull.edges[hull.faces[f]];
        const btConvexHullComputer::Edge* e = first;
        Vec3 n = Vec3::Zero(), mean = Vec3::Zero();
        const std::size_t start = out.corner.size();
        int count = 0;
        do {
            const Vec3 a = toVec(hull.vertices[e->getSourceVertex()]);
            const Vec3 b = toVec(hull.vertices[e->getTargetVertex()]);
            n += a.cross(b); // twice the area along the loop's normal (Newell)
            mean += a;
            out.corner.push_back(a);
            cornerVertex.push_back(e->getSourceVertex());
            ++count;
            e = e->getNextEdgeOfFace();
        } while (e != first && count <= hull.edges.size());
        const double len = n.norm();
        if (!(len > 1e-12 * out.size * out.size) || count < 3) {
            out.corner.resize(start);
            cornerVertex.resize(start);
            continue;
        }
        n /= len;
        mean /= double(count);
        if (n.dot(mean - centre) < 0.0) { // the loop runs clockwise seen from outside
            n = -n;
            std::reverse(out.corner.begin() + std::ptrdiff_t(start), out.corner.end());
            std::reverse(cornerVertex.begin() + std::ptrdiff_t(start), cornerVertex.end());
        }
        out.normal.push_back(n);
        out.offset.push_back(n.dot(mean));
        out.first.push_back(out.corner.size());
    }
    // Each rim runs one way round its face; the face across it runs it the other way.
    const std::size_t faces = out.normal.size();
    std::unordered_map<std::uint64_t, std::uint32_t> rimOwner; // (from, to) vertex -> face
    auto key = [](int from, int to) {
        return (std::uint64_t(std::uint32_t(from)) << 32) | std::uint32_t(to);
    };
    for (std::size_t f = 0; f < faces; ++f)
        for (std::size_t c = out.first[f], end = out.first[f + 1]; c < end; ++c)
            rimOwner[key(cornerVertex[c], cornerVertex[c + 1 == end ? out.first[f] : c + 1])] =
                std::uint32_t(f);
    out.across.assign(out.corner.size(), 0);
    out.walkable = faces >= 4;
    for (std::size_t f = 0; f < faces && out.walkable; ++f)
        for (std::size_t c = out.first[f], end = out.first[f + 1]; c < end; ++c) {
            const auto other = rimOwner.find(
                key(cornerVertex[c + 1 == end ? out.first[f] : c + 1], cornerVertex[c]));
            if (other == rimOwner.end()) {
                out.walkable = false;
                break;
            }
            out.across[c] = other->second;
        }
    if (!out.walkable) out.across.clear();
    // All its points in one plane: the polygon, seen from both sides (Newell's normals of
    // the two loops are opposite).
    out.flat = out.normal.size() == 2 && out.normal[0].dot(out.normal[1]) < -0.999999;
    if (out.normal.size() < 4 && !out.flat) {
        out.normal.clear();
        out.offset.clear();
        out.first.assign(1, 0);
        out.corner.clear();
    }
}

/// The point of the rim from a to b nearest to p.
inline Vec3 nearestOnRim(const Vec3& p, const Vec3& a, const Vec3& b) {
    const Vec3 ab = b - a;
    const double len2 = ab.squaredNorm();
    const double t = len2 > 0.0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
    return a + t * ab;
}

/// hullQuery for a flat hull (a polygon grown by the margin): the face on the point's side
/// (where the point is in the polygon's plane, the side it came from, `prev`); the projection
/// if it lies in the polygon, else the nearest rim point.
SurfaceHit flatQuery(const HullFaces& h, const Vec3& p, const Vec3& prev, const Pose& pose,
                     double margin) {
    const double s0 = h.normal[0].dot(p) - h.offset[0];
    const double side = s0 != 0.0 ? s0 : h.normal[0].dot(prev) - h.offset[0];
    const std::size_t f = side >= 0.0 ? 0 : 1;
    const Vec3& n = h.normal[f];
    const double s = n.dot(p) - h.offset[f]; // >= 0 but for rounding
    const Vec3* c = h.corner.data() + h.first[f];
    const std::size_t m = h.first[f + 1] - h.first[f];
    const Vec3 q = p - s * n;
    bool inside = true;
    for (std::size_t k = 0; k < m && inside; ++k)
        inside = (c[k + 1 == m ? 0 : k + 1] - c[k]).cross(q - c[k]).dot(n) >= 0.0;
    if (!inside) {
        double nearest2 = std::numeric_limits<double>::infinity();
        Vec3 nearest = p;
        for (std::size_t k = 0; k < m; ++k) {
            const Vec3 e = nearestOnRim(p, c[k], c[k + 1 == m ? 0 : k + 1]);
            const double d2 = (p - e).squaredNorm();
            if (d2 < nearest2) {
                nearest2 = d2;
                nearest = e;
            }
        }
        const double d = std::sqrt(nearest2);
        if (d > 1e-12 * h.size) {
            const Vec3 out = (p - nearest) / d;
            return makeHit(pose, d - margin, out, p - (d - margin) * out);
        }
    }
    const double distance = s - margin;
    return makeHit(pose, distance, n, p - distance * n);
}

std::atomic<std::uint64_t> gShapeGeneration{1};

/// Collects the corners a hull is the hull of, for the kinds polyhedronFaces measures.
class CornerCollector : public btInternalTriangleIndexCallback {
  public:
    explicit CornerCollector(std::vector<btVector3>& out) : out_(out) {}
    void internalProcessTriangleIndex(btVector3* tri, int, int) override {
        out_.insert(out_.end(), tri, tri + 3);
    }

  private:
    std::vector<btVector3>& out_;
};

/// The corners of a polyhedral convex shape in its frame, scaled (margin not included):
/// a convex hull's or a point cloud's points, a convex triangle mesh's vertices (each as often
/// as its triangles name it). False for other shapes.
bool polyhedronCorners(const btConvexShape* shape, std::vector<btVector3>& out) {
    out.clear();
    const btVector3 scaling = shape->getLocalScaling();
    switch (shape->getShapeType()) {
    case CONVEX_HULL_SHAPE_PROXYTYPE: {
        const auto* hull = static_cast<const btConvexHullShape*>(shape);
        const btVector3* pts = hull->getUnscaledPoints();
        for (int i = 0; i < hull->getNumPoints(); ++i)
            out.push_back(pts[i] * scaling);
        return true;
    }
    case CONVEX_POINT_CLOUD_SHAPE_PROXYTYPE: {
        const auto* cloud = static_cast<const btConvexPointCloudShape*>(shape);
        const btVector3* pts = cloud->getUnscaledPoints();
        for (int i = 0; pts && i < cloud->getNumPoints(); ++i)
            out.push_back(pts[i] * scaling);
        return true;
    }
    case CONVEX_TRIANGLEMESH_SHAPE_PROXYTYPE: {
        // (The mesh interface applies the shape's scaling, which setLocalScaling put there.)
        const auto* mesh = static_cast<const btConvexTriangleMeshShape*>(shape);
        const btStridingMeshInterface* source = mesh->getMeshInterface();
        if (!source) return false;
        CornerCollector collect(out);
        const btScalar big = BT_LARGE_FLOAT;
        source->InternalProcessAllTriangles(&collect, btVector3(-big, -big, -big),
                                            btVector3(big, big, big));
        return true;
    }
    default:
        return false;
    }
}

/// The faces of a polyhedral convex shape (polyhedronCorners; a thread-local cache by shape,
/// cleared when it holds many shapes): its corners are compared with those the faces were
/// built from once per thread after each shapesMayHaveChanged(), and the faces are built
/// again if they differ. Null for other shapes.
const HullFaces* polyhedronFaces(const btConvexShape* shape) {
    thread_local std::unordered_map<const btConvexShape*, HullFaces> cache;
    thread_local std::vector<btVector3> corners;
    const std::uint64_t generation = gShapeGeneration.load(std::memory_order_relaxed);
    auto it = cache.find(shape);
    if (it != cache.end() && it->second.checkedAt == generation) return &it->second;
    if (!polyhedronCorners(shape, corners)) return nullptr;
    if (it != cache.end()) {
        HullFaces& h = it->second;
        if (h.points.size() == corners.size() &&
            (corners.empty() || std::memcmp(h.points.data(), corners.data(),
                                            sizeof(btVector3) * corners.size()) == 0)) {
            h.checkedAt = generation;
            return &h;
        }
    } else {
        if (cache.size() >= 256) cache.clear();
        it = cache.emplace(shape, HullFaces{}).first;
    }
    HullFaces& h = it->second;
    h.points = corners;
    h.checkedAt = generation;
    h.normal.clear(); // (a shape at a reused address, or with fewer points: no old faces)
    h.offset.clear();
    h.first.assign(1, 0);
    h.corner.clear();
    h.lastFace = 0;
    if (h.points.size() >= 4) buildFaces(h.points, h);
    return &h;
}

/// How far inside a face's polygon (times the hull's size) a point's projection must lie for
/// the last query's face to answer without the scan (hullQuery).
constexpr double kHintRoom = 1e-9;

/// hullQuery's answer for a point in front of the last query's face, from the faces it is
/// in front of only: they are found by walking from that face across rims to faces the point
/// is in front of (from outside a convex polyhedron, the faces in front of a point are one
/// connected patch, and it holds the farthest-ahead face and every rim the nearest point can
/// lie on). The answer is the scan's: the lowest-numbered face whose polygon holds the
/// projection, else the nearest rim point (ties to the lowest face and rim), the normal of the
/// lowest-numbered farthest-ahead face where it must. Nothing when the point is not in front
/// of that face or the faces do not close up (then hullQuery scans every face).
std::optional<SurfaceHit> walkFaces(const HullFaces& h, const Vec3& p, const Pose& pose,
                                    double margin, double reach) {
    const std::size_t faces = h.normal.size();
    if (!h.walkable || h.lastFace >= faces) return std::nullopt;
    const auto ahead = [&](std::size_t f) { return h.normal[f].dot(p) - h.offset[f]; };
    if (!(ahead(h.lastFace) > 0.0)) return std::nullopt;
    thread_local std::vector<std::uint32_t> seenAt;
    thread_local std::vector<std::uint32_t> queue;
    thread_local std::uint32_t stamp = 0;
    if (seenAt.size() < faces) seenAt.resize(faces, 0);
    if (++stamp == 0) { // wrapped: forget every old mark
        std::fill(seenAt.begin(), seenAt.end(), 0u);
        stamp = 1;
    }
    queue.assign(1, std::uint32_t(h.lastFace));
    seenAt[h.lastFace] = stamp;
    std::size_t best = faces, insideFace = faces, nearFace = faces, nearRim = 0;
    double farthest = -std::numeric_limits<double>::infinity();
    double nearest2 = std::numeric_limits<double>::infinity();
    Vec3 nearest = p;
    for (std::size_t next = 0; next < queue.size(); ++next) {
        const std::size_t f = queue[next];
        const Vec3& n = h.normal[f];
        const double s = ahead(f); // > 0: only such faces are queued
        if (reach > 0.0 && s - margin > reach) return SurfaceHit{}; // beyond reach
        if (s > farthest || (s == farthest && f < best)) {
            farthest = s;
            best = f;
        }
        const Vec3* c = h.corner.data() + h.first[f];
        const std::size_t m = h.first[f + 1] - h.first[f];
        for (std::size_t k = 0; k < m; ++k) { // the faces across, in front of the point too
            const std::uint32_t g = h.across[h.first[f] + k];
            if (seenAt[g] == stamp) continue;
            seenAt[g] = stamp;
            if (ahead(g) > 0.0) queue.push_back(g);
        }
        if (f > insideFace) continue; // a lower face already holds the projection
        const Vec3 q = p - s * n;
        bool inside = true;
        for (std::size_t k = 0; k < m && inside; ++k) {
            const Vec3& a = c[k];
            const Vec3& b = c[k + 1 == m ? 0 : k + 1];
            inside = (b - a).cross(q - a).dot(n) >= 0.0;
        }
        if (inside) {
            insideFace = f;
            continue;
        }
        for (std::size_t k = 0; k < m; ++k) {
            const Vec3 e = nearestOnRim(p, c[k], c[k + 1 == m ? 0 : k + 1]);
            const double d2 = (p - e).squaredNorm();
            if (d2 < nearest2 ||
                (d2 == nearest2 && (f < nearFace || (f == nearFace && k < nearRim)))) {
                nearest2 = d2;
                nearest = e;
                nearFace = f;
                nearRim = k;
            }
        }
    }
    if (insideFace < faces) {
        h.lastFace = insideFace;
        const Vec3& n = h.normal[insideFace];
        const double distance = ahead(insideFace) - margin;
        return makeHit(pose, distance, n, p - distance * n);
    }
    h.lastFace = best; // the next particle's walk starts from a face in front of this one
    const double d = std::sqrt(nearest2);
    if (!(d > 1e-12 * h.size)) {
        const Vec3& n = h.normal[best];
        const double distance = farthest - margin;
        return makeHit(pose, distance, n, p - distance * n);
    }
    const Vec3 n = (p - nearest) / d;
    const double distance = d - margin;
    return makeHit(pose, distance, n, p - distance * n);
}

/// A polyhedral convex shape (a convex hull, a point cloud or a convex triangle mesh; margin
/// included: the hull of its corners grown by a sphere of that radius) and a point in its
/// frame, exactly from its faces. Outside the hull of the points:
/// if the point's projection on a face it is in front of lies in that face's polygon, the
/// projection is the nearest point (every other face's plane passes no farther ahead of the
/// point, since the projection is in the hull: the faces are read in order until one is found);
/// else the nearest point lies on the rim of a face the point is in front of, the nearest of
/// those. Inside, the face farthest ahead of the point is the nearest (the projection on it
/// lies in the face). A point ahead of some face's plane by more than `reach` (> 0) is
/// farther than that from the hull: an invalid hit, as closestSurface allows. Nothing for a
/// hull without faces (fewer than four points, or no area: the caller asks GJK then); a flat
/// hull is a polygon grown by the margin (flatQuery), `prev` (where the point was) the side
/// it is on when it lies in the polygon's plane. GJK per
/// particle and cloth step was 70 % of the cost of a cloth resting on a rock, and where an
/// edge or a corner was nearest it still cost a rock three times a box.
std::optional<SurfaceHit> hullQuery(const btConvexShape* shape, const Vec3& p, const Vec3& prev,
                                    const Pose& pose, double reach) {
    const HullFaces* built = polyhedronFaces(shape);
    if (!built || built->normal.empty()) return std::nullopt;
    const HullFaces& h = *built;
    const double margin = double(shape->getMargin());
    if (h.flat) return flatQuery(h, p, prev, pose, margin);
    const std::size_t faces = h.normal.size();
    // The last query's face first: if the point is in front of it and its projection lies
    // in the polygon, farther than kHintRoom times the hull's size from every rim, that
    // projection is the nearest point, the one the scan below would find (no other face can
    // hold a point so far inside this one's polygon; nearer a rim, rounding could let two
    // faces claim it, and the scan's order decides).
    if (h.lastFace < faces) {
        const std::size_t f = h.lastFace;
        const Vec3& n = h.normal[f];
        const double s = n.dot(p) - h.offset[f];
        if (reach > 0.0 && s - margin > reach) return SurfaceHit{}; // beyond reach
        if (s > 0.0) {
            const Vec3* c = h.corner.data() + h.first[f];
            const std::size_t m = h.first[f + 1] - h.first[f];
            const Vec3 q = p - s * n;
            const double room = kHintRoom * h.size;
            bool inside = true;
            for (std::size_t k = 0; k < m && inside; ++k) {
                const Vec3& a = c[k];
                const Vec3 ab = c[k + 1 == m ? 0 : k + 1] - a;
                const double across = ab.cross(q - a).dot(n); // |ab| times q's room from the rim
                inside = across > 0.0 && across * across >= room * room * ab.squaredNorm();
            }
            if (inside) {
                const double distance = s - margin;
                return makeHit(pose, distance, n, p - distance * n);
            }
        }
    }
    if (const std::optional<SurfaceHit> walked = walkFaces(h, p, pose, margin, reach))
        return *walked;
    std::size_t best = 0;
    double ahead = -std::numeric_limits<double>::infinity();
    double nearest2 = std::numeric_limits<double>::infinity(); // of the rims in front
    Vec3 nearest = p;
    for (std::size_t f = 0; f < faces; ++f) {
        const Vec3& n = h.normal[f];
        const double s = n.dot(p) - h.offset[f];
        if (reach > 0.0 && s - margin > reach) return SurfaceHit{}; // beyond reach
        if (s > ahead) {
            ahead = s;
            best = f;
        }
        if (!(s > 0.0)) continue;
        const Vec3* c = h.corner.data() + h.first[f];
        const std::size_t m = h.first[f + 1] - h.first[f];
        const Vec3 q = p - s * n;
        bool inside = true;
        for (std::size_t k = 0; k < m && inside; ++k) {
            const Vec3& a = c[k];
            const Vec3& b = c[k + 1 == m ? 0 : k + 1];
            inside = (b - a).cross(q - a).dot(n) >= 0.0;
        }
        if (inside) {
            h.lastFace = f;
            const double distance = s - margin;
            return makeHit(pose, distance, n, p - distance * n);
        }
        for (std::size_t k = 0; k < m; ++k) {
            const Vec3 e = nearestOnRim(p, c[k], c[k + 1 == m ? 0 : k + 1]);
            const double d2 = (p - e).squaredNorm();
            if (d2 < nearest2) {
                nearest2 = d2;
                nearest = e;
            }
        }
    }
    if (!(ahead > 0.0)) { // inside
        const Vec3& n = h.normal[best];
        const double distance = ahead - margin;
        return makeHit(pose, distance, n, p - distance * n);
    }
    // Off a rim: d >= ahead > 0 (the point is off every face's plane by at most its distance).
    // On a corner itself, where rounding put it ahead of a face whose polygon it missed: the
    // face farthest ahead.
    const double d = std::sqrt(nearest2);
    if (!(d > 1e-12 * h.size)) {
        const Vec3& n = h.normal[best];
        const double distance = ahead - margin;
        return makeHit(pose, distance, n, p - distance * n);
    }
    const Vec3 n = (p - nearest) / d;
    const double distance = d - margin;
    return makeHit(pose, distance, n, p - distance * n);
}

// Concave shapes: the nearest triangle within reach. The surface is two-sided; the point
// belongs to the side its previous position was on, so a point that crossed a triangle
// within a step gets a negative distance and is pushed back.
class NearestTriangle : public btTriangleCallback {
  public:
    NearestTriangle(const Vec3& p, const Vec3& prev)
        : p_(p), prev_(prev), pathLo_(p.cwiseMin(prev)), pathHi_(p.cwiseMax(prev)) {}
    void processTriangle(btVector3* tri, int, int) override {
        const Vec3 a = toVec(tri[0]), b = toVec(tri[1]), c = toVec(tri[2]);
        // A triangle that can neither be nearer than the best so far (its box is not) nor have
        // been crossed (its box misses the path's) changes nothing: skipped (a heightfield
        // hands over the cells around the query's box too).
        if (found_) {
            const Vec3 lo = a.cwiseMin(b).cwiseMin(c), hi = a.cwiseMax(b).cwiseMax(c);
            const bool path =
                (lo.array() <= pathHi_.array()).all() && (hi.array() >= pathLo_.array()).all();
            if (!path) {
                if (best_ < 0.0) return;
                const Vec3 out = (lo - p_).cwiseMax(p_ - hi).cwiseMax(0.0);
                if (out.squaredNorm() >= best_ * best_) return;
            }
        }
        Vec3 bary;
        const Vec3 q = closestPointOnTriangle(p_, a, b, c, bary);
        Vec3 face = (b - a).cross(c - a);
        const double area2 = face.norm();
        if (!(area2 > 0.0)) return; // degenerate triangle in the user's mesh: no normal
        face /= area2;
        const double sidePrev = (prev_ - q).dot(face);
        const double sideNow = (p_ - q).dot(face);
        const Vec3 d = p_ - q;
        const double len = d.norm();
        double signedDist;
        Vec3 n;
        if (sidePrev * sideNow < 0.0 && crossesInside(a, b, c, face, sidePrev, sideNow)) {
            // crossed this triangle since last step (its plane within its edges: beside it, the
            // path crossed the plane of a slope it passed, not the surface)
            n = sidePrev > 0.0 ? face : Vec3(-face);
            signedDist = -len;
        } else if (len > 1e-12) {
            n = d / len;
            signedDist = len;
        } else {
            n = sidePrev >= 0.0 ? face : Vec3(-face);
            signedDist = 0.0;
        }
        if (!found_ || signedDist < best_) {
            found_ = true;
            best_ = signedDist;
            normal_ = n;
            point_ = q;
        }
    }
    bool found_ = false;
    double best_ = 0.0;
    Vec3 normal_ = Vec3::UnitY();
    Vec3 point_ = Vec3::Zero();

  private:
    /// Whether the path prev_ -> p_, whose ends lie on the two sides of the triangle's plane
    /// (signed distances sidePrev and sideNow along the unit normal `face`), meets the plane
    /// within the triangle's edges (or on them, to a relative 1e-9: a path through a shared
    /// edge crosses both triangles).
    bool crossesInside(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& face,
                       double sidePrev, double sideNow) const {
        const double t = sidePrev / (sidePrev - sideNow);
        const Vec3 x = prev_ + t * (p_ - prev_);
        const double tol = -1e-9 * ((b - a).squaredNorm() + (c - a).squaredNorm());
        return (b - a).cross(x - a).dot(face) >= tol && (c - b).cross(x - b).dot(face) >= tol &&
               (a - c).cross(x - c).dot(face) >= tol;
    }
    Vec3 p_, prev_;
    Vec3 pathLo_, pathHi_; ///< the box of the path prev_ -> p_
};

} // namespace

TriangleHit closestToTriangle(const btCollisionShape* shape, const btTransform& transform,
                              const Vec3& a, const Vec3& b, const Vec3& c, double reach,
                              QueryCounters& counters) {
    if (shape->getShapeType() == CAPSULE_SHAPE_PROXYTYPE) {
        // Rods: exact, in double precision (GJK in single precision is off by millimetres
        // for a long capsule nearly parallel to a triangle).
        ++counters.triangleQueries;
        const auto* cap = static_cast<const btCapsuleShape*>(shape);
        const Pose pose = toPose(transform);
        Vec3 axis = Vec3::Zero();
        axis[cap->getUpAxis()] = double(cap->getHalfHeight());
        return capsuleTriangle(pose.toWorld(-axis), pose.toWorld(axis), double(cap->getRadius()), a,
                               b, c, reach);
    }
    if (shape->getShapeType() == SPHERE_SHAPE_PROXYTYPE) {
        // Balls: exact too, a capsule of no length (and a few times cheaper than GJK, which
        // a small ball swept against the triangles at every cloth step would pay).
        ++counters.triangleQueries;
        const Vec3 centre = toVec(transform.getOrigin());
        return capsuleTriangle(centre, centre,
                               double(static_cast<const btSphereShape*>(shape)->getRadius()), a, b,
                               c, reach);
    }
    if (shape->getShapeType() == BOX_SHAPE_PROXYTYPE) {
        // A triangle over a face (a cloth lying on a table): exact from its corners, in double
        // precision, and cheaper than GJK (a towel lying awake on a table: 4.9 -> 1.4 ms a 60
        // Hz step). Beside an edge or a corner, GJK below.
        // Bullet's GJK sees the box with its margin as a rounded box: the same flat faces. (A
        // margin beyond a half extent, as a box flattened by setLocalScaling keeps, makes
        // Bullet's box no convex shape and GJK's answers meaningless; the faces here are then
        // the box's with the margin, as the particle contacts take them.)
        const auto* box = static_cast<const btBoxShape*>(shape);
        const Pose pose = toPose(transform);
        TriangleHit h;
        if (triangleOverBoxFace(toVec(box->getHalfExtentsWithMargin()), double(box->getMargin()),
                                pose.toLocal(a), pose.toLocal(b), pose.toLocal(c), 1e-6 * reach,
                                h)) {
            ++counters.triangleQueries;
            if (!(h.distance < reach)) return {};
            h.normal = (pose.R * h.normal).normalized();
            h.bodyPoint = pose.toWorld(h.bodyPoint);
            return h;
        }
    }
    if (shape->getShapeType() == COMPOUND_SHAPE_PROXYTYPE) {
        const auto* compound = static_cast<const btCompoundShape*>(shape);
        const Vec3 lo = a.cwiseMin(b).cwiseMin(c).array() - reach;
        const Vec3 hi = a.cwiseMax(b).cwiseMax(c).array() + reach;
        TriangleHit best;
        for (int k = 0; k < compound->getNumChildShapes(); ++k) {
            const btTransform t = transform * compound->getChildTransform(k);
            btVector3 mn, mx;
            shapeAabb(compound->getChildShape(k), t, mn, mx);
            if ((toVec(mx).array() < lo.array()).any() || (toVec(mn).array() > hi.array()).any())
                continue;
            const TriangleHit h =
                closestToTriangle(compound->getChildShape(k), t, a, b, c, reach, counters);
            if (h.valid && (!best.valid || h.distance < best.distance)) best = h;
        }
        return best;
    }
    if (!shape->isConvex()) return {};
    ++counters.triangleQueries;
    // Relative to a: the numbers GJK sees in single precision are the size of the triangle
    // and of the body's offset from it, not of the world's coordinates.
    btTriangleShape tri(btVector3(0, 0, 0), toBt(b - a), toBt(c - a));
    tri.setMargin(0.0f);
    btVoronoiSimplexSolver simplex;
    btGjkEpaPenetrationDepthSolver epa;
    btGjkPairDetector gjk(&tri, static_cast<const btConvexShape*>(shape), &simplex, &epa);
    btGjkPairDetector::ClosestPointInput in;
    in.m_transformA.setIdentity();
    in.m_transformB = transform;
    in.m_transformB.setOrigin(toBt(toVec(transform.getOrigin()) - a));
    btPointCollector out;
    gjk.getClosestPoints(in, out, nullptr);
    if (!out.m_hasResult || !(double(out.m_distance) < reach)) return {};
    Vec3 n = toVec(out.m_normalOnBInWorld);
    const double len = n.norm();
    if (!(len > 0.0) || !std::isfinite(len)) return {};
    n /= len;
    TriangleHit h;
    h.valid = true;
    h.distance = double(out.m_distance);
    h.normal = n;
    h.bodyPoint = a + toVec(out.m_pointInWorld);
    Vec3 bary;
    closestPointOnTriangle(h.bodyPoint + h.distance * n, a, b, c, bary);
    h.barycentric = bary;
    return h;
}

SweptTriangleHit sweepToTriangle(const btCollisionShape* shape, double radius, const PosePath& path,
                                 const Vec3 (&start)[3], const Vec3 (&end)[3], double gap,
                                 double tolerance, QueryCounters& counters) {
    double corners = 0.0;
    for (int k = 0; k < 3; ++k)
        corners = std::max(corners, (end[k] - start[k]).norm());
    const double rate = path.shift.norm() + path.turn.angle() * radius + corners;
    if (!(rate > 0.0) || !std::isfinite(rate)) return {};
    constexpr int kMaxAdvances = 32;
    double s = 0.0;
    for (int it = 0; it < kMaxAdvances; ++it) {
        const Pose p = path.at(s);
        Vec3 v[3];
        for (int k = 0; k < 3; ++k)
            v[k] = start[k] + s * (end[k] - start[k]);
        // Nothing nearer than what the rest of the way can close: it never reaches the gap.
        const TriangleHit near = closestToTriangle(shape, toBtTransform(p), v[0], v[1], v[2],
                                                   gap + tolerance + rate * (1.0 - s), counters);
        if (!near.valid) return {};
        const double left = near.distance - gap;
        if (left <= tolerance) return SweptTriangleHit{true, s, p, near};
        s += left / rate;
        if (s > 1.0) return {};
    }
    return {}; // (a graze that advances by less than the tolerance each time)
}

SurfaceHit boxSurface(const Vec3& half, const Vec3* faceNormal, const Pose& pose, const Vec3& p,
                      QueryCounters& counters) {
    ++counters.queries;
    return boxQuery(half, pose.toLocal(p), pose, faceNormal);
}

bool inflatedPathHit(const btCollisionShape* shape, const Pose& pose, const Vec3& from,
                     const Vec3& to, double inflate, SurfaceHit& hit) {
    const int type = shape->getShapeType();
    if (type != SPHERE_SHAPE_PROXYTYPE && type != CAPSULE_SHAPE_PROXYTYPE) return false;
    const Vec3 o = pose.toLocal(from), e = pose.toLocal(to), d = e - o;
    double r = 0.0, hh = 0.0;
    int axis = 1;
    if (type == SPHERE_SHAPE_PROXYTYPE) {
        r = double(static_cast<const btSphereShape*>(shape)->getRadius());
    } else {
        const auto* cap = static_cast<const btCapsuleShape*>(shape);
        r = double(cap->getRadius());
        hh = double(cap->getHalfHeight());
        axis = cap->getUpAxis();
    }
    double t = 0.0;
    if (!segmentEntersCapsule(o, e, axis, hh, r + inflate, t)) return false;
    const Vec3 p = o + t * d;
    Vec3 c = Vec3::Zero();
    c[axis] = std::clamp(p[axis], -hh, hh);
    const Vec3 off = p - c;
    const double len = off.norm();
    if (!(len > 0.0)) return false;
    const Vec3 n = off / len;
    hit.valid = true;
    hit.normal = (pose.R * n).normalized();
    hit.point = pose.toWorld(c + r * n);
    hit.distance = std::min((to - hit.point).dot(hit.normal), 0.0);
    return true;
}

SurfaceHit closestSurface(const btCollisionShape* shape, const Pose& pose, const Vec3& p,
                          const Vec3& prev, double reach, QueryCounters& counters) {
    const Vec3 local = pose.toLocal(p);
    switch (shape->getShapeType()) {
    case BOX_SHAPE_PROXYTYPE: {
        ++counters.queries;
        const auto* box = static_cast<const btBoxShape*>(shape);
        return boxQuery(toVec(box->getHalfExtentsWithMargin()), local, pose);
    }
    case BOX_2D_SHAPE_PROXYTYPE: {
        // Bullet's support of a btBox2dShape is a box of these half extents (its z one 0 for
        // the usual flat one, its margin taken off the z extent and put back): GJK and EPA on
        // that flat box let a cloth sink 13 cm through its top edge (a new user's review).
        ++counters.queries;
        const auto* box = static_cast<const btBox2dShape*>(shape);
        return boxQuery(toVec(box->getHalfExtentsWithMargin()), local, pose);
    }
    case SPHERE_SHAPE_PROXYTYPE: {
        ++counters.queries;
        return placed(
            pose,
            closestOnSphere(double(static_cast<const btSphereShape*>(shape)->getRadius()), local));
    }
    case CAPSULE_SHAPE_PROXYTYPE: {
        ++counters.queries;
        const auto* cap = static_cast<const btCapsuleShape*>(shape);
        return placed(pose, closestOnCapsule(cap->getUpAxis(), double(cap->getHalfHeight()),
                                             double(cap->getRadius()), local));
    }
    case CYLINDER_SHAPE_PROXYTYPE: {
        ++counters.queries;
        const auto* cyl = static_cast<const btCylinderShape*>(shape);
        const int axis = cyl->getUpAxis();
        const Vec3 e = toVec(cyl->getHalfExtentsWithMargin());
        return placed(pose, closestOnCylinder(axis, e[cylinderRadiusAxis(axis)], e[axis], local));
    }
    case MULTI_SPHERE_SHAPE_PROXYTYPE: {
        // One or two spheres at a uniform scaling: their hull in closed form (Bullet's support
        // puts the margin back: the surface is the spheres' own). More spheres, or a
        // non-uniform scaling (whose support is no sphere's), through GJK below.
        const auto* ms = static_cast<const btMultiSphereShape*>(shape);
        const btVector3 sc = ms->getLocalScaling();
        const int n = ms->getSphereCount();
        if ((n == 1 || n == 2) && sc.x() == sc.y() && sc.y() == sc.z()) {
            ++counters.queries;
            const double k = double(sc.x());
            const Vec3 c0 = k * toVec(ms->getSpherePosition(0));
            const double r0 = k * double(ms->getSphereRadius(0));
            const int last = n - 1;
            return placed(pose, closestOnSphereHull(c0, r0, k * toVec(ms->getSpherePosition(last)),
                                                    k * double(ms->getSphereRadius(last)), local));
        }
        break;
    }
    case CONE_SHAPE_PROXYTYPE: {
        // Bullet's cone grown by its margin (GJK's rounded surface): the sharp cone's nearest
        // point moved out along its normal. Exact where a face is nearest; round the rim and
        // the apex a point within the margin's sphere.
        ++counters.queries;
        const auto* cone = static_cast<const btConeShape*>(shape);
        SurfacePoint q = closestOnCone(cone->getConeUpIndex(), double(cone->getRadius()),
                                       0.5 * double(cone->getHeight()), local);
        const double margin = double(cone->getMargin());
        q.distance -= margin;
        q.point += margin * q.normal;
        return placed(pose, q);
    }
    case STATIC_PLANE_PROXYTYPE: {
        ++counters.queries;
        return planeQuery(static_cast<const btStaticPlaneShape*>(shape), local, pose);
    }
    case COMPOUND_SHAPE_PROXYTYPE: {
        const auto* compound = static_cast<const btCompoundShape*>(shape);
        SurfaceHit best;
        for (int c = 0; c < compound->getNumChildShapes(); ++c) {
            const btCollisionShape* child = compound->getChildShape(c);
            const btTransform& ct = compound->getChildTransform(c);
            btVector3 mn, mx;
            shapeAabb(child, ct, mn, mx);
            const btVector3 lp = toBt(local);
            const auto r = btScalar(reach);
            if (lp.x() < mn.x() - r || lp.y() < mn.y() - r || lp.z() < mn.z() - r ||
                lp.x() > mx.x() + r || lp.y() > mx.y() + r || lp.z() > mx.z() + r) {
                continue;
            }
            const SurfaceHit h = closestSurface(child, pose * toPose(ct), p, prev, reach, counters);
            if (h.valid && (!best.valid || h.distance < best.distance)) best = h;
        }
        return best;
    }
    case UNIFORM_SCALING_SHAPE_PROXYTYPE: {
        // The child's surface (its margin included) scaled about the origin by k: measured on
        // the child at local / k, distances and points times k.
        const auto* scaled = static_cast<const btUniformScalingShape*>(shape);
        const double k = double(scaled->getUniformScalingFactor());
        if (!(k > 0.0 && std::isfinite(k))) break;
        const SurfaceHit h = closestSurface(scaled->getChildShape(), Pose{}, local / k,
                                            pose.toLocal(prev) / k, reach / k, counters);
        if (!h.valid) return h;
        return makeHit(pose, k * h.distance, h.normal, k * h.point);
    }
    default:
        break;
    }
    if (shape->isConvex()) {
        ++counters.queries;
        const auto* convex = static_cast<const btConvexShape*>(shape);
        if (const std::optional<SurfaceHit> hull =
                hullQuery(convex, local, pose.toLocal(prev), pose, reach))
            return *hull;
        return convexQuery(convex, local, pose);
    }
    if (shape->isConcave()) {
        ++counters.queries;
        const auto* concave = static_cast<const btConcaveShape*>(shape);
        NearestTriangle cb(local, pose.toLocal(prev));
        const Vec3 r = Vec3::Constant(reach);
        concave->processAllTriangles(&cb, toBt(local - r), toBt(local + r));
        if (!cb.found_) return {};
        return makeHit(pose, cb.best_, cb.normal_, cb.point_);
    }
    return {}; // soft bodies, empty shapes and the like: nothing to collide with
}

void shapesMayHaveChanged() {
    gShapeGeneration.fetch_add(1, std::memory_order_relaxed);
}

} // namespace drape::bullet::detail
