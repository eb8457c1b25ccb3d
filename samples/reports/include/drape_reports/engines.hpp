// drape_reports/engines.hpp: the engines the compare report runs (drape in a Bullet world,
// btSoftBody, Bullet's deformable world), each stepping one ClothScene frame by frame, so
// that other programs (drape-bench-bullet) time exactly what the report times.
#pragma once

#include "drape_reports/scenes.hpp"

#include <drape/settings.hpp>

#include <memory>
#include <vector>

namespace drape::reports {

/// One engine running one scene.
class ClothEngine {
  public:
    virtual ~ClothEngine() = default;
    virtual void step() = 0; ///< one frame of the scene's dt (throws on a detected failure)
    virtual void state(std::vector<Vec3>& x, std::vector<Vec3>& v) const = 0;
    virtual std::size_t links() const = 0;
};

/// drape (Velocity-Verlet) with `limiter`, contacts through drape::bullet (DrapeWorld).
std::unique_ptr<ClothEngine> makeDrapeEngine(const ClothScene& scene, LimiterKind limiter);
/// btSoftBody in a btSoftRigidDynamicsWorld: m_cfg.piterations and sub-steps per frame.
std::unique_ptr<ClothEngine> makeSoftBodyEngine(const ClothScene& scene, int piterations,
                                                int substeps);
/// Bullet's deformable world (implicit mass-spring at the scene's stiffness).
std::unique_ptr<ClothEngine> makeDeformableEngine(const ClothScene& scene);

} // namespace drape::reports
