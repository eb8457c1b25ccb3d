// The particle boxes' plane test (see particle_boxes.hpp).
#include "particle_boxes.hpp"

namespace drape::bullet::detail {

bool ParticleBoxes::aboveReach(const BodySnapshot& b, const Vec3& lo, const Vec3& hi) const {
    Vec3 corner; // the box's corner deepest along -normal
    for (int k = 0; k < 3; ++k)
        corner[k] = b.planeNormal[k] >= 0.0 ? lo[k] : hi[k];
    if (!corner.allFinite()) return false;
    const double reach = h_ + band_;
    const double size = b.planeScale + std::max(lo.cwiseAbs().maxCoeff(), hi.cwiseAbs().maxCoeff());
    return b.planeNormal.dot(corner) - b.planeOffset > reach + 1e-5 * size;
}

} // namespace drape::bullet::detail
