// rigid_world.hpp: the seam between Simulation and the Bullet integration. Only
// rigid_world_bullet.cpp knows Bullet; without drape::bullet, rigid_world_none.cpp refuses
// scenes with rigid bodies.
#pragma once

#include "drape_samples/simulation.hpp"

namespace drape::samples {

struct Simulation::RigidWorld {
    /// Builds the world of the scene's rigid bodies around `cloth` (which it then steps).
    /// attachSets[i] are the particles of scene.attachments[i].
    static std::unique_ptr<RigidWorld> create(const SceneDesc& scene, Cloth& cloth,
                                              const std::vector<std::vector<Index>>& attachSets);
    virtual ~RigidWorld() = default;
    /// Steps rigid bodies and cloth together by dt [s]; t is the time at the step's start.
    virtual void step(double t, double dt) = 0;
    virtual std::size_t contactCount() const = 0;
    /// Local-to-world transform of scene.rigidBodies[i].
    virtual Eigen::Matrix4f transform(std::size_t body) const = 0;
    virtual Vec3 velocity(std::size_t body) const = 0;
    virtual void launch(std::size_t body, const Vec3& position, const Vec3& velocity) = 0;
    virtual std::string description() const = 0;
};

} // namespace drape::samples
