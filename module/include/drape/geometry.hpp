// drape/geometry.hpp: closest-point geometry the cloth's contacts share (self-collision in the
// core, triangle contacts in drape::bullet).
#pragma once

#include "drape/mesh.hpp"

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

} // namespace drape
