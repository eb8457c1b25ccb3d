// rigid_world_bullet.cpp: the scene's rigid bodies in a btDiscreteDynamicsWorld, with the
// cloth added through drape::bullet so that one stepSimulation steps both.
#include "rigid_world.hpp"

#include "drape_samples/mesh_io.hpp"

#include <drape/bullet/bullet_cloth.hpp>
#include <drape/bullet/convert.hpp>
#include <drape/error.hpp>

#include <btBulletDynamicsCommon.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <sstream>
#include <utility>

namespace drape::samples {

bool rigidBodiesAvailable() {
    return true;
}

namespace {

constexpr double kDegToRad = 3.14159265358979323846 / 180.0;

using bullet::toBt;
using bullet::toVec;

btQuaternion rotation(const Vec3& deg) {
    const Eigen::Quaterniond q = Eigen::AngleAxisd(deg.z() * kDegToRad, Vec3::UnitZ()) *
                                 Eigen::AngleAxisd(deg.y() * kDegToRad, Vec3::UnitY()) *
                                 Eigen::AngleAxisd(deg.x() * kDegToRad, Vec3::UnitX());
    return btQuaternion(static_cast<btScalar>(q.x()), static_cast<btScalar>(q.y()),
                        static_cast<btScalar>(q.z()), static_cast<btScalar>(q.w()));
}

btTransform pose(const Vec3& position, const Vec3& rotationDeg) {
    return btTransform(rotation(rotationDeg), toBt(position));
}

/// Keyframe interpolation: linear in position, spherical in rotation; held at the ends.
btTransform keyframePose(const std::vector<KeyframeDesc>& keys, const RigidBodyDesc& b, double t) {
    if (keys.empty()) return pose(b.position, b.rotationDeg);
    if (t <= keys.front().time) return pose(keys.front().position, keys.front().rotationDeg);
    if (t >= keys.back().time) return pose(keys.back().position, keys.back().rotationDeg);
    std::size_t k = 0;
    while (keys[k + 1].time < t)
        ++k;
    const KeyframeDesc& a = keys[k];
    const KeyframeDesc& c = keys[k + 1];
    const double s = (t - a.time) / (c.time - a.time);
    const Vec3 p = a.position + s * (c.position - a.position);
    const btQuaternion q =
        rotation(a.rotationDeg).slerp(rotation(c.rotationDeg), static_cast<btScalar>(s));
    return btTransform(q, toBt(p));
}

class BulletWorld final : public Simulation::RigidWorld {
  public:
    BulletWorld(const SceneDesc& scene, Cloth& cloth,
                const std::vector<std::vector<Index>>& attachSets)
        : scene_(scene), dispatcher_(&config_),
          world_(&dispatcher_, &broadphase_, &solver_, &config_) {
        world_.setGravity(toBt(scene.cloth.gravity));
        const CollisionDesc c = scene.collision.value_or(CollisionDesc{});
        // Not given: BulletClothSettings' defaults (one set of defaults, samples/SCENES.md), in
        // the scene's length unit.
        bullet::BulletClothSettings s = bullet::BulletClothSettings::inUnits(scene.unitsPerMetre);
        const double thickness = c.thickness.value_or(s.contact.thickness);
        checkPrecision(scene, cloth, thickness);
        checkOverlaps(scene);
        for (const RigidBodyDesc& d : scene.rigidBodies)
            addBody(d);

        // The cloth is owned by Simulation; the integration wants a shared_ptr, so hand it
        // a non-owning one (the world is destroyed before the cloth).
        std::shared_ptr<Cloth> shared(&cloth, [](Cloth*) {});
        s.contact.thickness = thickness;
        s.contact.frictionScale = c.frictionScale;
        s.contact.penaltyForce = c.penaltyForce;
        s.contact.continuous = c.continuous;
        s.contact.triangles = c.triangleContacts;
        s.contact.boxEdges = c.boxEdges;
        s.substeps = scene.substeps; // simulation.substeps, collision.substeps or "auto"
        s.selfCollision.enabled = c.selfCollision;
        s.selfCollision.thickness = c.selfThickness.value_or(s.selfCollision.thickness);
        s.useWorldGravity = false;   // the scene's gravity is already in the cloth
        s.timeStep = scene.timeStep; // the cloth steps with the scene's exact double dt
        try {
            cloth_ = bullet::addCloth(&world_, shared, s);
            for (std::size_t a = 0; a < scene.attachments.size(); ++a) {
                const std::size_t b = bodyIndex(scene.attachments[a].body);
                for (Index i : attachSets[a])
                    cloth_->attachHere(i, bodies_[b].body.get());
            }
        } catch (const drape::Error& e) {
            throw SceneError(scene.sourceFile.string() + ": collision: " + e.what());
        }
    }

    ~BulletWorld() override {
        if (cloth_) cloth_->remove();
        cloth_.reset();
        for (auto& b : bodies_)
            if (b.inWorld) world_.removeRigidBody(b.body.get());
    }

    void step(double t, double dt) override {
        for (std::size_t i = 0; i < bodies_.size(); ++i) {
            Body& b = bodies_[i];
            const RigidBodyDesc& d = scene_.rigidBodies[i];
            if (d.motion == MotionKind::Kinematic) {
                b.motion->setWorldTransform(keyframePose(d.keyframes, d, t + dt));
            } else if (d.motion == MotionKind::Dynamic && !b.inWorld && !b.manual &&
                       t + 0.5 * dt >= d.launchTime) {
                b.body->setLinearVelocity(toBt(d.linearVelocity));
                b.body->setAngularVelocity(toBt(d.angularVelocity));
                world_.addRigidBody(b.body.get());
                b.inWorld = true;
            }
        }
        // maxSubSteps = 0: exactly one internal step of dt (no accumulator, no rounding).
        world_.stepSimulation(static_cast<btScalar>(dt), 0);
    }

    std::size_t contactCount() const override { return cloth_->lastStats().contacts; }

    Eigen::Matrix4f transform(std::size_t i) const override {
        btTransform tr;
        const Body& b = bodies_[i];
        if (b.motion)
            b.motion->getWorldTransform(tr);
        else
            tr = b.body->getWorldTransform();
        Eigen::Matrix4f m = Eigen::Matrix4f::Identity();
        const btMatrix3x3& r = tr.getBasis();
        for (int row = 0; row < 3; ++row) {
            for (int col = 0; col < 3; ++col)
                m(row, col) = static_cast<float>(r[row][col]);
            m(row, 3) = static_cast<float>(tr.getOrigin()[row]);
        }
        return m;
    }

    Vec3 velocity(std::size_t i) const override {
        return toVec(bodies_[i].body->getLinearVelocity());
    }

    void launch(std::size_t i, const Vec3& position, const Vec3& velocity) override {
        Body& b = bodies_[i];
        b.manual = true;
        btTransform tr = b.body->getWorldTransform();
        tr.setOrigin(toBt(position));
        b.body->setWorldTransform(tr);
        b.body->setInterpolationWorldTransform(tr);
        if (b.motion) b.motion->setWorldTransform(tr);
        b.body->setLinearVelocity(toBt(velocity));
        b.body->setAngularVelocity(btVector3(0, 0, 0));
        b.body->clearForces();
        if (!b.inWorld) {
            world_.addRigidBody(b.body.get());
            b.inWorld = true;
        }
        b.body->activate(true);
    }

    std::string description() const override {
        std::ostringstream s;
        s << "bullet world, " << bodies_.size() << " rigid bod"
          << (bodies_.size() == 1 ? "y" : "ies");
        if (!scene_.attachments.empty())
            s << ", " << cloth_->attachments().size() << " attached particles";
        return s.str();
    }

  private:
    struct Body {
        std::shared_ptr<btCollisionShape> shape;   // shared by the bodies of one mesh file
        std::shared_ptr<btTriangleMesh> triangles; // for mesh shapes
        std::unique_ptr<btDefaultMotionState> motion;
        std::unique_ptr<btRigidBody> body;
        bool inWorld = false;
        bool manual = false; // launched by the program (a game), not by launch_time
    };

    /// Bullet keeps poses in single precision: at a distance |x| from the origin it resolves
    /// about |x| 2^-23. A scene whose cloth or bodies lie where that is coarser than a tenth
    /// of the contact thickness would place bodies off by more than the gap the cloth keeps
    /// (near 1e6 m: 6 cm): refused, naming what lies too far out.
    static void checkPrecision(const SceneDesc& scene, const Cloth& cloth, double thickness) {
        const double reach = 0.1 * thickness * 8388608.0;
        auto refuse = [&](const std::string& what, double at) {
            char buf[160];
            std::snprintf(buf, sizeof buf,
                          " lies %.6g m from the origin; with rigid bodies the scene must lie "
                          "within %.6g m",
                          at, reach);
            const std::string file =
                scene.sourceFile.empty() ? std::string("scene") : scene.sourceFile.string();
            throw SceneError(file + ": " + what + buf +
                             " (Bullet keeps positions in single precision, which resolves a "
                             "tenth of the contact thickness only that far out; move the scene "
                             "toward the origin)");
        };
        const auto& x = cloth.positions();
        for (std::size_t i = 0; i < x.size(); ++i)
            if (const double at = x[i].cwiseAbs().maxCoeff(); at > reach)
                refuse("the cloth's particle " + std::to_string(i), at);
        for (std::size_t k = 0; k < scene.rigidBodies.size(); ++k) {
            const RigidBodyDesc& d = scene.rigidBodies[k];
            const std::string name = "rigid_bodies[" + std::to_string(k) + "] \"" + d.name + "\"";
            double at = d.position.cwiseAbs().maxCoeff();
            for (const KeyframeDesc& f : d.keyframes)
                at = std::max(at, f.position.cwiseAbs().maxCoeff());
            if (d.shape.kind == ShapeKind::Plane) at = std::max(at, std::abs(d.shape.offset));
            if (at > reach) refuse(name, at);
        }
    }

    /// The most pairs of rigid bodies whose bounding spheres overlap at the start, per body
    /// (plus a floor): a stack or a pile has a few per body; bodies piled at one point have
    /// n^2 / 2, and Bullet's broadphase and solver work (and memory) grow with the pairs
    /// (10,000 spheres at one point: over a minute and 3.7 GB before the first step ended).
    static constexpr std::size_t kMaxOverlapsPerBody = 16, kMaxOverlapsFloor = 1000;

    /// Refuses a scene whose bodies start piled into each other beyond kMaxOverlapsPerBody
    /// pairs per body: sort and sweep on x over bounding spheres, stopping at the limit.
    static void checkOverlaps(const SceneDesc& scene) {
        struct Ball {
            double lo, hi;
            Vec3 c;
            double r;
            bool moving; // dynamic or kinematic: Bullet pairs static bodies only with these
        };
        std::vector<Ball> balls;
        for (const RigidBodyDesc& d : scene.rigidBodies) {
            double r = 0.0;
            switch (d.shape.kind) {
            case ShapeKind::Box:
                r = d.shape.halfExtents.norm();
                break;
            case ShapeKind::Sphere:
                r = d.shape.radius;
                break;
            case ShapeKind::Capsule:
                r = d.shape.radius + 0.5 * d.shape.height;
                break;
            case ShapeKind::Plane:
            case ShapeKind::Mesh:
                continue; // static: Bullet pairs nothing static with static
            }
            const Vec3 c = d.keyframes.empty() ? d.position : d.keyframes.front().position;
            balls.push_back(Ball{c.x() - r, c.x() + r, c, r, d.motion != MotionKind::Static});
        }
        const std::size_t limit = kMaxOverlapsFloor + kMaxOverlapsPerBody * balls.size();
        std::sort(balls.begin(), balls.end(),
                  [](const Ball& a, const Ball& b) { return a.lo < b.lo; });
        std::size_t pairs = 0;
        for (std::size_t i = 0; i < balls.size(); ++i) {
            for (std::size_t j = i + 1; j < balls.size() && balls[j].lo <= balls[i].hi; ++j) {
                const double reach = balls[i].r + balls[j].r;
                if (!(balls[i].moving || balls[j].moving) ||
                    (balls[i].c - balls[j].c).squaredNorm() > reach * reach)
                    continue;
                if (++pairs > limit) {
                    const std::string file =
                        scene.sourceFile.empty() ? std::string("scene") : scene.sourceFile.string();
                    throw SceneError(
                        file + ": rigid_bodies: more than " + std::to_string(limit) +
                        " pairs of bodies overlap where they start (" +
                        std::to_string(balls.size()) +
                        " bodies, bounding spheres): bodies piled into each other cost Bullet "
                        "work and memory for every pair; spread them out");
                }
            }
        }
    }

    /// Mesh files' triangles and shapes, by path (see addBody).
    std::map<std::string,
             std::pair<std::shared_ptr<btTriangleMesh>, std::shared_ptr<btCollisionShape>>>
        meshShapes_;

    std::size_t bodyIndex(const std::string& name) const {
        for (std::size_t i = 0; i < scene_.rigidBodies.size(); ++i)
            if (scene_.rigidBodies[i].name == name) return i;
        throw SceneError(scene_.sourceFile.string() + ": no rigid body named \"" + name + "\"");
    }

    void addBody(const RigidBodyDesc& d) {
        Body b;
        switch (d.shape.kind) {
        case ShapeKind::Box:
            b.shape = std::make_unique<btBoxShape>(toBt(d.shape.halfExtents));
            break;
        case ShapeKind::Sphere:
            b.shape = std::make_unique<btSphereShape>(static_cast<btScalar>(d.shape.radius));
            break;
        case ShapeKind::Capsule:
            b.shape = std::make_unique<btCapsuleShape>(static_cast<btScalar>(d.shape.radius),
                                                       static_cast<btScalar>(d.shape.height));
            break;
        case ShapeKind::Plane:
            b.shape = std::make_unique<btStaticPlaneShape>(toBt(d.shape.normal),
                                                           static_cast<btScalar>(d.shape.offset));
            break;
        case ShapeKind::Mesh: {
            // One import and one BVH per file, however many (static) bodies name it.
            auto& shared = meshShapes_[meshDescKey(d.shape.mesh)];
            if (!shared.second) {
                const ImportedMesh im = importMesh(d.shape.mesh, false); // a collider
                shared.first = std::make_shared<btTriangleMesh>(true, false);
                for (const Triangle& t : im.mesh.triangles)
                    shared.first->addTriangle(toBt(im.mesh.vertices[t[0]]),
                                              toBt(im.mesh.vertices[t[1]]),
                                              toBt(im.mesh.vertices[t[2]]), false);
                shared.second = std::make_shared<btBvhTriangleMeshShape>(shared.first.get(), true);
            }
            b.triangles = shared.first;
            b.shape = shared.second;
            break;
        }
        }
        const bool dynamic = d.motion == MotionKind::Dynamic;
        btVector3 inertia(0, 0, 0);
        const btScalar mass = dynamic ? static_cast<btScalar>(d.mass) : btScalar(0);
        if (dynamic) b.shape->calculateLocalInertia(mass, inertia);
        const btTransform start = d.motion == MotionKind::Kinematic
                                      ? keyframePose(d.keyframes, d, 0.0)
                                      : pose(d.position, d.rotationDeg);
        if (d.motion == MotionKind::Kinematic)
            b.motion = std::make_unique<btDefaultMotionState>(start);
        btRigidBody::btRigidBodyConstructionInfo info(mass, b.motion.get(), b.shape.get(), inertia);
        info.m_startWorldTransform = start;
        info.m_friction = static_cast<btScalar>(d.friction);
        info.m_restitution = static_cast<btScalar>(d.restitution);
        b.body = std::make_unique<btRigidBody>(info);
        if (d.motion == MotionKind::Kinematic) {
            b.body->setCollisionFlags(b.body->getCollisionFlags() |
                                      btCollisionObject::CF_KINEMATIC_OBJECT);
            b.body->setActivationState(DISABLE_DEACTIVATION);
        }
        if (dynamic) {
            b.body->setLinearVelocity(toBt(d.linearVelocity));
            b.body->setAngularVelocity(toBt(d.angularVelocity));
            // Thrown objects should not stop in mid-air because Bullet put them to sleep.
            b.body->setActivationState(DISABLE_DEACTIVATION);
        }
        if (!dynamic || d.launchTime <= 0.0) {
            world_.addRigidBody(b.body.get());
            b.inWorld = true;
        }
        bodies_.push_back(std::move(b));
    }

    const SceneDesc& scene_;
    btDefaultCollisionConfiguration config_;
    btCollisionDispatcher dispatcher_;
    btDbvtBroadphase broadphase_;
    btSequentialImpulseConstraintSolver solver_;
    btDiscreteDynamicsWorld world_;
    std::vector<Body> bodies_;
    std::unique_ptr<bullet::BulletCloth> cloth_;
};

} // namespace

std::unique_ptr<Simulation::RigidWorld>
Simulation::RigidWorld::create(const SceneDesc& scene, Cloth& cloth,
                               const std::vector<std::vector<Index>>& attachSets) {
    return std::make_unique<BulletWorld>(scene, cloth, attachSets);
}

} // namespace drape::samples
