// particle_boxes.hpp (private to drape::bullet): the cheap tests that come before a
// particle's contact query. Per particle a box (the particle, or its path since the previous
// step when that is longer than the thickness), per block of kBlock consecutive particles the
// union of their boxes, tested against a body's AABB grown by the contact reach and, for a
// static plane (whose AABB is infinite), against its half-space. Only particles these tests
// keep are queried; the tests never reject one the query would have found. Inline: they run
// per particle and body.
#pragma once

#include "body_snapshot.hpp"

#include <algorithm>
#include <limits>
#include <vector>

namespace drape::bullet::detail {

class ParticleBoxes {
  public:
    /// Particle i's box. Empty (no AABB overlaps it) for particles that never collide (zero
    /// inverse mass). Kept up to date as contacts move particles, so every body sees the box
    /// of the particle as it is when it is tested.
    struct Box {
        double lo[3], hi[3];
    };
    /// The union of the boxes of kBlock consecutive particles (or of any group), and how many
    /// of them collide.
    struct Block {
        Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity());
        Vec3 hi = Vec3::Constant(-std::numeric_limits<double>::infinity());
        std::size_t free = 0;
        void grow(const Box& b) {
            // Component by component: the compiler keeps a block that a loop grows in
            // registers (two-lane vector minima made it store and reload it each time).
            for (int k = 0; k < 3; ++k) {
                lo[k] = std::min(lo[k], b.lo[k]);
                hi[k] = std::max(hi[k], b.hi[k]);
            }
        }
        /// Grows to hold point p.
        void grow(const Vec3& p) {
            for (int k = 0; k < 3; ++k) {
                lo[k] = std::min(lo[k], p[k]);
                hi[k] = std::max(hi[k], p[k]);
            }
        }
    };
    static constexpr std::size_t kBlock = 16;

    /// thickness h [m], eq. (7)'s band [m] (the reach is h + band), and whether fast
    /// particles are swept (contact.continuous).
    ParticleBoxes(double thickness, double band, bool continuous)
        : h_(thickness), band_(band), continuous_(continuous) {}

    void resize(std::size_t n) { boxes_.resize(n); }
    const Box& operator[](std::size_t i) const { return boxes_[i]; }
    /// Particle i's box, at xi, having been at `from` after the previous step.
    void update(std::size_t i, const Vec3& xi, const Vec3& from, bool fixed);
    /// No particle whose box is inside bl can be within the reach of body b.
    bool misses(const BodySnapshot& b, const Block& bl) const {
        return (bl.hi.array() < b.aabbMin.array()).any() ||
               (bl.lo.array() > b.aabbMax.array()).any() ||
               (b.plane && aboveReach(b, bl.lo, bl.hi));
    }
    /// False when particle i (at xi, at `from` after the previous step) cannot be within the
    /// contact reach of body b in this step, so that the contact query would find nothing.
    bool mayTouch(const BodySnapshot& b, std::size_t i, const Vec3& xi, const Vec3& from) const;

  private:
    /// Whether the box lo..hi lies entirely above plane b, farther than the contact reach,
    /// with the margin mayTouch uses for swept particles: then no particle whose box is inside
    /// it (both its ends when swept) can touch the plane.
    bool aboveReach(const BodySnapshot& b, const Vec3& lo, const Vec3& hi) const;

    double h_, band_;
    bool continuous_;
    std::vector<Box> boxes_;
};

inline void ParticleBoxes::update(std::size_t i, const Vec3& xi, const Vec3& from, bool fixed) {
    Box& box = boxes_[i];
    if (fixed) { // never collides: a box no AABB overlaps
        for (int k = 0; k < 3; ++k) {
            box.lo[k] = std::numeric_limits<double>::infinity();
            box.hi[k] = -std::numeric_limits<double>::infinity();
        }
        return;
    }
    const double h = h_;
    const bool sweep = continuous_ && (xi - from).squaredNorm() > h * h;
    for (int k = 0; k < 3; ++k) {
        box.lo[k] = sweep ? std::min(xi[k], from[k]) : xi[k];
        box.hi[k] = sweep ? std::max(xi[k], from[k]) : xi[k];
    }
}

inline bool ParticleBoxes::mayTouch(const BodySnapshot& b, std::size_t i, const Vec3& xi,
                                    const Vec3& from) const {
    // The particle's box against the body's AABB grown by the reach: the comparisons
    // the contact query would make first.
    const Box& box = boxes_[i];
    // (Bitwise on integers: no branch per comparison.)
    if ((int(box.hi[0] < b.aabbMin[0]) | int(box.hi[1] < b.aabbMin[1]) |
         int(box.hi[2] < b.aabbMin[2]) | int(box.lo[0] > b.aabbMax[0]) |
         int(box.lo[1] > b.aabbMax[1]) | int(box.lo[2] > b.aabbMax[2])) != 0) {
        return false;
    }
    if (!b.plane) return true;
    // A plane's AABB is infinite: reject particles clearly above it. The margin covers the
    // rounding of this distance against the query's (1e-9 relative), and for a swept particle
    // that of Bullet's single-precision ray test (1e-5 relative): only particles that the
    // query and the ray test would certainly reject are skipped, so nothing changes.
    const double h = h_;
    const double reach = h + band_;
    const bool sweep = continuous_ && (xi - from).squaredNorm() > h * h;
    const double dist = b.planeNormal.dot(xi) - b.planeOffset;
    const double size = b.planeScale + xi.cwiseAbs().maxCoeff();
    if (!sweep) return !(dist > reach + 1e-9 * size);
    const double distFrom = b.planeNormal.dot(from) - b.planeOffset;
    const double sizeFrom = std::max(size, b.planeScale + from.cwiseAbs().maxCoeff());
    return !(dist > reach + 1e-5 * sizeFrom && distFrom > reach + 1e-5 * sizeFrom);
}

} // namespace drape::bullet::detail
