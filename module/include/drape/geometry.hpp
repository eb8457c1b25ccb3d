// drape/geometry.hpp: closest-point geometry the cloth's contacts share (self-collision in the
// core, triangle contacts in drape::bullet).
#pragma once

#include "drape/mesh.hpp"

namespace drape {

/// Closest point to p on triangle (a, b, c) [m]; `barycentric` gets its weights on a, b, c
/// (non-negative, summing to 1). Degenerate triangles give a point of the triangle too.
Vec3 closestPointOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c,
                            Vec3& barycentric);

} // namespace drape
