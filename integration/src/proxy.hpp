// proxy.hpp (private to drape::bullet): the cloth's broadphase proxy, a btGhostObject whose
// AABB is the cloth's box swept over the next step plus a margin. Its broadphase overlaps are
// the bodies the cloth may touch; no loop over the world's bodies anywhere. It has no
// geometry and refuses narrow-phase, so it never takes part in the world's contacts or ray
// tests.
#pragma once

#include "drape/cloth.hpp"

#include <memory>
#include <vector>

class btCollisionObject;
class btDynamicsWorld;

namespace drape::bullet::detail {

class BoundsShape;
class ProxyGhost;

class ClothProxy {
  public:
    /// `owner` becomes the ghost's user pointer (the BulletCloth).
    explicit ClothProxy(void* owner);
    ~ClothProxy();
    ClothProxy(const ClothProxy&) = delete;
    ClothProxy& operator=(const ClothProxy&) = delete;

    const btCollisionObject* object() const;
    /// Puts the ghost into the world (installing the ghost pair callback that keeps its
    /// overlap list); from then on setBounds updates its broadphase AABB.
    void addTo(btDynamicsWorld* world, int group, int mask);
    void removeFromWorld();
    /// Forgets the world without touching it (it was destroyed: see inLiveWorld).
    void forgetWorld() { world_ = nullptr; }
    /// Whether the ghost is still in a live world: Bullet's world destructor (and
    /// removeCollisionObject) clears the broadphase handle of every object it held, and the
    /// ghost is ours, so this reads no freed memory.
    bool inLiveWorld() const;
    /// The proxy's AABB [m].
    void setBounds(const Vec3& lo, const Vec3& hi);
    const Vec3& min() const { return min_; }
    const Vec3& max() const { return max_; }
    /// The objects whose broadphase proxies overlap the ghost, into `out`. When lo..hi (where
    /// the cloth will reach in this step) is not inside the proxy's box, the box is first grown
    /// to cover it and the broadphase asked directly (a tree query) for what the larger box
    /// overlaps; returns whether it did.
    bool candidates(const Vec3& lo, const Vec3& hi, std::vector<const btCollisionObject*>& out);
    /// Whether the world's broadphase would pair `object` with the ghost: the world's overlap
    /// filter callback if it has one, else Bullet's default test of the collision filter
    /// groups and masks both ways (btOverlappingPairCache::needsBroadphaseCollision). False
    /// for an object without a broadphase handle. The ghost's overlap list is filtered so by
    /// Bullet; the direct queries (candidates' tree query, the fast bodies) ask this.
    bool collidesWith(const btCollisionObject* object) const;

  private:
    btDynamicsWorld* world_ = nullptr; ///< while the ghost is in it
    std::unique_ptr<BoundsShape> shape_;
    std::unique_ptr<ProxyGhost> ghost_;
    Vec3 min_ = Vec3::Zero(), max_ = Vec3::Zero();
};

/// The cloth's box swept over dt at its current velocities, grown by `grow` [m].
void sweptBounds(const Cloth& c, double dt, double grow, Vec3& lo, Vec3& hi);

} // namespace drape::bullet::detail
