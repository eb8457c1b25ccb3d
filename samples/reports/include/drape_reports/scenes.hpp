// drape_reports/scenes.hpp: the report scenes (the paper's Experiments I and II, hanging
// sheets, a cloth on a sphere) as plain data that any engine can build (drape, btSoftBody,
// Bullet's deformable world), and DrapeWorld, which runs one in drape (with Bullet colliders
// when the scene has any).
//
// Units are the paper's: grid spacing 10, particle mass 0.5, stiffness 20, g = 9.8, so
// lengths are "paper units" (think centimetres with a weak gravity); the report text says so.
#pragma once

#include <drape/cloth.hpp>
#include <drape_samples/render.hpp>
#include <drape_samples/scene.hpp>

#include <memory>
#include <string>
#include <vector>

namespace drape::reports {

/// A static rigid collider.
struct Collider {
    enum class Kind { Box, Sphere, Plane };
    Kind kind = Kind::Box;
    Vec3 center = Vec3::Zero();      ///< box and sphere centre
    Vec3 halfExtents = Vec3::Ones(); ///< box
    double radius = 1.0;             ///< sphere
    Vec3 normal = Vec3::UnitY();     ///< plane: normal . x = offset
    double offset = 0.0;             ///< plane
    double friction = 0.6;           ///< Coulomb mu [-]
    /// Signed distance of x from the surface (negative inside).
    double signedDistance(const Vec3& x) const;
};

/// A cloth scene described independently of the engine.
struct ClothScene {
    std::string name;  ///< file-name friendly
    std::string title; ///< human readable
    SheetSpec sheet;
    TriangleMesh mesh;         ///< makeSheet(sheet)
    double particleMass = 0.5; ///< every particle [kg]
    double stiffness = 20.0;   ///< every linked spring [N/m]
    double damping = 0.05;     ///< eq. (8) C_d on every particle [N s/m]
    Vec3 gravity = Vec3(0.0, -9.8, 0.0);
    std::vector<Index> pins; ///< fixed particles
    std::vector<Collider> colliders;
    double thickness = 1.0;     ///< contact thickness [scene length]
    double timeStep = 0.01;     ///< the scene's dt [s]
    double duration = 10.0;     ///< simulated time of a run [s]
    samples::CameraDesc camera; ///< for renders
};

/// Experiment I: rows x cols sheet (35 x 35 in the paper) hanging from its two top corners.
ClothScene experiment1(Index rows = 35, Index cols = 35);
/// Experiment II: a rows x cols tablecloth (30 x 60 in the paper) dropped onto a desk
/// (200 x 340 top, smaller than the cloth) over a floor.
ClothScene experiment2(Index rows = 30, Index cols = 60);
/// An n x n sheet of the paper's parameters hanging from its two top corners.
ClothScene hangingSheet(Index n);
/// An n x n horizontal sheet dropped onto a sphere of radius 0.28 of the sheet's side.
ClothScene clothOnSphere(Index n);

/// A scene file's scene (samples/scenes/*.json) as a ClothScene, for the engines that do not
/// read scene files (btSoftBody, the deformable world): its sheet, particle mass, stiffness,
/// particle damping, gravity, time step, duration, thickness, and its static boxes, spheres and
/// planes (unrotated). Throws samples::SceneError for what a ClothScene cannot hold (mesh
/// cloths, pins, attachments, wind, non-static or rotated bodies, capsules, meshes).
ClothScene fromSceneFile(const samples::SceneDesc& scene);

/// ClothSettings for the scene (mass, stiffness, damping, gravity) with an integrator and a
/// limiter; rejectUnstableTimeStep off (the reports step beyond the limit on purpose).
ClothSettings clothSettings(const ClothScene& scene, IntegratorKind integrator,
                            LimiterKind limiter);

/// Deepest penetration (>= 0) and number of particles inside the colliders.
struct Penetration {
    double depth = 0.0;
    std::size_t inside = 0;
};
Penetration measurePenetration(const std::vector<Collider>& colliders, const std::vector<Vec3>& x);

/// Meshes to draw the colliders (planes as a square around `around`).
std::vector<samples::DrawMesh> colliderMeshes(const std::vector<Collider>& colliders,
                                              const Vec3& around);

/// A drape cloth of a scene, in a Bullet world holding the scene's colliders (none when the
/// scene has no colliders: the cloth is stepped alone).
class DrapeWorld {
  public:
    DrapeWorld(const ClothScene& scene, const ClothSettings& settings);
    ~DrapeWorld();
    DrapeWorld(const DrapeWorld&) = delete;
    DrapeWorld& operator=(const DrapeWorld&) = delete;
    /// One step of dt [s]. Throws drape::Error (SimulationFailure when the state blew up).
    void step(double dt);
    Cloth& cloth();
    const Cloth& cloth() const;

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

/// Cloth state summaries used by every report.
double rmsDistance(const std::vector<Vec3>& a, const std::vector<Vec3>& b);

} // namespace drape::reports
