// The report scenes and the drape runner for them.
#include "drape_reports/scenes.hpp"

#include "colliders.hpp"

#include <drape/bullet/bullet_cloth.hpp>
#include <drape/bullet/convert.hpp>

#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace drape::reports {

double Collider::signedDistance(const Vec3& x) const {
    switch (kind) {
    case Kind::Sphere:
        return (x - center).norm() - radius;
    case Kind::Plane:
        return normal.dot(x) - offset;
    case Kind::Box: {
        const Vec3 d = (x - center).cwiseAbs() - halfExtents;
        const double outside = d.cwiseMax(0.0).norm();
        const double inside = std::min(d.maxCoeff(), 0.0);
        return outside + inside;
    }
    }
    return 0.0;
}

std::filesystem::path sceneDirectory() {
    return DRAPE_REPORTS_SCENES_DIR;
}

ClothScene loadClothScene(const std::string& fileName, Index rows, Index cols) {
    const samples::SceneDesc file = samples::loadScene(sceneDirectory() / fileName);
    return fromSceneFile(rows > 0 ? samples::resizedSheet(file, rows, cols) : file);
}

ClothScene experiment1(Index rows, Index cols) {
    ClothScene s = loadClothScene("experiment1_suspended_sheet.json", rows, cols);
    s.name = "experiment1";
    s.title = "Experiment I (" + std::to_string(rows) + " x " + std::to_string(cols) +
              " suspended sheet)";
    return s;
}

ClothScene hangingSheet(Index n) {
    ClothScene s = experiment1(n, n);
    s.name = "hanging" + std::to_string(n);
    s.title = "hanging sheet " + std::to_string(n) + " x " + std::to_string(n);
    s.duration = 5.0;
    return s;
}

ClothScene experiment2(Index rows, Index cols) {
    ClothScene s = loadClothScene("experiment2_tablecloth.json", rows, cols);
    s.name = "experiment2";
    s.title = "Experiment II (" + std::to_string(rows) + " x " + std::to_string(cols) +
              " tablecloth onto a desk)";
    return s;
}

ClothScene clothOnSphere(Index n) {
    ClothScene s = loadClothScene("cloth_on_sphere.json", n, n);
    s.name = "sphere" + std::to_string(n);
    s.title = "cloth " + std::to_string(n) + " x " + std::to_string(n) + " onto a sphere";
    return s;
}

ClothScene fromSceneFile(const samples::SceneDesc& d) {
    const std::string origin = d.sourceFile.empty() ? d.name : d.sourceFile.string();
    auto refuse = [&origin](const std::string& what) {
        throw samples::SceneError(origin + ": cannot be run by every engine: " + what);
    };
    if (!d.sheet) refuse("the cloth is not a generated sheet");
    if (!d.attachments.empty()) refuse("attachments are not supported");
    if (d.wind) refuse("wind is not supported");
    ClothScene s;
    s.name = d.name;
    s.title = d.name;
    s.sheet = d.sheet->spec;
    s.mesh = makeSheet(s.sheet);
    {
        // The file's cloth as the core builds it (mass and stiffness given directly, or through
        // total_mass or a material): a ClothScene holds one mass and one stiffness.
        const Cloth probe(ClothTopology::build(s.mesh), d.cloth);
        const auto [mLo, mHi] = std::minmax_element(probe.masses().begin(), probe.masses().end());
        const auto [kLo, kHi] =
            std::minmax_element(probe.stiffness().begin(), probe.stiffness().end());
        if (*mLo != *mHi) refuse("the particle masses are not all equal");
        if (*kLo != *kHi) refuse("the spring stiffnesses are not all equal");
        s.particleMass = *mLo;
        s.stiffness = *kLo;
    }
    s.damping = d.cloth.damping;
    s.gravity = d.cloth.gravity;
    s.timeStep = d.timeStep;
    s.duration = d.duration;
    s.camera = d.camera;
    s.pins = samples::fixedPins(d);
    if (d.collision && d.collision->thickness) s.thickness = *d.collision->thickness;
    if (d.collision) s.boxEdges = d.collision->boxEdges;
    for (const samples::RigidBodyDesc& b : d.rigidBodies) {
        if (b.motion != samples::MotionKind::Static) refuse("body " + b.name + " is not static");
        if (b.rotationDeg != Vec3::Zero()) refuse("body " + b.name + " is rotated");
        Collider c;
        c.friction = b.friction;
        c.center = b.position;
        switch (b.shape.kind) {
        case samples::ShapeKind::Box:
            c.kind = Collider::Kind::Box;
            c.halfExtents = b.shape.halfExtents;
            break;
        case samples::ShapeKind::Sphere:
            c.kind = Collider::Kind::Sphere;
            c.radius = b.shape.radius;
            break;
        case samples::ShapeKind::Plane:
            if (b.position != Vec3::Zero()) refuse("plane " + b.name + " is translated");
            c.kind = Collider::Kind::Plane;
            c.normal = b.shape.normal;
            c.offset = b.shape.offset;
            break;
        default:
            refuse("body " + b.name + " is neither a box, a sphere nor a plane");
        }
        s.colliders.push_back(c);
    }
    return s;
}

ClothSettings clothSettings(const ClothScene& scene, IntegratorKind integrator,
                            LimiterKind limiter) {
    ClothSettings s;
    s.integrator = integrator;
    s.particleMass = scene.particleMass;
    s.springStiffness = scene.stiffness;
    s.damping = scene.damping;
    s.relativeDamping = 0.0; // the paper's model: the scene's damping only
    s.gravity = scene.gravity;
    s.limiter.kind = limiter;
    s.rejectUnstableTimeStep = false;
    s.substeps.automatic = false; // the step is the dt given (a sweep beyond the limit)
    return s;
}

Penetration measurePenetration(const std::vector<Collider>& colliders, const std::vector<Vec3>& x) {
    Penetration p;
    for (const Vec3& xi : x) {
        double deepest = 0.0;
        for (const Collider& c : colliders)
            deepest = std::max(deepest, -c.signedDistance(xi));
        if (deepest > 0.0) {
            ++p.inside;
            p.depth = std::max(p.depth, deepest);
        }
    }
    return p;
}

std::vector<samples::DrawMesh> colliderMeshes(const std::vector<Collider>& colliders,
                                              const Vec3& around) {
    std::vector<samples::DrawMesh> out;
    for (const Collider& c : colliders) {
        if (c.kind == Collider::Kind::Plane) {
            auto planes =
                samples::makePlaneMeshes(c.normal, c.offset, around, 1500.0, {0.78f, 0.80f, 0.82f});
            out.insert(out.end(), planes.begin(), planes.end());
            continue;
        }
        samples::DrawMesh m = c.kind == Collider::Kind::Box ? samples::makeBoxMesh(c.halfExtents)
                                                            : samples::makeSphereMesh(c.radius);
        m.front = m.back = {0.55f, 0.38f, 0.24f};
        m.model.block<3, 1>(0, 3) = c.center.cast<float>();
        out.push_back(std::move(m));
    }
    return out;
}

double rmsDistance(const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
    double sum = 0.0;
    for (std::size_t i = 0; i < a.size(); ++i)
        sum += (a[i] - b[i]).squaredNorm();
    return a.empty() ? 0.0 : std::sqrt(sum / static_cast<double>(a.size()));
}

// --- StaticColliders -------------------------------------------------------------------------

void StaticColliders::build(btDynamicsWorld* world, const std::vector<Collider>& colliders,
                            float margin) {
    for (const Collider& c : colliders) {
        std::unique_ptr<btCollisionShape> shape;
        btTransform t;
        t.setIdentity();
        switch (c.kind) {
        case Collider::Kind::Box:
            shape = std::make_unique<btBoxShape>(bullet::toBt(c.halfExtents));
            t.setOrigin(bullet::toBt(c.center));
            break;
        case Collider::Kind::Sphere:
            shape = std::make_unique<btSphereShape>(btScalar(c.radius));
            t.setOrigin(bullet::toBt(c.center));
            break;
        case Collider::Kind::Plane:
            shape =
                std::make_unique<btStaticPlaneShape>(bullet::toBt(c.normal), btScalar(c.offset));
            break;
        }
        shape->setMargin(margin);
        btRigidBody::btRigidBodyConstructionInfo info(0.0f, nullptr, shape.get());
        info.m_startWorldTransform = t;
        info.m_friction = btScalar(c.friction);
        auto body = std::make_unique<btRigidBody>(info);
        world->addRigidBody(body.get());
        shapes.push_back(std::move(shape));
        bodies.push_back(std::move(body));
    }
}

void StaticColliders::remove(btDynamicsWorld* world) {
    for (auto& b : bodies)
        world->removeRigidBody(b.get());
}

// --- DrapeWorld ------------------------------------------------------------------------------

struct DrapeWorld::Impl {
    std::shared_ptr<Cloth> cloth;
    bullet::BulletClothSettings options;
    std::unique_ptr<btDefaultCollisionConfiguration> config;
    std::unique_ptr<btCollisionDispatcher> dispatcher;
    std::unique_ptr<btDbvtBroadphase> broadphase;
    std::unique_ptr<btSequentialImpulseConstraintSolver> solver;
    std::unique_ptr<btDiscreteDynamicsWorld> world;
    StaticColliders colliders;
    std::unique_ptr<bullet::BulletCloth> handle;

    ~Impl() {
        handle.reset();
        colliders.remove(world.get());
    }
};

DrapeWorld::DrapeWorld(const ClothScene& scene, const ClothSettings& settings)
    : impl_(std::make_unique<Impl>()) {
    impl_->cloth = std::make_shared<Cloth>(ClothTopology::build(scene.mesh), settings);
    for (Index p : scene.pins)
        impl_->cloth->pin(p);
    Impl& m = *impl_;
    m.config = std::make_unique<btDefaultCollisionConfiguration>();
    m.dispatcher = std::make_unique<btCollisionDispatcher>(m.config.get());
    m.broadphase = std::make_unique<btDbvtBroadphase>();
    m.solver = std::make_unique<btSequentialImpulseConstraintSolver>();
    m.world = std::make_unique<btDiscreteDynamicsWorld>(m.dispatcher.get(), m.broadphase.get(),
                                                        m.solver.get(), m.config.get());
    m.world->setGravity(bullet::toBt(scene.gravity));
    m.colliders.build(m.world.get(), scene.colliders, 0.0f);
    m.options.contact.thickness = scene.thickness;
    m.options.contact.boxEdges = scene.boxEdges;
    m.options.useWorldGravity = false; // the cloth keeps the scene's exact (double) gravity
    // Alone, the cloth keeps its own settings (the reports measure the integrators on hanging
    // sheets; the integration's default would turn sleeping on). With colliders, the
    // integration's defaults, as drape-run has them.
    if (scene.colliders.empty()) m.options.sleep = false;
}

DrapeWorld::~DrapeWorld() = default;

void DrapeWorld::step(double dt) {
    Impl& m = *impl_;
    // stepSimulation takes a step below btScalar's epsilon as no step at all.
    if (!(btScalar(dt) >= SIMD_EPSILON))
        throw std::invalid_argument("DrapeWorld::step: dt = " + std::to_string(dt) +
                                    " s is below the smallest step Bullet takes");
    if (!m.handle) {
        m.options.timeStep = dt;
        m.handle = bullet::addCloth(m.world.get(), m.cloth, m.options);
    } else if (m.handle->settings().timeStep != dt) {
        m.handle->setTimeStep(dt);
    }
    // maxSubSteps 0: one internal step of exactly dt (in btScalar), which the cloth, told its
    // timeStep, takes as the double dt.
    m.world->stepSimulation(btScalar(dt), 0);
}

Cloth& DrapeWorld::cloth() {
    return *impl_->cloth;
}
const Cloth& DrapeWorld::cloth() const {
    return *impl_->cloth;
}

} // namespace drape::reports
