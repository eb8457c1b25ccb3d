// layer_contact.hpp (private to the core): one particle kept off one triangle of cloth, the
// response that self-collision (self_collision.cpp) and the collision of two cloths
// (cloth_pair.cpp) share.
#pragma once

#include "drape/forces.hpp"

#include <algorithm>
#include <array>

namespace drape::detail {

/// A particle or a triangle's corner: its position, velocity and inverse mass (0: held, or a
/// cloth that does not give way).
struct LayerPoint {
    Vec3* x;
    Vec3* v;
    double w;
};

/// Moves particle `p` and the triangle's corners `c` apart along the unit normal `nrm` (toward
/// p's side) by `violation` (thickness - gap > 0), weighted by inverse mass and the closest
/// point's barycentric weights `bary`, `denom` = w_p + sum bary_k^2 w_k > 0: the linearised
/// projection of (x_p - sum bary_k x_k) . nrm >= thickness, which keeps momentum. Then removes
/// their approaching relative normal velocity with the same weights and applies Coulomb
/// friction `friction`. Returns the approaching normal speed removed (0 if they were parting).
inline double separateLayers(const LayerPoint& p, const std::array<LayerPoint, 3>& c,
                             const Vec3& bary, const Vec3& nrm, double violation, double denom,
                             double friction) {
    const double lambda = violation / denom;
    *p.x += (p.w * lambda) * nrm;
    for (int k = 0; k < 3; ++k)
        *c[k].x -= (bary[k] * c[k].w * lambda) * nrm;
    const Vec3 vTri = bary[0] * *c[0].v + bary[1] * *c[1].v + bary[2] * *c[2].v;
    const Vec3 rel = *p.v - vTri;
    const double vn = rel.dot(nrm);
    if (!(vn < 0.0)) return 0.0;
    const double jn = -vn / denom;
    Vec3 dv = jn * nrm;
    const Vec3 vt = rel - vn * nrm;
    const double vtLen = vt.norm();
    if (vtLen > 0.0 && friction > 0.0) {
        const double jt = std::min(vtLen / denom, friction * jn);
        dv -= (jt / vtLen) * vt;
    }
    *p.v += p.w * dv;
    for (int k = 0; k < 3; ++k)
        *c[k].v -= (bary[k] * c[k].w) * dv;
    return -vn;
}

} // namespace drape::detail
