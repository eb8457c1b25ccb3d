// The report scenes and the drape runner for them.
#include "drape_reports/scenes.hpp"

#include <drape/bullet/bullet_cloth.hpp>
#include <drape/bullet/convert.hpp>

#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <cmath>

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

namespace {

ClothScene hanging(const std::string& name, const std::string& title, Index rows, Index cols) {
    ClothScene s;
    s.name = name;
    s.title = title;
    const double side = 10.0 * (cols - 1);
    s.sheet.rows = rows;
    s.sheet.cols = cols;
    s.sheet.spacing = 10.0;
    s.sheet.origin = Vec3(-0.5 * side, 0.0, 0.0);
    s.sheet.uAxis = Vec3::UnitX();
    s.sheet.vAxis = -Vec3::UnitY();
    s.mesh = makeSheet(s.sheet);
    s.pins = {sheetIndex(s.sheet, 0, 0), sheetIndex(s.sheet, 0, cols - 1)};
    s.duration = 10.0;
    const double height = 10.0 * (rows - 1);
    // The limited sheet hangs about 1.1 of its height; frame that, and some slack below.
    s.camera.target = Vec3(0.0, -0.6 * height, 0.0);
    s.camera.position = Vec3(0.35 * side, -0.45 * height, 2.6 * std::max(side, height));
    s.camera.fovDeg = 45.0;
    s.camera.width = 360;
    s.camera.height = 300;
    return s;
}

} // namespace

ClothScene experiment1(Index rows, Index cols) {
    ClothScene s = hanging("experiment1",
                           "Experiment I (" + std::to_string(rows) + " x " + std::to_string(cols) +
                               " suspended sheet)",
                           rows, cols);
    return s;
}

ClothScene hangingSheet(Index n) {
    ClothScene s = hanging("hanging" + std::to_string(n),
                           "hanging sheet " + std::to_string(n) + " x " + std::to_string(n), n, n);
    s.duration = 5.0;
    return s;
}

ClothScene experiment2(Index rows, Index cols) {
    ClothScene s;
    s.name = "experiment2";
    s.title = "Experiment II (" + std::to_string(rows) + " x " + std::to_string(cols) +
              " tablecloth onto a desk)";
    s.sheet.rows = rows;
    s.sheet.cols = cols;
    s.sheet.spacing = 10.0;
    const double alongX = 10.0 * (rows - 1), alongZ = 10.0 * (cols - 1);
    s.sheet.origin = Vec3(-0.5 * alongX, 60.0, -0.5 * alongZ);
    s.sheet.uAxis = Vec3::UnitZ();
    s.sheet.vAxis = Vec3::UnitX();
    s.mesh = makeSheet(s.sheet);
    // The desk top is smaller than the cloth in both directions (the paper's figure 8):
    // 200 x 340 for the 290 x 590 cloth, scaled with the cloth for reduced sizes.
    Collider desk;
    desk.kind = Collider::Kind::Box;
    desk.center = Vec3::Zero();
    desk.halfExtents = Vec3(100.0 * alongX / 290.0, 5.0, 170.0 * alongZ / 590.0);
    desk.friction = 0.6;
    Collider floor;
    floor.kind = Collider::Kind::Plane;
    floor.normal = Vec3::UnitY();
    floor.offset = -150.0;
    floor.friction = 0.8;
    s.colliders = {desk, floor};
    s.thickness = 1.0;
    s.duration = 10.0;
    s.camera.position = Vec3(430.0, 250.0, 560.0) * std::max(alongZ / 590.0, 0.3);
    s.camera.target = Vec3(0.0, -30.0, 0.0);
    s.camera.width = 360;
    s.camera.height = 300;
    return s;
}

ClothScene clothOnSphere(Index n) {
    ClothScene s;
    s.name = "sphere" + std::to_string(n);
    s.title = "cloth " + std::to_string(n) + " x " + std::to_string(n) + " onto a sphere";
    const double side = 10.0 * (n - 1);
    const double radius = 0.28 * side;
    s.sheet.rows = n;
    s.sheet.cols = n;
    s.sheet.spacing = 10.0;
    s.sheet.origin = Vec3(-0.5 * side, radius + 20.0, -0.5 * side);
    s.sheet.uAxis = Vec3::UnitX();
    s.sheet.vAxis = Vec3::UnitZ();
    s.mesh = makeSheet(s.sheet);
    Collider ball;
    ball.kind = Collider::Kind::Sphere;
    ball.radius = radius;
    ball.friction = 0.5;
    Collider floor;
    floor.kind = Collider::Kind::Plane;
    floor.offset = -radius - 0.4 * side;
    floor.friction = 0.8;
    s.colliders = {ball, floor};
    s.duration = 8.0;
    s.camera.position = Vec3(1.3 * side, 0.9 * side, 1.6 * side);
    s.camera.target = Vec3(0.0, -0.1 * side, 0.0);
    s.camera.width = 360;
    s.camera.height = 300;
    return s;
}

ClothScene fromSceneFile(const samples::SceneDesc& d) {
    const std::string origin = d.sourceFile.empty() ? d.name : d.sourceFile.string();
    auto refuse = [&origin](const std::string& what) {
        throw samples::SceneError(origin + ": cannot be run by every engine: " + what);
    };
    if (!d.sheet) refuse("the cloth is not a generated sheet");
    if (!d.pins.empty() || !d.attachments.empty()) refuse("pins and attachments are not supported");
    if (d.wind) refuse("wind is not supported");
    ClothScene s;
    s.name = d.name;
    s.title = d.name;
    s.sheet = d.sheet->spec;
    s.mesh = makeSheet(s.sheet);
    if (!d.cloth.particleMass || !d.cloth.springStiffness)
        refuse("particle_mass and stiffness must be given");
    s.particleMass = *d.cloth.particleMass;
    s.stiffness = *d.cloth.springStiffness;
    s.damping = d.cloth.damping;
    s.gravity = d.cloth.gravity;
    s.timeStep = d.timeStep;
    s.duration = d.duration;
    s.camera = d.camera;
    if (d.collision && d.collision->thickness) s.thickness = *d.collision->thickness;
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
    s.gravity = scene.gravity;
    s.limiter.kind = limiter;
    s.rejectUnstableTimeStep = false;
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

// --- DrapeWorld ------------------------------------------------------------------------------

struct DrapeWorld::Impl {
    std::shared_ptr<Cloth> cloth;
    std::unique_ptr<btDefaultCollisionConfiguration> config;
    std::unique_ptr<btCollisionDispatcher> dispatcher;
    std::unique_ptr<btDbvtBroadphase> broadphase;
    std::unique_ptr<btSequentialImpulseConstraintSolver> solver;
    std::unique_ptr<btDiscreteDynamicsWorld> world;
    std::vector<std::unique_ptr<btCollisionShape>> shapes;
    std::vector<std::unique_ptr<btRigidBody>> bodies;
    std::unique_ptr<bullet::BulletCloth> handle;

    ~Impl() {
        handle.reset();
        for (auto& b : bodies)
            world->removeRigidBody(b.get());
    }
};

DrapeWorld::DrapeWorld(const ClothScene& scene, const ClothSettings& settings)
    : impl_(std::make_unique<Impl>()) {
    impl_->cloth = std::make_shared<Cloth>(ClothTopology::build(scene.mesh), settings);
    for (Index p : scene.pins)
        impl_->cloth->pin(p);
    // Every scene gets a world (an empty one costs nothing per step) so that all runs share
    // the same code path.
    Impl& m = *impl_;
    m.config = std::make_unique<btDefaultCollisionConfiguration>();
    m.dispatcher = std::make_unique<btCollisionDispatcher>(m.config.get());
    m.broadphase = std::make_unique<btDbvtBroadphase>();
    m.solver = std::make_unique<btSequentialImpulseConstraintSolver>();
    m.world = std::make_unique<btDiscreteDynamicsWorld>(m.dispatcher.get(), m.broadphase.get(),
                                                        m.solver.get(), m.config.get());
    const Vec3 g = scene.gravity;
    m.world->setGravity(bullet::toBt(g));
    if (scene.colliders.empty()) return;
    for (const Collider& c : scene.colliders) {
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
        shape->setMargin(0.0f);
        btRigidBody::btRigidBodyConstructionInfo info(0.0f, nullptr, shape.get());
        info.m_startWorldTransform = t;
        info.m_friction = btScalar(c.friction);
        auto body = std::make_unique<btRigidBody>(info);
        m.world->addRigidBody(body.get());
        m.shapes.push_back(std::move(shape));
        m.bodies.push_back(std::move(body));
    }
    bullet::BulletClothSettings bs;
    bs.contact.thickness = scene.thickness;
    bs.useWorldGravity = false; // the cloth keeps the scene's exact (double) gravity
    m.handle = bullet::addCloth(m.world.get(), m.cloth, bs);
}

DrapeWorld::~DrapeWorld() = default;

void DrapeWorld::step(double dt) {
    if (!impl_->handle) {
        impl_->cloth->step(dt);
        return;
    }
    // Static colliders need no rigid-body step: refresh the broadphase pairs (the cloth's
    // proxy moved last step) and step the cloth with the exact double dt.
    impl_->world->getBroadphase()->calculateOverlappingPairs(impl_->world->getDispatcher());
    impl_->handle->stepInWorld(dt);
}

Cloth& DrapeWorld::cloth() {
    return *impl_->cloth;
}
const Cloth& DrapeWorld::cloth() const {
    return *impl_->cloth;
}

} // namespace drape::reports
