// A small owning Bullet world for the integration tests: the usual five Bullet objects plus
// the shapes, motion states and bodies a test adds, destroyed in the right order.
#pragma once

#include "drape/bullet/bullet_cloth.hpp"
#include "drape/bullet/convert.hpp"
#include "drape/cloth.hpp"
#include "drape/mesh.hpp"
#include "drape/topology.hpp"

#include <btBulletDynamicsCommon.h>

#include <memory>
#include <vector>

namespace drape::testing {

// The tests' short names for drape/bullet/convert.hpp's conversions.
inline btVector3 bt(const Vec3& v) {
    return bullet::toBt(v);
}
inline Vec3 eig(const btVector3& v) {
    return bullet::toVec(v);
}

struct TestWorld {
    btDefaultCollisionConfiguration config;
    btCollisionDispatcher dispatcher{&config};
    btDbvtBroadphase broadphase;
    btSequentialImpulseConstraintSolver solver;
    btDiscreteDynamicsWorld world{&dispatcher, &broadphase, &solver, &config};
    std::vector<std::unique_ptr<btCollisionShape>> shapes;
    std::vector<std::unique_ptr<btMotionState>> motionStates;
    std::vector<std::unique_ptr<btRigidBody>> bodies;
    std::vector<std::unique_ptr<btCollisionObject>> objects;
    std::vector<std::unique_ptr<bullet::BulletCloth>> cloths; ///< removed before the bodies

    explicit TestWorld(const Vec3& gravity = Vec3(0, -9.81, 0)) { world.setGravity(bt(gravity)); }
    TestWorld(const TestWorld&) = delete;
    TestWorld& operator=(const TestWorld&) = delete;
    ~TestWorld() {
        cloths.clear();
        for (auto& b : bodies)
            world.removeRigidBody(b.get());
        for (auto& o : objects)
            world.removeCollisionObject(o.get());
    }

    template <class Shape, class... Args> Shape* shape(Args&&... args) {
        auto s = std::make_unique<Shape>(std::forward<Args>(args)...);
        Shape* raw = s.get();
        shapes.push_back(std::move(s));
        return raw;
    }

    /// A rigid body: mass 0 makes it static.
    btRigidBody* body(btCollisionShape* s, double mass, const Vec3& position,
                      const btQuaternion& rotation = btQuaternion::getIdentity()) {
        btVector3 inertia(0, 0, 0);
        if (mass > 0.0) s->calculateLocalInertia(btScalar(mass), inertia);
        auto ms = std::make_unique<btDefaultMotionState>(btTransform(rotation, bt(position)));
        btRigidBody::btRigidBodyConstructionInfo info(btScalar(mass), ms.get(), s, inertia);
        auto b = std::make_unique<btRigidBody>(info);
        btRigidBody* raw = b.get();
        world.addRigidBody(raw);
        motionStates.push_back(std::move(ms));
        bodies.push_back(std::move(b));
        return raw;
    }

    /// A kinematic body, moved by setting its motion state's transform.
    btRigidBody* kinematic(btCollisionShape* s, const Vec3& position) {
        btRigidBody* b = body(s, 0.0, position);
        b->setCollisionFlags(b->getCollisionFlags() | btCollisionObject::CF_KINEMATIC_OBJECT);
        b->setActivationState(DISABLE_DEACTIVATION);
        return b;
    }

    bullet::BulletCloth& add(std::shared_ptr<Cloth> cloth,
                             const bullet::BulletClothSettings& s = {}) {
        cloths.push_back(bullet::addCloth(&world, std::move(cloth), s));
        return *cloths.back();
    }
};

/// A horizontal sheet (in the x-z plane at height y) of rows x cols particles, centred on
/// (cx, cz). Row r runs along z, column c along x.
inline TriangleMesh horizontalSheet(Index rows, Index cols, double spacing, double y,
                                    double cx = 0.0, double cz = 0.0) {
    SheetSpec spec;
    spec.rows = rows;
    spec.cols = cols;
    spec.spacing = spacing;
    spec.origin = Vec3(cx - 0.5 * spacing * (cols - 1), y, cz - 0.5 * spacing * (rows - 1));
    spec.uAxis = Vec3::UnitX();
    spec.vAxis = Vec3::UnitZ();
    return makeSheet(spec);
}

/// A small, soft cloth's settings: 10 g particles, 50 N/m springs, the rest default.
inline ClothSettings softCloth() {
    ClothSettings s;
    s.particleMass = 0.01;
    s.springStiffness = 50.0;
    return s;
}

inline std::shared_ptr<Cloth> makeCloth(const TriangleMesh& mesh, const ClothSettings& s) {
    return std::make_shared<Cloth>(ClothTopology::build(mesh), s);
}

/// Pins the border of an n x n sheet.
inline void pinBorder(Cloth& c, Index n) {
    for (Index k = 0; k < n; ++k) {
        c.pin(k);
        c.pin((n - 1) * n + k);
        c.pin(k * n);
        c.pin(k * n + n - 1);
    }
}

/// The cloth's linear momentum [N s].
inline Vec3 clothMomentum(const Cloth& c) {
    Vec3 p = Vec3::Zero();
    for (std::size_t i = 0; i < c.particleCount(); ++i)
        p += c.masses()[i] * c.velocities()[i];
    return p;
}

} // namespace drape::testing
