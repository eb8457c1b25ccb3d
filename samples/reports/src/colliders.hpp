// colliders.hpp (drape_reports, private): a scene's static colliders as Bullet rigid bodies,
// the same for every engine of the reports (DrapeWorld, btSoftBody, the deformable world).
#pragma once

#include "drape_reports/scenes.hpp"

#include <btBulletDynamicsCommon.h>

#include <memory>
#include <vector>

namespace drape::reports {

/// Static boxes, spheres and planes (unrotated), with the collider's friction and a margin.
struct StaticColliders {
    std::vector<std::unique_ptr<btCollisionShape>> shapes;
    std::vector<std::unique_ptr<btRigidBody>> bodies;
    /// Adds one static body per collider to `world`.
    void build(btDynamicsWorld* world, const std::vector<Collider>& colliders, float margin);
    /// Takes them out of `world` again (before the world or the bodies go).
    void remove(btDynamicsWorld* world);
};

} // namespace drape::reports
