// The cloth's broadphase proxy (see proxy.hpp).
#include "proxy.hpp"

#include "drape/bullet/convert.hpp"

#include <BulletCollision/CollisionDispatch/btGhostObject.h>
#include <BulletCollision/CollisionShapes/btEmptyShape.h>
#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <limits>

namespace drape::bullet::detail {

/// The proxy's shape: no geometry (Bullet's ray tests and contact queries find nothing in
/// it), only an AABB that we set.
class BoundsShape final : public btEmptyShape {
  public:
    BT_DECLARE_ALIGNED_ALLOCATOR();
    void getAabb(const btTransform&, btVector3& aabbMin, btVector3& aabbMax) const override {
        aabbMin = min_;
        aabbMax = max_;
    }
    const char* getName() const override { return "DrapeClothBounds"; }
    void set(const Vec3& lo, const Vec3& hi) {
        min_ = toBt(lo);
        max_ = toBt(hi);
    }

  private:
    btVector3 min_{0, 0, 0};
    btVector3 max_{0, 0, 0};
};

/// The proxy: a ghost object whose broadphase overlaps are the cloth's candidate bodies. It
/// refuses narrow-phase with everything (checkCollideWith), so Bullet's dispatcher never
/// computes contacts for its pairs.
class ProxyGhost final : public btGhostObject {
  public:
    BT_DECLARE_ALIGNED_ALLOCATOR();
    ProxyGhost() { m_checkCollideWith = 1; }
    bool checkCollideWithOverride(const btCollisionObject*) const override { return false; }
};

namespace {

/// The ghost pair callback that keeps btGhostObject overlap lists. Stateless, so one instance
/// serves every world; a world that already uses a btGhostPairCallback behaves the same with it.
btGhostPairCallback& ghostPairCallback() {
    static btGhostPairCallback callback;
    return callback;
}

/// Collects the objects of the broadphase proxies overlapping a box.
struct CollectObjects final : btBroadphaseAabbCallback {
    std::vector<const btCollisionObject*>* out = nullptr;
    const ClothProxy* proxy = nullptr;
    bool process(const btBroadphaseProxy* found) override {
        const auto* object = static_cast<const btCollisionObject*>(found->m_clientObject);
        if (proxy->collidesWith(object)) out->push_back(object);
        return true;
    }
};

} // namespace

ClothProxy::ClothProxy(void* owner)
    : shape_(std::make_unique<BoundsShape>()), ghost_(std::make_unique<ProxyGhost>()) {
    ghost_->setCollisionShape(shape_.get());
    ghost_->setCollisionFlags(ghost_->getCollisionFlags() |
                              btCollisionObject::CF_NO_CONTACT_RESPONSE);
    ghost_->setActivationState(DISABLE_DEACTIVATION);
    ghost_->setUserPointer(owner);
}

ClothProxy::~ClothProxy() = default;

const btCollisionObject* ClothProxy::object() const {
    return ghost_.get();
}

void ClothProxy::addTo(btDynamicsWorld* world, int group, int mask) {
    world->getPairCache()->setInternalGhostPairCallback(&ghostPairCallback());
    world->addCollisionObject(ghost_.get(), group, mask);
    world_ = world;
}

bool ClothProxy::collidesWith(const btCollisionObject* object) const {
    btBroadphaseProxy* mine = ghost_->getBroadphaseHandle();
    // (Bullet's filter callback takes non-const proxies; it only reads them.)
    btBroadphaseProxy* theirs =
        object ? const_cast<btCollisionObject*>(object)->getBroadphaseHandle() : nullptr;
    if (!world_ || !mine || !theirs || object == ghost_.get()) return false;
    if (const btOverlapFilterCallback* filter = world_->getPairCache()->getOverlapFilterCallback())
        return filter->needBroadphaseCollision(mine, theirs);
    return (mine->m_collisionFilterGroup & theirs->m_collisionFilterMask) != 0 &&
           (theirs->m_collisionFilterGroup & mine->m_collisionFilterMask) != 0;
}

bool ClothProxy::inLiveWorld() const {
    return world_ != nullptr && ghost_->getBroadphaseHandle() != nullptr;
}

void ClothProxy::removeFromWorld() {
    if (!world_) return;
    world_->removeCollisionObject(ghost_.get());
    world_ = nullptr;
}

void ClothProxy::setBounds(const Vec3& lo, const Vec3& hi) {
    min_ = lo;
    max_ = hi;
    shape_->set(lo, hi);
    // (Not while out of the world's broadphase: taken out by the program, or the world gone.)
    if (world_ && ghost_->getBroadphaseHandle()) world_->updateSingleAabb(ghost_.get());
}

bool ClothProxy::candidates(const Vec3& lo, const Vec3& hi,
                            std::vector<const btCollisionObject*>& out) {
    const auto& overlaps = ghost_->getOverlappingPairs();
    for (int k = 0; k < overlaps.size(); ++k)
        out.push_back(overlaps[k]);
    if (!((lo.array() < min_.array()).any() || (hi.array() > max_.array()).any())) return false;
    setBounds(lo, hi);
    CollectObjects collect;
    collect.out = &out;
    collect.proxy = this;
    world_->getBroadphase()->aabbTest(toBt(min_), toBt(max_), collect);
    std::sort(out.begin(), out.end());
    out.erase(std::unique(out.begin(), out.end()), out.end());
    return true;
}

void sweptBounds(const Cloth& c, double dt, double grow, Vec3& lo, Vec3& hi) {
    // x and y as one two-lane Eigen array (one SSE2 register), z on its own: the same values
    // as Vec3 arithmetic (min and max are exact, x + dt v is computed the same way per lane)
    // at half the instructions. Each particle's own least and greatest come first, so that
    // the running bounds wait for one min and one max a particle, not two.
    using Pair = Eigen::Array2d;
    const double inf = std::numeric_limits<double>::infinity();
    Pair lo01 = Pair::Constant(inf), hi01 = Pair::Constant(-inf);
    double lo2 = inf, hi2 = -inf;
    const Vec3* xs = c.positions().data();
    const Vec3* vs = c.velocities().data();
    for (std::size_t i = 0, n = c.particleCount(); i < n; ++i) {
        const Pair x01 = Eigen::Map<const Pair>(xs[i].data());
        const Pair a01 = x01 + dt * Eigen::Map<const Pair>(vs[i].data());
        lo01 = lo01.min(x01.min(a01));
        hi01 = hi01.max(x01.max(a01));
        const double x2 = xs[i][2], a2 = x2 + dt * vs[i][2];
        lo2 = std::min(lo2, std::min(x2, a2));
        hi2 = std::max(hi2, std::max(x2, a2));
    }
    lo = Vec3(lo01[0], lo01[1], lo2);
    hi = Vec3(hi01[0], hi01[1], hi2);
    lo.array() -= grow;
    hi.array() += grow;
}

} // namespace drape::bullet::detail
