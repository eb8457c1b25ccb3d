// rigid_world_none.cpp: builds without the Bullet integration run cloth-only scenes.
#include "rigid_world.hpp"

namespace drape::samples {

bool rigidBodiesAvailable() {
    return false;
}

std::unique_ptr<Simulation::RigidWorld>
Simulation::RigidWorld::create(const SceneDesc& scene, Cloth&,
                               const std::vector<std::vector<Index>>&) {
    throw SceneError(scene.sourceFile.string() +
                     ": rigid_bodies: this build has no Bullet integration (configure with "
                     "-DDRAPE_BUILD_INTEGRATION=ON) and cannot run scenes with rigid bodies");
}

} // namespace drape::samples
