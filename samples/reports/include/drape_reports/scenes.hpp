// drape_reports/scenes.hpp: the report scenes (the paper's Experiments I and II, hanging
// sheets, a cloth on a sphere) as plain data that any engine can build (drape, btSoftBody,
// Bullet's deformable world), and DrapeWorld, which runs one in drape inside a Bullet world.
// The scenes are the files of samples/scenes (the ones drape-run runs), read through
// drape::samples; reduced sizes come from resizedSheet.
//
// Units are the paper's: grid spacing 10, particle mass 0.5, stiffness 20, g = 9.8, so
// lengths are "paper units" (think centimetres with a weak gravity); the report text says so.
#pragma once

#include <drape/cloth.hpp>
#include <drape_samples/render.hpp>
#include <drape_samples/scene.hpp>

#include <filesystem>
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
    bool boxEdges = true;       ///< ContactSettings::boxEdges (the scene's collision.box_edges)
    double timeStep = 0.01;     ///< the scene's dt [s]
    double duration = 10.0;     ///< simulated time of a run [s]
    samples::CameraDesc camera; ///< for renders
};

/// The folder of the shipped scene files (samples/scenes of the source tree).
std::filesystem::path sceneDirectory();
/// A shipped scene file (`fileName` in sceneDirectory()) as a ClothScene: samples::loadScene,
/// resized to rows x cols by samples::resizedSheet (the one way the reports and benchmarks
/// derive other sizes from a scene file) unless rows is 0, then fromSceneFile.
/// Throws samples::SceneError.
ClothScene loadClothScene(const std::string& fileName, Index rows = 0, Index cols = 0);

/// Experiment I (samples/scenes/experiment1_suspended_sheet.json), resized to rows x cols
/// (35 x 35 in the paper and the file).
ClothScene experiment1(Index rows = 35, Index cols = 35);
/// Experiment II (samples/scenes/experiment2_tablecloth.json: a 30 x 60 tablecloth dropped
/// onto a desk with four legs, smaller than the cloth, over a floor), resized to rows x cols.
ClothScene experiment2(Index rows = 30, Index cols = 60);
/// Experiment I resized to n x n (named "hanging<n>"; 5 s).
ClothScene hangingSheet(Index n);
/// samples/scenes/cloth_on_sphere.json (a 40 x 40 sheet dropped onto a sphere of radius 0.28
/// of its side) resized to n x n (named "sphere<n>").
ClothScene clothOnSphere(Index n);

/// A scene file's scene (samples/scenes/*.json) as a ClothScene, for the engines that do not
/// read scene files (btSoftBody, the deformable world): its sheet, particle mass, stiffness,
/// particle damping, gravity, time step, duration, thickness, fixed pins (samples::fixedPins),
/// and its static boxes, spheres and planes (unrotated). Throws samples::SceneError for
/// what a ClothScene cannot hold (mesh cloths, moving pins or pins chosen by box or group,
/// attachments, wind, non-static or rotated bodies, capsules, meshes).
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

/// A drape cloth of a scene in a btDiscreteDynamicsWorld holding the scene's colliders (an
/// empty world when it has none), stepped as a game steps it: world->stepSimulation(dt, 0), one
/// internal step of dt, with BulletClothSettings::timeStep = dt so that the cloth steps with
/// the exact double dt (the reports' numbers do not depend on dt's float rounding).
/// The cloth joins the world at its first step (with that step's dt); a step with another dt
/// takes it out and adds it again (the reports keep one dt per world).
class DrapeWorld {
  public:
    DrapeWorld(const ClothScene& scene, const ClothSettings& settings);
    ~DrapeWorld();
    DrapeWorld(const DrapeWorld&) = delete;
    DrapeWorld& operator=(const DrapeWorld&) = delete;
    /// One world step of dt [s]. Throws drape::Error (SimulationFailure when the state blew
    /// up, UnstableTimeStep when the cloth's settings refuse dt), std::invalid_argument for a
    /// dt below btScalar's epsilon (which stepSimulation would not step).
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
