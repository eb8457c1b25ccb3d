// Closest-point geometry (see drape/geometry.hpp).
#include "drape/geometry.hpp"

#include <algorithm>
#include <cmath>
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

} // namespace drape
