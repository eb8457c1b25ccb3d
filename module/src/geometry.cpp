// Closest-point geometry (see drape/geometry.hpp).
#include "drape/geometry.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

namespace drape {

Vec3 closestPointOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c,
                            Vec3& bary) {
    // Voronoi regions of the vertices, edges and face, tested in turn.
    const Vec3 ab = b - a, ac = c - a, ap = p - a;
    const double d1 = ab.dot(ap), d2 = ac.dot(ap);
    if (d1 <= 0.0 && d2 <= 0.0) {
        bary = Vec3(1, 0, 0);
        return a;
    }
    const Vec3 bp = p - b;
    const double d3 = ab.dot(bp), d4 = ac.dot(bp);
    if (d3 >= 0.0 && d4 <= d3) {
        bary = Vec3(0, 1, 0);
        return b;
    }
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
        const double v = d1 / (d1 - d3);
        bary = Vec3(1 - v, v, 0);
        return a + v * ab;
    }
    const Vec3 cp = p - c;
    const double d5 = ab.dot(cp), d6 = ac.dot(cp);
    if (d6 >= 0.0 && d5 <= d6) {
        bary = Vec3(0, 0, 1);
        return c;
    }
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
        const double w = d2 / (d2 - d6);
        bary = Vec3(1 - w, 0, w);
        return a + w * ac;
    }
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
        const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        bary = Vec3(0, 1 - w, w);
        return b + w * (c - b);
    }
    const double denom = 1.0 / (va + vb + vc);
    const double v = vb * denom, w = vc * denom;
    bary = Vec3(1 - v - w, v, w);
    return a + v * ab + w * ac;
}

// Moller and Trumbore's test: o + t d = a + u (b - a) + v (c - a), solved by Cramer's rule.
bool segmentCrossesTriangle(const Vec3& o, const Vec3& e, const Vec3& a, const Vec3& b,
                            const Vec3& c, double& t, Vec3& barycentric) {
    const Vec3 d = e - o, ab = b - a, ac = c - a;
    const Vec3 p = d.cross(ac);
    const double det = ab.dot(p);
    // In the plane (or degenerate): relative to the sizes involved, not to an absolute scale.
    if (!(std::abs(det) > 1e-14 * d.norm() * ab.norm() * ac.norm())) return false;
    const double inv = 1.0 / det;
    const Vec3 s = o - a;
    const double u = s.dot(p) * inv;
    if (u < 0.0 || u > 1.0) return false;
    const Vec3 q = s.cross(ab);
    const double v = d.dot(q) * inv;
    if (v < 0.0 || u + v > 1.0) return false;
    const double along = ac.dot(q) * inv;
    if (along < 0.0 || along > 1.0) return false;
    t = along;
    barycentric = Vec3(1.0 - u - v, u, v);
    return true;
}

bool segmentEntersBox(const Vec3& o, const Vec3& e, const Vec3& half, double& t, Vec3& normal) {
    if ((o.cwiseAbs().array() <= half.array()).all()) return false; // starts inside
    const Vec3 d = e - o;
    double enter = 0.0, leave = 1.0;
    int axis = -1;
    for (int k = 0; k < 3; ++k) {
        if (d[k] == 0.0) {
            if (std::abs(o[k]) > half[k]) return false; // parallel to this slab, outside it
            continue;
        }
        double t0 = (-half[k] - o[k]) / d[k], t1 = (half[k] - o[k]) / d[k];
        if (t0 > t1) std::swap(t0, t1);
        if (t0 > enter) {
            enter = t0;
            axis = k;
        }
        leave = std::min(leave, t1);
        if (enter > leave) return false;
    }
    if (axis < 0) return false; // (only with a non-finite o or e: an outside o enters a slab)
    t = enter;
    normal = Vec3::Zero();
    normal[axis] = d[axis] > 0.0 ? -1.0 : 1.0;
    return true;
}

void closestSegmentSegment(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1,
                           double& s, double& t) {
    const Vec3 d1 = p1 - p0, d2 = q1 - q0, r = p0 - q0;
    const double a = d1.squaredNorm(), e = d2.squaredNorm(), f = d2.dot(r);
    if (a <= 0.0 && e <= 0.0) {
        s = t = 0.0;
        return;
    }
    if (a <= 0.0) {
        s = 0.0;
        t = std::clamp(f / e, 0.0, 1.0);
        return;
    }
    const double c = d1.dot(r);
    if (e <= 0.0) {
        t = 0.0;
        s = std::clamp(-c / a, 0.0, 1.0);
        return;
    }
    const double b = d1.dot(d2), denom = a * e - b * b;
    s = denom > 0.0 ? std::clamp((b * f - c * e) / denom, 0.0, 1.0) : 0.0;
    t = (b * s + f) / e;
    if (t < 0.0) {
        t = 0.0;
        s = std::clamp(-c / a, 0.0, 1.0);
    } else if (t > 1.0) {
        t = 1.0;
        s = std::clamp((b - c) / a, 0.0, 1.0);
    }
}

SurfacePoint closestOnSphere(double r, const Vec3& p) {
    const double len = p.norm();
    const Vec3 n = len > 0.0 ? Vec3(p / len) : Vec3(Vec3::UnitY());
    return {len - r, n, r * n};
}

SurfacePoint closestOnCapsule(int axis, double halfHeight, double r, const Vec3& p) {
    Vec3 c = Vec3::Zero();
    c[axis] = std::clamp(p[axis], -halfHeight, halfHeight);
    const Vec3 d = p - c;
    const double len = d.norm();
    Vec3 n;
    if (len > 0.0) {
        n = d / len;
    } else { // on the axis: any direction across it
        n = Vec3::Zero();
        n[(axis + 1) % 3] = 1.0;
    }
    return {len - r, n, c + r * n};
}

SurfacePoint closestOnCylinder(int axis, double r, double halfHeight, const Vec3& p) {
    Vec3 radial = p;
    radial[axis] = 0.0;
    const double rho = radial.norm();
    const Vec3 u = rho > 0.0 ? Vec3(radial / rho) : Vec3(Vec3::Unit((axis + 1) % 3));
    Vec3 up = Vec3::Zero();
    up[axis] = p[axis] >= 0.0 ? 1.0 : -1.0;
    const double dr = rho - r;                        // > 0 outside the side wall
    const double da = std::abs(p[axis]) - halfHeight; // > 0 beyond a cap
    if (dr <= 0.0 && da <= 0.0) {                     // inside: nearest of wall and cap
        if (dr > da) {
            Vec3 s = r * u;
            s[axis] = p[axis];
            return {dr, u, s};
        }
        Vec3 s = p;
        s[axis] = up[axis] * halfHeight;
        return {da, up, s};
    }
    Vec3 q = std::min(rho, r) * u;
    q[axis] = std::clamp(p[axis], -halfHeight, halfHeight);
    const Vec3 d = p - q;
    const double len = d.norm();
    return {len, d / len, q};
}

SurfacePoint closestOnCone(int axis, double r, double halfHeight, const Vec3& p) {
    // In the half-plane through the axis and p: (rho, y), the cone is the triangle of the
    // apex (0, h), the rim (r, -h) and the base's centre (0, -h); its surface is the slant
    // apex-rim and the base centre-rim.
    Vec3 radial = p;
    radial[axis] = 0.0;
    const double rho = radial.norm(), y = p[axis], h = halfHeight;
    const Vec3 u = rho > 0.0 ? Vec3(radial / rho) : Vec3(Vec3::Unit((axis + 1) % 3));
    auto toSpace = [&](double pr, double py) {
        Vec3 v = pr * u;
        v[axis] = py;
        return v;
    };
    // Nearest on the slant (A + t (B - A), A the apex, B the rim) and on the base.
    const double sr = r, sy = -2.0 * h; // B - A
    const double len2 = sr * sr + sy * sy;
    const double t = len2 > 0.0 ? std::clamp((rho * sr + (y - h) * sy) / len2, 0.0, 1.0) : 0.0;
    const double slantR = t * sr, slantY = h + t * sy;
    const double baseR = std::clamp(rho, 0.0, r), baseY = -h;
    const double ds = std::hypot(rho - slantR, y - slantY);
    const double db = std::hypot(rho - baseR, y - baseY);
    const bool inside = h > 0.0 && y >= -h && rho * 2.0 * h <= r * (h - y);
    if (inside) {
        if (ds < db) {
            const double n = std::sqrt(4.0 * h * h + r * r); // the slant's outward (2h, r)
            return {-ds, toSpace(2.0 * h / n, r / n), toSpace(slantR, slantY)};
        }
        return {-db, toSpace(0.0, -1.0), toSpace(baseR, baseY)};
    }
    const bool slant = ds <= db;
    const double cr = slant ? slantR : baseR, cy = slant ? slantY : baseY;
    const double d = slant ? ds : db;
    if (!(d > 0.0)) return {0.0, toSpace(0.0, 1.0), toSpace(cr, cy)};
    return {d, toSpace((rho - cr) / d, (y - cy) / d), toSpace(cr, cy)};
}

SurfacePoint closestOnSphereHull(const Vec3& c0, double r0, const Vec3& c1, double r1,
                                 const Vec3& p) {
    const Vec3 axis = c1 - c0;
    const double d = axis.norm();
    auto onSphere = [&p](const Vec3& c, double r) {
        const Vec3 off = p - c;
        const double len = off.norm();
        const Vec3 n = len > 0.0 ? Vec3(off / len) : Vec3(Vec3::UnitY());
        return SurfacePoint{len - r, n, c + r * n};
    };
    if (d <= std::abs(r0 - r1)) return r0 >= r1 ? onSphere(c0, r0) : onSphere(c1, r1);
    const Vec3 u = axis / d;
    const double b = (r0 - r1) / d, a = std::sqrt(1.0 - b * b);
    const Vec3 rel = p - c0;
    const double y = rel.dot(u);
    Vec3 radial = rel - y * u;
    const double rho = radial.norm();
    Vec3 e;
    if (rho > 0.0) {
        e = radial / rho;
    } else { // on the axis: any direction across it
        e = u.cross(std::abs(u.x()) < 0.9 ? Vec3(Vec3::UnitX()) : Vec3(Vec3::UnitY())).normalized();
    }
    // Along the side, from its tangent point on sphere 0 (k = 0) to sphere 1's (k = d a).
    const double k = -b * rho + a * y;
    if (k < 0.0) return onSphere(c0, r0);
    if (k > d * a) return onSphere(c1, r1);
    const Vec3 n = a * e + b * u;
    const double dist = a * rho + b * y - r0;
    return {dist, n, p - dist * n};
}

SegmentDeepest deepestOnSegment(const Vec3& half, const Vec3& pa, const Vec3& pb, const Vec3& ga,
                                const Vec3& gb) {
    // The faces either end sees: sign per axis (0: none; both signs: a spring through the box).
    int sign[3] = {0, 0, 0};
    bool opposite = false;
    for (const Vec3* g : {&ga, &gb})
        for (int k = 0; k < 3; ++k) {
            if ((*g)[k] == 0.0) continue;
            const int sk = (*g)[k] > 0.0 ? 1 : -1;
            opposite = opposite || (sign[k] != 0 && sign[k] != sk);
            sign[k] = sk;
        }
    SegmentDeepest best;
    best.d = std::numeric_limits<double>::infinity();
    Vec3 g;
    auto consider = [&](double t) {
        const double d = boxSignedDistance(half, pa + t * (pb - pa), g);
        if (d < best.d) {
            best.d = d;
            best.t = t;
            best.g = g;
        }
    };
    bool edges = false;
    if (!opposite)
        for (int k = 0; k < 3; ++k) { // the edge along axis k between faces i and j
            const int i = (k + 1) % 3, j = (k + 2) % 3;
            if (sign[i] == 0 || sign[j] == 0) continue;
            Vec3 e0, e1;
            e0[i] = e1[i] = sign[i] * half[i];
            e0[j] = e1[j] = sign[j] * half[j];
            e0[k] = -half[k];
            e1[k] = half[k];
            double sp = 0.0, se = 0.0;
            closestSegmentSegment(pa, pb, e0, e1, sp, se);
            consider(sp);
            edges = true;
        }
    if (edges) {
        // The point nearest to an edge is the deepest where the segment passes the edge
        // outside the box (there the signed distance is the distance to the edge). Beside a
        // face it need not be: the segment may come nearer the box, or enter it, elsewhere. The
        // signed distance is convex along the segment, so a point no deeper than its
        // neighbours on either side (1e-6 of the way) is the least; a point inside the box is
        // kept as it is (the spring cuts the edge there: pushed out along the edge's normal,
        // not a face's); any other is left to the search.
        constexpr double kStep = 1e-6;
        auto at = [&](double t) { return boxSignedDistance(half, pa + t * (pb - pa), g); };
        const double inf = std::numeric_limits<double>::infinity();
        const double before = best.t > 0.0 ? at(std::max(0.0, best.t - kStep)) : inf;
        const double after = best.t < 1.0 ? at(std::min(1.0, best.t + kStep)) : inf;
        if (best.d < 0.0 || (before >= best.d && after >= best.d)) return best;
    }
    double lo = 0.0, hi = 1.0;
    constexpr double kGolden = 0.6180339887498949;
    double t1 = hi - kGolden * (hi - lo), t2 = lo + kGolden * (hi - lo);
    double f1 = boxSignedDistance(half, pa + t1 * (pb - pa), g);
    double f2 = boxSignedDistance(half, pa + t2 * (pb - pa), g);
    for (int it = 0; it < 24; ++it) {
        if (f1 < f2) {
            hi = t2;
            t2 = t1;
            f2 = f1;
            t1 = hi - kGolden * (hi - lo);
            f1 = boxSignedDistance(half, pa + t1 * (pb - pa), g);
        } else {
            lo = t1;
            t1 = t2;
            f1 = f2;
            t2 = lo + kGolden * (hi - lo);
            f2 = boxSignedDistance(half, pa + t2 * (pb - pa), g);
        }
    }
    best.t = 0.5 * (lo + hi);
    best.d = boxSignedDistance(half, pa + best.t * (pb - pa), best.g);
    return best;
}

double sphereEntry(const Vec3& o, const Vec3& d, const Vec3& c, double R) {
    const Vec3 oc = o - c;
    const double a = d.squaredNorm(), b = oc.dot(d), cc = oc.squaredNorm() - R * R;
    if (!(a > 0.0) || cc <= 0.0 || b >= 0.0) return -1.0;
    const double disc = b * b - a * cc;
    if (disc < 0.0) return -1.0;
    const double t = (-b - std::sqrt(disc)) / a;
    return t >= 0.0 && t <= 1.0 ? t : -1.0;
}

bool triangleOverBoxFace(const Vec3& half, double rounding, const Vec3& a, const Vec3& b,
                         const Vec3& c, double tie, TriangleHit& hit) {
    const Vec3* corners[3] = {&a, &b, &c};
    for (int k = 0; k < 3; ++k) {
        const int j1 = (k + 1) % 3, j2 = (k + 2) % 3;
        const double across1 = half[j1] - rounding, across2 = half[j2] - rounding;
        for (const double side : {1.0, -1.0}) {
            bool prism = true;
            double height[3];
            for (int v = 0; v < 3 && prism; ++v) {
                const Vec3& p = *corners[v];
                height[v] = side * p[k] - half[k];
                prism =
                    height[v] >= 0.0 && std::abs(p[j1]) <= across1 && std::abs(p[j2]) <= across2;
            }
            if (!prism) continue;
            const double least = std::min({height[0], height[1], height[2]});
            Vec3 weights = Vec3::Zero();
            for (int v = 0; v < 3; ++v)
                if (height[v] <= least + tie) weights[v] = 1.0;
            weights /= weights.sum();
            Vec3 onTriangle = weights[0] * a + weights[1] * b + weights[2] * c;
            hit.valid = true;
            hit.barycentric = weights;
            hit.distance = side * onTriangle[k] - half[k];
            hit.normal = Vec3::Zero();
            hit.normal[k] = side;
            onTriangle[k] = side * half[k];
            hit.bodyPoint = onTriangle;
            return true;
        }
    }
    return false;
}

TriangleHit capsuleTriangle(const Vec3& p0, const Vec3& p1, double r, const Vec3& a, const Vec3& b,
                            const Vec3& c, double reach) {
    Vec3 bestSeg = p0, bestTri = a;
    double best = std::numeric_limits<double>::infinity();
    auto consider = [&](const Vec3& onSeg, const Vec3& onTri) {
        const double d2 = (onTri - onSeg).squaredNorm();
        if (d2 < best) {
            best = d2;
            bestSeg = onSeg;
            bestTri = onTri;
        }
    };
    Vec3 bary;
    consider(p0, closestPointOnTriangle(p0, a, b, c, bary));
    consider(p1, closestPointOnTriangle(p1, a, b, c, bary));
    const Vec3 corners[3] = {a, b, c};
    for (int k = 0; k < 3; ++k) {
        const Vec3& e0 = corners[k];
        const Vec3& e1 = corners[(k + 1) % 3];
        double s = 0.0, t = 0.0;
        closestSegmentSegment(p0, p1, e0, e1, s, t);
        consider(p0 + s * (p1 - p0), e0 + t * (e1 - e0));
    }
    TriangleHit h;
    Vec3 normal = (b - a).cross(c - a);
    const double area = normal.norm();
    if (!(area > 0.0)) return h;
    normal /= area;
    double dist = std::sqrt(best);
    // Does the segment pierce the triangle? (Its ends on both sides, the crossing inside.)
    const double s0 = normal.dot(p0 - a), s1 = normal.dot(p1 - a);
    if ((s0 < 0.0) != (s1 < 0.0)) {
        const Vec3 x = p0 + (s0 / (s0 - s1)) * (p1 - p0);
        const Vec3 onTri = closestPointOnTriangle(x, a, b, c, bary);
        if ((onTri - x).squaredNorm() <= 1e-24 * (1.0 + x.squaredNorm())) {
            if (normal.dot((a + b + c) / 3.0 - 0.5 * (p0 + p1)) < 0.0) normal = -normal;
            h.valid = -r < reach;
            h.distance = -r;
            h.normal = normal;
            h.bodyPoint = x - r * normal;
            closestPointOnTriangle(x, a, b, c, h.barycentric);
            return h;
        }
    }
    if (!(dist - r < reach)) return h;
    Vec3 n = dist > 0.0 ? Vec3((bestTri - bestSeg) / dist) : normal;
    h.valid = true;
    h.distance = dist - r;
    h.normal = n;
    h.bodyPoint = bestSeg + r * n;
    closestPointOnTriangle(bestTri, a, b, c, h.barycentric);
    return h;
}

bool segmentEntersCapsule(const Vec3& o, const Vec3& e, int axis, double halfHeight, double R,
                          double& t) {
    const Vec3 d = e - o;
    const double hh = halfHeight;
    // The core (a point, or the axis segment) within R of the path's start: not a path entering
    // it.
    Vec3 c0 = Vec3::Zero();
    c0[axis] = std::clamp(o[axis], -hh, hh);
    if ((o - c0).squaredNorm() <= R * R) return false;
    t = -1.0;
    auto earliest = [&t](double s) {
        if (s >= 0.0 && (t < 0.0 || s < t)) t = s;
    };
    Vec3 cap0 = Vec3::Zero(), cap1 = Vec3::Zero();
    cap0[axis] = -hh;
    cap1[axis] = hh;
    earliest(sphereEntry(o, d, cap0, R));
    if (hh > 0.0) {
        earliest(sphereEntry(o, d, cap1, R));
        // The cylinder between the caps: the path across the axis.
        Vec3 op = o, dp = d;
        op[axis] = 0.0;
        dp[axis] = 0.0;
        const double a = dp.squaredNorm(), b = op.dot(dp), cc = op.squaredNorm() - R * R;
        if (a > 0.0 && cc > 0.0 && b < 0.0 && b * b - a * cc >= 0.0) {
            const double s = (-b - std::sqrt(b * b - a * cc)) / a;
            const double along = o[axis] + s * d[axis];
            if (s >= 0.0 && s <= 1.0 && along >= -hh && along <= hh) earliest(s);
        }
    }
    return t >= 0.0;
}

} // namespace drape
