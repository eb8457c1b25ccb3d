// The scenes of drape-bench-games: what a game is made of (a net, a curtain a character walks
// through, a flag in gusty wind, capes on kinematic and dynamic bodies, a cloth dropped on a
// stack of boxes, a garment on a moving body), each in a real btDiscreteDynamicsWorld with
// drape's DEFAULT settings (ClothSettings{}, BulletClothSettings{}), changed only where the
// scene itself needs it (pins, attachments, wind). SI units, y up, gravity -9.81 m/s^2.
//
// A scene builder returns a GameScene: the world with its bodies, one cloth in it, how long
// it runs, and hooks the runner calls around every frame (move the kinematic bodies, set the
// wind, measure). Nothing here times anything; drape_bench_games.cpp does.
#pragma once

#include <drape/bullet/bullet_cloth.hpp>
#include <drape/bullet/convert.hpp>
#include <drape/cloth.hpp>
#include <drape/mesh.hpp>
#include <drape/topology.hpp>

#include <BulletCollision/CollisionShapes/btMultiSphereShape.h>
#include <BulletCollision/NarrowPhaseCollision/btGjkEpa2.h>
#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

namespace drape::games {

/// The frame of a 60 Hz game: stepSimulation(kFrame) with Bullet's defaults (maxSubSteps 1,
/// fixedTimeStep 1/60) takes exactly one internal sub-step per frame.
inline constexpr btScalar kFrame = btScalar(1.0) / btScalar(60.0);
inline constexpr double kGravity = 9.81; ///< [m/s^2], along -y
inline constexpr double kPi = 3.14159265358979323846;

/// A btDiscreteDynamicsWorld and everything it needs, owning its bodies. Bodies are removed
/// from the world before they are destroyed, the world is destroyed before its parts.
class GameWorld {
  public:
    GameWorld()
        : config_(std::make_unique<btDefaultCollisionConfiguration>()),
          dispatcher_(std::make_unique<btCollisionDispatcher>(config_.get())),
          broadphase_(std::make_unique<btDbvtBroadphase>()),
          solver_(std::make_unique<btSequentialImpulseConstraintSolver>()),
          world_(std::make_unique<btDiscreteDynamicsWorld>(dispatcher_.get(), broadphase_.get(),
                                                           solver_.get(), config_.get())) {
        world_->setGravity(btVector3(0, btScalar(-kGravity), 0));
    }
    ~GameWorld() {
        for (auto& c : constraints_)
            world_->removeConstraint(c.get());
        constraints_.clear();
        for (auto it = bodies_.rbegin(); it != bodies_.rend(); ++it)
            world_->removeRigidBody(it->get());
        bodies_.clear();
        world_.reset();
    }
    GameWorld(const GameWorld&) = delete;
    GameWorld& operator=(const GameWorld&) = delete;

    btDiscreteDynamicsWorld* world() const { return world_.get(); }

    /// Adds a body: static (mass 0), kinematic (mass 0, kinematic = true: moved through its
    /// motion state, never deactivated) or dynamic (mass > 0). Friction and everything else
    /// are Bullet's defaults (friction 0.5, restitution 0).
    btRigidBody* addBody(std::unique_ptr<btCollisionShape> shape, btScalar mass,
                         const btTransform& pose, bool kinematic = false) {
        btVector3 inertia(0, 0, 0);
        if (mass > 0) shape->calculateLocalInertia(mass, inertia);
        auto motion = std::make_unique<btDefaultMotionState>(pose);
        btRigidBody::btRigidBodyConstructionInfo info(mass, motion.get(), shape.get(), inertia);
        auto body = std::make_unique<btRigidBody>(info);
        if (kinematic) {
            body->setCollisionFlags(body->getCollisionFlags() |
                                    btCollisionObject::CF_KINEMATIC_OBJECT);
            body->setActivationState(DISABLE_DEACTIVATION);
        }
        world_->addRigidBody(body.get());
        btRigidBody* raw = body.get();
        shapes_.push_back(std::move(shape));
        motions_.push_back(std::move(motion));
        bodies_.push_back(std::move(body));
        return raw;
    }

    /// Adds a joint (removed from the world before the bodies); its bodies collide with each
    /// other unless `apart` is false.
    template <class Constraint>
    Constraint* addConstraint(std::unique_ptr<Constraint> c, bool apart = true) {
        Constraint* raw = c.get();
        world_->addConstraint(raw, !apart);
        constraints_.push_back(std::move(c));
        return raw;
    }

  private:
    std::unique_ptr<btDefaultCollisionConfiguration> config_;
    std::unique_ptr<btCollisionDispatcher> dispatcher_;
    std::unique_ptr<btDbvtBroadphase> broadphase_;
    std::unique_ptr<btSequentialImpulseConstraintSolver> solver_;
    std::unique_ptr<btDiscreteDynamicsWorld> world_;
    std::vector<std::unique_ptr<btCollisionShape>> shapes_;
    std::vector<std::unique_ptr<btMotionState>> motions_;
    std::vector<std::unique_ptr<btRigidBody>> bodies_;
    std::vector<std::unique_ptr<btTypedConstraint>> constraints_;
};

/// One scene: a world, one cloth in it and the hooks the runner calls. Members are destroyed
/// in reverse order: the cloth leaves the world before the world goes.
struct GameScene {
    std::unique_ptr<GameWorld> world;
    std::shared_ptr<Cloth> cloth;
    std::unique_ptr<bullet::BulletCloth> handle;
    /// More cloths in the world (a scene of several): stepped with it by stepSimulation and
    /// timed with it, not measured in the table's cloth columns. Leave the world first.
    std::vector<std::shared_ptr<Cloth>> others;
    std::vector<std::unique_ptr<bullet::BulletCloth>> otherHandles;
    double seconds = 1.0; ///< simulated time the scene runs [s] (before --seconds-scale)
    /// Before the frame that ends at simulated time tEnd [s] (scene time: 0 when the runner
    /// starts): move kinematic bodies, set the wind. Not timed.
    std::function<void(double tEnd)> beforeFrame;
    /// After every frame (t: scene time at its end) [s]: scene-specific measurements. Not
    /// timed.
    std::function<void(double t)> afterFrame;
    /// After the last frame: the scene-specific results, one short Markdown cell.
    std::function<std::string()> notes;
};

/// Moves a kinematic body: its motion state, read by Bullet at the start of the next
/// stepSimulation (which derives the body's velocity from the move).
inline void moveKinematic(btRigidBody* body, const btTransform& pose) {
    body->getMotionState()->setWorldTransform(pose);
}

inline btTransform at(double x, double y, double z) {
    btTransform t;
    t.setIdentity();
    t.setOrigin(btVector3(btScalar(x), btScalar(y), btScalar(z)));
    return t;
}

/// Adds the cloth of `mesh` with default settings (changed by `edit`, if given) to the scene's
/// world with default BulletClothSettings.
inline void addDefaultCloth(GameScene& s, const TriangleMesh& mesh,
                            const std::function<void(ClothSettings&)>& edit = {}) {
    ClothSettings settings;
    if (edit) edit(settings);
    s.cloth = std::make_shared<Cloth>(ClothTopology::build(mesh), settings);
    s.handle = bullet::addCloth(s.world->world(), s.cloth);
}

inline std::string format(const char* fmt, double a) {
    char buf[128];
    std::snprintf(buf, sizeof buf, fmt, a);
    return buf;
}

inline std::string timeOrNever(double t) {
    return t < 0.0 ? std::string("never") : format("%.2f s", t);
}

/// 1. net: 41 x 41, 0.025 m (1 m square), horizontal, pinned on all four edges, untouched.
inline GameScene makeNet() {
    GameScene s;
    s.world = std::make_unique<GameWorld>();
    SheetSpec sheet;
    sheet.rows = 41;
    sheet.cols = 41;
    sheet.spacing = 0.025;
    sheet.origin = Vec3(-0.5, 1.0, -0.5);
    sheet.uAxis = Vec3::UnitX();
    sheet.vAxis = Vec3::UnitZ();
    addDefaultCloth(s, makeSheet(sheet));
    for (Index r = 0; r < sheet.rows; ++r)
        for (Index c = 0; c < sheet.cols; ++c)
            if (r == 0 || c == 0 || r + 1 == sheet.rows || c + 1 == sheet.cols)
                s.cloth->pin(sheetIndex(sheet, r, c));
    s.seconds = 4.0;
    return s;
}

/// 2. curtain_walk: 41 x 41, 0.05 m (2 m square), vertical in the x-y plane at z = 0, top row
/// pinned. A kinematic upright capsule (radius 0.3, cylinder 1.0) walks along z at 1.5 m/s
/// from -1.5 to +1.5 (2 s) and back (2 s), then stands still at z = -1.5 while the curtain
/// swings free (2 s).
inline GameScene makeCurtainWalk() {
    GameScene s;
    s.world = std::make_unique<GameWorld>();
    constexpr double kY = 0.9, kStart = -1.5, kSpeed = 1.5;
    btRigidBody* walker = s.world->addBody(std::make_unique<btCapsuleShape>(btScalar(0.3), 1), 0,
                                           at(0.0, kY, kStart), true);
    SheetSpec sheet;
    sheet.rows = 41;
    sheet.cols = 41;
    sheet.spacing = 0.05;
    sheet.origin = Vec3(-1.0, 2.2, 0.0); // top-left; bottom row at y = 0.2
    addDefaultCloth(s, makeSheet(sheet));
    for (Index c = 0; c < sheet.cols; ++c)
        s.cloth->pin(sheetIndex(sheet, 0, c));
    s.beforeFrame = [walker](double t) {
        double z = kStart;
        if (t < 2.0)
            z = kStart + kSpeed * t;
        else if (t < 4.0)
            z = -kStart - kSpeed * (t - 2.0);
        moveKinematic(walker, at(0.0, kY, z));
    };
    s.seconds = 6.0;
    return s;
}

/// The flags' wind at time t [m/s]: gusts along x, a slow swing along z.
inline Vec3 gustyWind(double t) {
    const double wx =
        8.0 + 4.0 * std::sin(2.0 * kPi * 0.5 * t) + 2.0 * std::sin(2.0 * kPi * 1.7 * t);
    const double wz = 0.5 + 0.5 * std::sin(2.0 * kPi * 0.23 * t);
    return Vec3(wx, 0.0, wz);
}

/// 3. flag: 25 x 17, 0.05 m (1.2 x 0.8 m) in the x-y plane, left column pinned, aerodynamics
/// on (air 1.2 kg/m^3, C_d and C_l default), gusty wind along x with a small z component, set
/// every frame.
inline GameScene makeFlag() {
    GameScene s;
    s.world = std::make_unique<GameWorld>();
    SheetSpec sheet;
    sheet.rows = 17;
    sheet.cols = 25;
    sheet.spacing = 0.05;
    sheet.origin = Vec3(0.0, 2.0, 0.0);
    addDefaultCloth(s, makeSheet(sheet), [](ClothSettings& c) { c.aero.airDensity = 1.2; });
    for (Index r = 0; r < sheet.rows; ++r)
        s.cloth->pin(sheetIndex(sheet, r, 0));
    Cloth* cloth = s.cloth.get();
    s.beforeFrame = [cloth](double t) { cloth->setWind(gustyWind(t)); };
    s.seconds = 6.0;
    return s;
}

/// The box the cape of scenes 4, 5 and 19 hangs from (addCape): half-extents (0.4, 0.1, 0.2).
inline std::unique_ptr<btBoxShape> capeShoulders() {
    return std::make_unique<btBoxShape>(btVector3(btScalar(0.4), btScalar(0.1), btScalar(0.2)));
}

/// The cape of scenes 4 and 5: 13 x 19, 0.05 m (0.6 x 0.9 m) in the x-y plane, hanging from
/// the back top edge of a box of half-extents (0.4, 0.1, 0.2) centred at `centre` (the cape's
/// top row 3 cm behind the box's back face, beyond the default contact thickness and penalty
/// band, at the height of its top face), top row attached.
inline void addCape(GameScene& s, btRigidBody* shoulders, const Vec3& centre) {
    SheetSpec sheet;
    sheet.rows = 19;
    sheet.cols = 13;
    sheet.spacing = 0.05;
    sheet.origin = centre + Vec3(-0.3, 0.1, -0.23);
    addDefaultCloth(s, makeSheet(sheet));
    for (Index c = 0; c < sheet.cols; ++c)
        s.handle->attachHere(sheetIndex(sheet, 0, c), shoulders);
}

/// 4. cape_kinematic: the cape on a kinematic box moving on a circle of radius 1 m at 2 rad/s
/// (2 m/s), turned to face where it goes; it starts at rest and runs from the first frame.
inline GameScene makeCapeKinematic() {
    GameScene s;
    s.world = std::make_unique<GameWorld>();
    constexpr double kRadius = 1.0, kOmega = 2.0, kY = 1.5;
    btRigidBody* box = s.world->addBody(capeShoulders(), 0, at(kRadius, kY, 0.0), true);
    addCape(s, box, Vec3(kRadius, kY, 0.0));
    s.beforeFrame = [box](double t) {
        const double a = kOmega * t;
        btTransform pose = at(kRadius * std::cos(a), kY, kRadius * std::sin(a));
        // Local +z (the front) along the velocity (-sin a, 0, cos a): a yaw of -a.
        pose.setRotation(btQuaternion(btVector3(0, 1, 0), btScalar(-a)));
        moveKinematic(box, pose);
    };
    s.seconds = 6.0;
    return s;
}

/// 5. cape_dynamic: the cape on a dynamic 5 kg box with no gravity of its own, all at rest.
/// Only the cape's weight and its air drag (the particle damping -C_d v, an external force)
/// act on box + cape, so their momentum along y must be -m_cape g t plus the drag's impulse
/// (summed over the frames, trapezoidal); the note is the relative error at the end and the
/// largest after 1 s. cape_light: the same on a 0.05 kg box, half the cape's mass (the box
/// and the cape's top row move as one rigid body: integration/README.md, "A free body the
/// cloth hangs from carries its particles in the walk").
inline GameScene makeCapeOnBox(double boxMass) {
    GameScene s;
    s.world = std::make_unique<GameWorld>();
    constexpr double kY = 1.5;
    btRigidBody* box = s.world->addBody(capeShoulders(), btScalar(boxMass), at(0.0, kY, 0.0));
    box->setGravity(btVector3(0, 0, 0));
    box->setActivationState(DISABLE_DEACTIVATION);
    addCape(s, box, Vec3(0.0, kY, 0.0));
    struct State {
        double endError = 0.0, maxError = -1.0, expected = 0.0, measured = 0.0, capeMass = 0.0;
        double drag = 0.0, lastDragForce = 0.0, lastTime = 0.0; ///< [N s], [N], [s]
    };
    auto st = std::make_shared<State>();
    for (double m : s.cloth->masses())
        st->capeMass += m;
    Cloth* cloth = s.cloth.get();
    s.afterFrame = [st, box, cloth, boxMass](double) {
        double p = boxMass * static_cast<double>(box->getLinearVelocity().y());
        const auto& m = cloth->masses();
        const auto& v = cloth->velocities();
        double vSum = 0.0;
        for (std::size_t i = 0; i < m.size(); ++i) {
            p += m[i] * v[i].y();
            vSum += v[i].y();
        }
        const double dragForce = -cloth->settings().damping * vSum;
        st->drag += 0.5 * (dragForce + st->lastDragForce) * (cloth->time() - st->lastTime);
        st->lastDragForce = dragForce;
        st->lastTime = cloth->time();
        const double expected = -st->capeMass * kGravity * cloth->time() + st->drag;
        const double err = expected != 0.0 ? 100.0 * (p - expected) / std::abs(expected) : 0.0;
        st->endError = err;
        st->expected = expected;
        st->measured = p;
        if (cloth->time() >= 1.0) st->maxError = std::max(st->maxError, std::abs(err));
    };
    bullet::BulletCloth* handle = s.handle.get();
    s.notes = [st, handle, boxMass]() {
        const Vec3 j = handle->totalStats().impulseOnBodies;
        char buf[512];
        std::snprintf(buf, sizeof buf,
                      "momentum y error %+.3f %% at the end (%.4f against %.4f N s), max abs error "
                      "after 1 s %s; cape %.4f kg on a %.2f kg box; impulse on bodies (%.3f, "
                      "%.3f, %.3f) N s",
                      st->endError, st->measured, st->expected,
                      st->maxError < 0.0 ? "n/a" : format("%.3f %%", st->maxError).c_str(),
                      st->capeMass, boxMass, j.x(), j.y(), j.z());
        return std::string(buf);
    };
    s.seconds = 4.0;
    return s;
}
inline GameScene makeCapeDynamic() {
    return makeCapeOnBox(5.0);
}
inline GameScene makeCapeLight() {
    return makeCapeOnBox(0.05);
}

/// 6. stack: three dynamic 0.4 m cubes (2 kg, friction 0.5) on a static ground plane, settled
/// for 1 s (untimed, before the cloth exists), then a 25 x 25, 0.05 m (1.2 m square)
/// horizontal cloth is dropped from 0.3 m above the top box. Notes: the top box's
/// displacement from where it settled, when the boxes and the cloth fell asleep (for good).
inline GameScene makeStack() {
    GameScene s;
    s.world = std::make_unique<GameWorld>();
    s.world->addBody(std::make_unique<btStaticPlaneShape>(btVector3(0, 1, 0), btScalar(0)), 0,
                     at(0.0, 0.0, 0.0));
    std::vector<btRigidBody*> boxes;
    for (int i = 0; i < 3; ++i)
        boxes.push_back(s.world->addBody(
            std::make_unique<btBoxShape>(btVector3(btScalar(0.2), btScalar(0.2), btScalar(0.2))), 2,
            at(0.0, 0.2 + 0.4 * i, 0.0)));
    for (int f = 0; f < 60; ++f)
        s.world->world()->stepSimulation(kFrame);
    const btVector3 settled = boxes.back()->getWorldTransform().getOrigin();
    const double top = static_cast<double>(settled.y()) + 0.2;

    SheetSpec sheet;
    sheet.rows = 25;
    sheet.cols = 25;
    sheet.spacing = 0.05;
    sheet.origin = Vec3(-0.6, top + 0.3, -0.6);
    sheet.uAxis = Vec3::UnitX();
    sheet.vAxis = Vec3::UnitZ();
    addDefaultCloth(s, makeSheet(sheet));

    struct State {
        double boxesAsleep = -1.0, clothAsleep = -1.0; ///< start of the last asleep run
        double boxesFirst = -1.0, clothFirst = -1.0;
        int boxWakes = 0, clothWakes = 0;
        double maxDisplacement = 0.0, endDisplacement = 0.0;
    };
    auto st = std::make_shared<State>();
    Cloth* cloth = s.cloth.get();
    bullet::BulletCloth* handle = s.handle.get();
    s.afterFrame = [st, boxes, settled, cloth](double t) {
        bool asleep = true;
        for (const btRigidBody* b : boxes)
            asleep = asleep && !b->isActive();
        if (asleep && st->boxesAsleep < 0.0) {
            st->boxesAsleep = t;
            if (st->boxesFirst < 0.0) st->boxesFirst = t;
        } else if (!asleep && st->boxesAsleep >= 0.0) {
            st->boxesAsleep = -1.0;
            ++st->boxWakes;
        }
        if (cloth->isAsleep() && st->clothAsleep < 0.0) {
            st->clothAsleep = t;
            if (st->clothFirst < 0.0) st->clothFirst = t;
        } else if (!cloth->isAsleep() && st->clothAsleep >= 0.0) {
            st->clothAsleep = -1.0;
            ++st->clothWakes;
        }
        const double d =
            static_cast<double>((boxes.back()->getWorldTransform().getOrigin() - settled).length());
        st->endDisplacement = d;
        st->maxDisplacement = std::max(st->maxDisplacement, d);
    };
    s.notes = [st, handle]() {
        const Vec3 j = handle->totalStats().impulseOnBodies;
        char buf[512];
        std::snprintf(buf, sizeof buf,
                      "top box moved %.1f mm (max %.1f mm); boxes asleep %s (first %s, woke %d "
                      "times); cloth asleep %s (first %s, woke %d times); impulse on bodies "
                      "(%.2f, %.2f, %.2f) N s",
                      1e3 * st->endDisplacement, 1e3 * st->maxDisplacement,
                      timeOrNever(st->boxesAsleep).c_str(), timeOrNever(st->boxesFirst).c_str(),
                      st->boxWakes, timeOrNever(st->clothAsleep).c_str(),
                      timeOrNever(st->clothFirst).c_str(), st->clothWakes, j.x(), j.y(), j.z());
        return std::string(buf);
    };
    s.seconds = 12.0;
    return s;
}

/// The fastest particle of a cloth [m/s].
inline double fastestParticle(const Cloth& cloth) {
    double v = 0.0;
    for (const Vec3& u : cloth.velocities())
        v = std::max(v, u.norm());
    return v;
}

/// 19. cape_snap: the cape of scenes 4-5 on a kinematic box walking forward (+z, out of the
/// cape's plane) at 1.5 m/s, snapped by the game in one frame 0.3 m sideways (+x, in the cape's
/// plane) at 2 s and 0.3 m forward at 4 s (a network correction or a character snapped to the
/// ground: slower than BulletClothSettings::teleportSpeed, so the cape is dragged, not
/// carried). The cape must gain the snap's 18 m/s within the frame: the strain limiter drags
/// the whole cape (integration/README.md, "Jolt beside drape on game scenes"); the table's max
/// column is the snap frames'. Notes: the fastest particle in the second after each snap.
inline GameScene makeCapeSnap() {
    GameScene s;
    s.world = std::make_unique<GameWorld>();
    constexpr double kY = 1.5, kSpeed = 1.5, kSnap = 0.3;
    btRigidBody* box = s.world->addBody(capeShoulders(), 0, at(0.0, kY, 0.0), true);
    addCape(s, box, Vec3(0.0, kY, 0.0));
    s.beforeFrame = [box](double t) {
        const double x = t >= 2.0 ? kSnap : 0.0;
        const double z = kSpeed * t + (t >= 4.0 ? kSnap : 0.0);
        moveKinematic(box, at(x, kY, z));
    };
    auto fastest = std::make_shared<std::array<double, 2>>();
    Cloth* cloth = s.cloth.get();
    s.afterFrame = [fastest, cloth](double t) {
        const int snap = t > 2.0 && t <= 3.0 ? 0 : t > 4.0 && t <= 5.0 ? 1 : -1;
        if (snap >= 0)
            (*fastest)[std::size_t(snap)] =
                std::max((*fastest)[std::size_t(snap)], fastestParticle(*cloth));
    };
    s.notes = [fastest]() {
        char buf[256];
        std::snprintf(buf, sizeof buf,
                      "snapped %.1f m in the cape's plane at 2 s and %.1f m out of it at 4 s "
                      "(18 m/s within a frame): the fastest particle in the second after "
                      "%.1f and %.1f m/s",
                      kSnap, kSnap, (*fastest)[0], (*fastest)[1]);
        return std::string(buf);
    };
    s.seconds = 6.0;
    return s;
}

/// 20. curtain_pick: picking as the README shows it. A 1 m curtain (41 x 41, 0.025 m, pinned
/// along its top row at y 2) is grabbed (Cloth::setGrab, automatic stiffness) 0.7 m below the
/// pins in its middle column; the mouse moves 0.2 m sideways in the curtain's plane at 1 m/s
/// (0.5-0.7 s) and holds, then 0.2 m toward the viewer (2.0-2.2 s) and holds; the grab is let
/// go at 3.5 s. Notes: how far the grabbed particle trails the mouse at the end of each hold
/// (the cloth pulls back where it cannot follow) and the fastest particle after letting go.
inline GameScene makeCurtainPick() {
    GameScene s;
    s.world = std::make_unique<GameWorld>();
    SheetSpec sheet;
    sheet.rows = 41;
    sheet.cols = 41;
    sheet.spacing = 0.025;
    sheet.origin = Vec3(-0.5, 2.0, 0.0);
    addDefaultCloth(s, makeSheet(sheet));
    for (Index c = 0; c < sheet.cols; ++c)
        s.cloth->pin(sheetIndex(sheet, 0, c));
    const Index grabbed = sheetIndex(sheet, 28, 20);
    const Vec3 start = s.cloth->positions()[grabbed];
    auto mouse = [start](double t) {
        const double side = 0.2 * std::clamp((t - 0.5) / 0.2, 0.0, 1.0);
        const double toward = 0.2 * std::clamp((t - 2.0) / 0.2, 0.0, 1.0);
        return Vec3(start + Vec3(side, 0.0, toward));
    };
    Cloth* cloth = s.cloth.get();
    s.beforeFrame = [cloth, grabbed, mouse](double t) {
        if (t <= 3.5)
            cloth->setGrab(grabbed, mouse(t));
        else if (!cloth->grabs().empty())
            cloth->releaseGrab(grabbed);
    };
    struct State {
        double trailSide = 0.0, trailToward = 0.0, fastestAfter = 0.0;
    };
    auto st = std::make_shared<State>();
    s.afterFrame = [st, cloth, grabbed, mouse](double t) {
        const double trail = (cloth->positions()[grabbed] - mouse(t)).norm();
        if (std::abs(t - 2.0) < 0.5 / 60.0) st->trailSide = trail;
        if (std::abs(t - 3.5) < 0.5 / 60.0) st->trailToward = trail;
        if (t > 3.5) st->fastestAfter = std::max(st->fastestAfter, fastestParticle(*cloth));
    };
    s.notes = [st]() {
        char buf[256];
        std::snprintf(buf, sizeof buf,
                      "grabbed 0.7 m below the pins: the particle trails the mouse by %.3f m "
                      "held 0.2 m aside in the plane, %.3f m held 0.2 m out of it too; let go, "
                      "the fastest particle %.2f m/s",
                      st->trailSide, st->trailToward, st->fastestAfter);
        return std::string(buf);
    };
    s.seconds = 5.0;
    return s;
}

/// A tube (open cylinder) around the y axis: `around` particles per ring, `rings` rings from
/// y = top down to top - height, each quad split along alternating diagonals.
inline TriangleMesh makeTube(const Vec3& centreTop, double radius, double height, Index around,
                             Index rings) {
    TriangleMesh m;
    for (Index j = 0; j < rings; ++j)
        for (Index i = 0; i < around; ++i) {
            const double a = 2.0 * kPi * static_cast<double>(i) / static_cast<double>(around);
            const double y = -height * static_cast<double>(j) / static_cast<double>(rings - 1);
            m.vertices.push_back(centreTop + Vec3(radius * std::cos(a), y, radius * std::sin(a)));
        }
    for (Index j = 0; j + 1 < rings; ++j)
        for (Index i = 0; i < around; ++i) {
            const Index i1 = (i + 1) % around;
            const Index a = j * around + i, b = j * around + i1;
            const Index c = (j + 1) * around + i1, d = (j + 1) * around + i;
            if ((i + j) % 2 == 0) {
                m.triangles.push_back({a, d, c});
                m.triangles.push_back({a, c, b});
            } else {
                m.triangles.push_back({a, d, b});
                m.triangles.push_back({b, d, c});
            }
        }
    return m;
}

/// 7. garment: a tube (radius 0.2, height 0.6, 32 around x 13 high) around a kinematic
/// capsule "body" (radius 0.17, cylinder 0.8, centred at y = 0.9), its top ring attached to
/// the capsule, which moves side to side along x: x = 0.25 sin(4 t) (peak speed 1 m/s).
inline GameScene makeGarment() {
    GameScene s;
    s.world = std::make_unique<GameWorld>();
    constexpr double kY = 0.9, kAmplitude = 0.25, kOmega = 4.0;
    btRigidBody* body = s.world->addBody(
        std::make_unique<btCapsuleShape>(btScalar(0.17), btScalar(0.8)), 0, at(0, kY, 0), true);
    constexpr Index kAround = 32, kRings = 13;
    addDefaultCloth(s, makeTube(Vec3(0.0, kY + 0.4, 0.0), 0.2, 0.6, kAround, kRings));
    // No vertex is welded or dropped: particle i is vertex i, the top ring is 0 .. kAround - 1.
    for (Index i = 0; i < kAround; ++i)
        s.handle->attachHere(s.cloth->topology().vertexToParticle()[i], body);
    s.beforeFrame = [body](double t) {
        moveKinematic(body, at(kAmplitude * std::sin(kOmega * t), kY, 0.0));
    };
    s.seconds = 6.0;
    return s;
}

/// 8. net_ball: the net of scene 1 (41 x 41, 1 m, pinned on all edges) and a dynamic ball
/// (radius 5 cm, 0.5 kg, a game's projectile) launched at t = 1 s from 0.5 m above the net's
/// centre, straight down at 20 m/s (world gravity on both). The net must catch it: it sags
/// at most 0.23 m at its 10 % bound, so the ball's lowest centre over the net is above
/// 1.0 - 0.23 - r. (Thrown back up, the ball drifts sideways and may fall past the net's
/// edge: only its centre over the net, |x|, |z| < 0.5, counts.)
/// Notes: the ball's lowest point over the net, the fastest it was thrown back up, its speed
/// at the end and the impulse the cloth gave the bodies along y. The frame columns' max is the
/// hit.
inline GameScene makeNetBall() {
    GameScene s = makeNet();
    constexpr double kRadius = 0.05, kMass = 0.5, kSpeed = 20.0, kLaunch = 1.0;
    struct State {
        btRigidBody* ball = nullptr;
        double lowest = 1e9, fastestUp = 0.0;
    };
    auto st = std::make_shared<State>();
    GameWorld* world = s.world.get();
    s.beforeFrame = [st, world](double tEnd) {
        if (st->ball || tEnd < kLaunch) return;
        st->ball = world->addBody(std::make_unique<btSphereShape>(btScalar(kRadius)),
                                  btScalar(kMass), at(0.013, 1.5, 0.007));
        st->ball->setLinearVelocity(btVector3(0, btScalar(-kSpeed), 0));
        st->ball->setActivationState(DISABLE_DEACTIVATION);
    };
    s.afterFrame = [st](double) {
        if (!st->ball) return;
        const btVector3 c = st->ball->getCenterOfMassPosition();
        if (std::abs(double(c.x())) < 0.5 && std::abs(double(c.z())) < 0.5)
            st->lowest = std::min(st->lowest, double(c.y()));
        st->fastestUp = std::max(st->fastestUp, double(st->ball->getLinearVelocity().y()));
    };
    bullet::BulletCloth* handle = s.handle.get();
    s.notes = [st, handle]() {
        if (!st->ball) return std::string("ball never launched");
        const double v = double(st->ball->getLinearVelocity().length());
        const double caughtAbove = 1.0 - 0.23 - kRadius;
        char buf[512];
        std::snprintf(
            buf, sizeof buf,
            "ball %.2f kg r %.0f mm at %.0f m/s: lowest centre over the net y %.3f m (caught: %s, "
            "above %.3f), thrown back up at %.2f m/s at most, speed at the end %.2f m/s; "
            "the cloth's impulse on bodies y %.3f N s",
            kMass, 1000.0 * kRadius, kSpeed, st->lowest, st->lowest > caughtAbove ? "yes" : "NO",
            caughtAbove, st->fastestUp, v, handle->totalStats().impulseOnBodies.y());
        return std::string(buf);
    };
    s.seconds = 3.0;
    return s;
}

/// A banner between two light posts: a 1 m sheet of 30 x 30 hanging from its top row, the
/// left half attached to one 2 kg post (0.2 x 0.2 x 1.2 m), the right half to another, each
/// post hanging from two ball joints on its top face; at t = 1 s a 20 kg box (0.3 m) is thrown
/// at it at `speed` (8 m/s: `banner`, 12 m/s: `banner_fast`), 0.4 m below its top row (it goes
/// through under the free hem). Notes: how far the posts moved from where they hang (they
/// swing on their joints) and the peak strain of the spring between them (held by the walk,
/// which moves the posts as their joints let them, and as a rope one Bullet step late:
/// Attachments::holdTethers). The frame columns' max is the hit.
inline GameScene makeBannerHitAt(double speed) {
    GameScene s;
    s.world = std::make_unique<GameWorld>();
    constexpr double kHalf = 0.1, kPostX = 0.6, kTop = 1.5, kBoxMass = 20.0, kThrow = 1.0;
    btRigidBody* posts[2];
    for (int p = 0; p < 2; ++p) {
        posts[p] = s.world->addBody(std::make_unique<btBoxShape>(
                                        btVector3(btScalar(kHalf), btScalar(kHalf), btScalar(0.6))),
                                    btScalar(2.0), at(p == 0 ? -kPostX : kPostX, kTop, 0.0));
        posts[p]->setActivationState(DISABLE_DEACTIVATION);
        for (float z : {-0.5f, 0.5f}) {
            const btVector3 local(0.0f, btScalar(kHalf), z);
            auto joint = std::make_unique<btPoint2PointConstraint>(*posts[p], local);
            joint->setPivotB(posts[p]->getWorldTransform() * local);
            s.world->addConstraint(std::move(joint));
        }
    }
    SheetSpec sheet;
    sheet.rows = sheet.cols = 30;
    sheet.spacing = 1.0 / 29.0;
    sheet.origin = Vec3(-0.5, kTop, 0.0); // hanging down (vAxis -y) in the plane z = 0
    addDefaultCloth(s, makeSheet(sheet));
    for (Index c = 0; c < sheet.cols; ++c)
        s.handle->attachHere(c, posts[c < sheet.cols / 2 ? 0 : 1]);
    struct State {
        btRigidBody* posts[2] = {nullptr, nullptr};
        Vec3 home[2];
        btRigidBody* box = nullptr;
        double postMoved = 0.0, between = 0.0;
        double others = 0.0; ///< every other spring's largest strain
    };
    auto st = std::make_shared<State>();
    for (int p = 0; p < 2; ++p) {
        st->posts[p] = posts[p];
        st->home[p] = Vec3(p == 0 ? -kPostX : kPostX, kTop, 0.0);
    }
    GameWorld* world = s.world.get();
    s.beforeFrame = [st, world, speed](double tEnd) {
        if (st->box || tEnd < kThrow) return;
        st->box = world->addBody(std::make_unique<btBoxShape>(btVector3(0.15f, 0.15f, 0.15f)),
                                 btScalar(kBoxMass), at(0.0, 1.0, 1.0));
        st->box->setLinearVelocity(btVector3(0, 2, btScalar(-speed)));
    };
    Cloth* cloth = s.cloth.get();
    const Index left = sheet.cols / 2 - 1, right = sheet.cols / 2;
    const double rest = sheet.spacing;
    s.afterFrame = [st, cloth, left, right, rest](double) {
        for (int p = 0; p < 2; ++p) {
            const Vec3 c = bullet::toVec(st->posts[p]->getCenterOfMassPosition());
            st->postMoved = std::max(st->postMoved, (c - st->home[p]).norm());
        }
        st->between =
            std::max(st->between,
                     (cloth->positions()[right] - cloth->positions()[left]).norm() / rest - 1.0);
        for (const Spring& sp : cloth->topology().springs()) {
            if ((sp.a == left && sp.b == right) || (sp.a == right && sp.b == left)) continue;
            const Vec3 d = cloth->positions()[sp.b] - cloth->positions()[sp.a];
            st->others = std::max(st->others, d.norm() / sp.restLength - 1.0);
        }
    };
    s.notes = [st, speed, cloth]() {
        double farthest = 0.0;
        for (const Vec3& x : cloth->positions())
            farthest = std::min(farthest, x.z());
        char buf[320];
        std::snprintf(buf, sizeof buf,
                      "posts 2 kg on joints, box %.0f kg at %.0f m/s: posts moved %.3f m at most; "
                      "the spring between them peaked at strain %.4f, every other spring at "
                      "%.4f; at the end the box's centre is at z %.2f m, the banner's farthest "
                      "particle at z %.2f m",
                      kBoxMass, speed, st->postMoved, st->between, st->others,
                      st->box ? double(st->box->getCenterOfMassPosition().z()) : 1.0, farthest);
        return std::string(buf);
    };
    s.seconds = 4.0;
    return s;
}
inline GameScene makeBanner() {
    return makeBannerHitAt(8.0);
}
/// 10. banner_fast: the banner with the box at 12 m/s (integration/README.md, "A banner hit
/// hard": from about 10 m/s the posts were thrown away until capped walks passed no pull).
inline GameScene makeBannerFast() {
    return makeBannerHitAt(12.0);
}

/// 11. flag_pole: the flag of scene 3 in the same gusts, its first column attached to a thin
/// dynamic pole (a 2 kg cylinder of radius 2 cm, 2 m tall) on a vertical hinge at its foot, so
/// that the wind turns the pole slowly. A pole thinner than the cloth's longest spring is swept
/// against the cloth's triangles in every cloth step (contact.continuous); the triangles held
/// on it turn with it and are not (a new user's review measured 5 times the cost of a static
/// pole when they were). Notes: the pole's largest turn rate and the triangle queries.
inline GameScene makeFlagPole() {
    GameScene s;
    s.world = std::make_unique<GameWorld>();
    btRigidBody* pole =
        s.world->addBody(std::make_unique<btCylinderShape>(btVector3(0.02f, 1.0f, 0.02f)),
                         btScalar(2.0), at(0.0, 1.0, 0.0));
    pole->setActivationState(DISABLE_DEACTIVATION);
    s.world->addConstraint(
        std::make_unique<btHingeConstraint>(*pole, btVector3(0, -1, 0), btVector3(0, 1, 0)));
    SheetSpec sheet;
    sheet.rows = 17;
    sheet.cols = 25;
    sheet.spacing = 0.05;
    sheet.origin = Vec3(0.03, 1.95, 0.0); // its first column 1 cm off the pole's surface
    addDefaultCloth(s, makeSheet(sheet), [](ClothSettings& c) { c.aero.airDensity = 1.2; });
    for (Index r = 0; r < sheet.rows; ++r)
        s.handle->attachHere(sheetIndex(sheet, r, 0), pole);
    Cloth* cloth = s.cloth.get();
    s.beforeFrame = [cloth](double t) { cloth->setWind(gustyWind(t)); };
    auto fastest = std::make_shared<double>(0.0);
    s.afterFrame = [pole, fastest](double) {
        *fastest = std::max(*fastest, double(pole->getAngularVelocity().length()));
    };
    const bullet::BulletCloth* handle = s.handle.get();
    s.notes = [fastest, handle]() {
        char buf[160];
        std::snprintf(buf, sizeof buf, "pole turned at up to %.2f rad/s; %zu triangle queries",
                      *fastest, handle->totalStats().triangleQueries);
        return std::string(buf);
    };
    s.seconds = 6.0;
    return s;
}

/// 13. cape_ragdoll: the cape of scenes 4-5 attached along the back of a ragdoll's torso (a 0.4 x
/// 0.6 x 0.2 m box of 20 kg; four 3 kg capsule limbs on cone-twist joints, a 5 kg ball head on
/// a ball joint; the parts joined do not collide), dropped on a static floor from 1.5 m; at 2 s
/// the torso is kicked (40, 60, 0) N s. The cape lies between torso, head and arms: the walk
/// does not keep the joints between bodies it moves, so the torso is an attachment body with
/// the reaction after the cloth's steps (integration/README.md, "A body in joints carries its
/// particles too"). Notes: impulses refused, the ragdoll's fastest part, where the torso ends.
inline GameScene makeCapeRagdoll() {
    GameScene s;
    s.world = std::make_unique<GameWorld>();
    s.world->addBody(std::make_unique<btStaticPlaneShape>(btVector3(0, 1, 0), btScalar(0)), 0,
                     at(0.0, 0.0, 0.0));
    constexpr double kY = 1.5;
    btRigidBody* torso = s.world->addBody(std::make_unique<btBoxShape>(btVector3(0.2f, 0.3f, 0.1f)),
                                          btScalar(20), at(0.0, kY, 0.0));
    std::vector<btRigidBody*> parts{torso};
    const double lx[4] = {-0.3, 0.3, -0.12, 0.12}, ly[4] = {0.2, 0.2, -0.3, -0.3};
    for (int k = 0; k < 4; ++k) {
        const bool leg = ly[k] < 0.0;
        btRigidBody* limb =
            s.world->addBody(std::make_unique<btCapsuleShape>(0.05f, 0.4f), btScalar(3),
                             at(lx[k], kY + ly[k] - (leg ? 0.3 : 0.0), 0.0));
        btTransform inTorso, inLimb;
        inTorso.setIdentity();
        inLimb.setIdentity();
        inTorso.setOrigin(btVector3(btScalar(lx[k]), btScalar(ly[k]), 0.0f));
        inLimb.setOrigin(btVector3(0.0f, leg ? 0.3f : 0.0f, 0.0f));
        auto joint = std::make_unique<btConeTwistConstraint>(*torso, *limb, inTorso, inLimb);
        joint->setLimit(0.8f, 0.8f, 0.5f);
        s.world->addConstraint(std::move(joint), false);
        parts.push_back(limb);
    }
    btRigidBody* head = s.world->addBody(std::make_unique<btSphereShape>(0.1f), btScalar(5),
                                         at(0.0, kY + 0.45, 0.0));
    s.world->addConstraint(std::make_unique<btPoint2PointConstraint>(*torso, *head,
                                                                     btVector3(0.0f, 0.32f, 0.0f),
                                                                     btVector3(0.0f, -0.13f, 0.0f)),
                           false);
    parts.push_back(head);
    SheetSpec sheet;
    sheet.rows = 19;
    sheet.cols = 13;
    sheet.spacing = 0.05;
    sheet.origin = Vec3(-0.3, kY + 0.28, -0.12); // along the torso's back, hanging down
    sheet.uAxis = Vec3::UnitX();
    sheet.vAxis = Vec3(0.0, -1.0, 0.0);
    addDefaultCloth(s, makeSheet(sheet));
    for (Index c = 0; c < sheet.cols; ++c)
        s.handle->attachHere(sheetIndex(sheet, 0, c), torso);
    auto fastest = std::make_shared<double>(0.0);
    s.beforeFrame = [torso](double tEnd) {
        if (tEnd > 2.0 && tEnd <= 2.0 + 1.5 * double(kFrame))
            torso->applyCentralImpulse(btVector3(40.0f, 60.0f, 0.0f));
    };
    s.afterFrame = [parts, fastest](double) {
        for (const btRigidBody* p : parts)
            *fastest = std::max(*fastest, double(p->getLinearVelocity().length()));
    };
    const bullet::BulletCloth* handle = s.handle.get();
    s.notes = [handle, fastest, torso]() {
        char buf[256];
        std::snprintf(buf, sizeof buf,
                      "ragdoll 40 kg (torso 20 kg), kicked at 2 s: %zu impulses refused, its "
                      "fastest part at %.2f m/s, the torso ends at (%.2f, %.2f, %.2f) m",
                      std::size_t(handle->totalStats().refusedBodyImpulses), *fastest,
                      double(torso->getCenterOfMassPosition().x()),
                      double(torso->getCenterOfMassPosition().y()),
                      double(torso->getCenterOfMassPosition().z()));
        return std::string(buf);
    };
    s.seconds = 5.0;
    return s;
}

/// 12. crate_net: the net of scene 1 (41 x 41, 1 m, 0.2 kg, pinned on all edges) and a 0.2 m
/// crate of 2.5 kg (a box, friction 0.5) dropped from 0.2 m above its middle at t = 0: a load
/// twelve times the net's weight, which the strain limiter carries nearly all of to the pins.
/// Bullet may put the crate to sleep. Notes: the crate's lowest centre, its largest turn rate
/// after the first 2 s (a box rocking on the net), its speed at the end, and whether Bullet has
/// put it to sleep.
inline GameScene makeCrateNet() {
    GameScene s = makeNet();
    constexpr double kMass = 2.5, kHalf = 0.1;
    btRigidBody* crate = s.world->addBody(
        std::make_unique<btBoxShape>(btVector3(btScalar(kHalf), btScalar(kHalf), btScalar(kHalf))),
        btScalar(kMass), at(0.013, 1.0 + 0.2 + kHalf, 0.007));
    crate->setFriction(0.5f);
    struct State {
        double lowest = 1e9, turnLate = 0.0;
    };
    auto st = std::make_shared<State>();
    s.afterFrame = [st, crate](double t) {
        st->lowest = std::min(st->lowest, double(crate->getCenterOfMassPosition().y()));
        if (t > 2.0)
            st->turnLate = std::max(st->turnLate, double(crate->getAngularVelocity().length()));
    };
    s.notes = [st, crate]() {
        char buf[256];
        std::snprintf(buf, sizeof buf,
                      "crate %.1f kg (a %.1f m box) dropped from 0.2 m: lowest centre y %.3f m, "
                      "turning at up to %.2f rad/s after 2 s, speed at the end %.3f m/s, %s",
                      kMass, 2.0 * kHalf, st->lowest, st->turnLate,
                      double(crate->getLinearVelocity().length()),
                      crate->isActive() ? "awake" : "asleep");
        return std::string(buf);
    };
    s.seconds = 8.0;
    return s;
}

/// 15. towel_tablecloth: a 1 m tablecloth (41 x 41, 0.025 m) dropped from 2 cm onto a static
/// 0.8 m table (a box, its top at y 0.8) and a 0.4 m towel (17 x 17, 0.025 m) dropped onto it
/// from 0.3 m above at t = 0: two cloths in one world that collide with each other
/// (BulletClothSettings::collideWithCloths, the default). The table's columns are the
/// tablecloth's; the frame's time includes the towel. Notes: the towel's lowest point above the
/// table's top (on the tablecloth: about two thicknesses, 2 cm; through it: one, 1 cm), its
/// particles over the table nearer its top than 1.5 cm (gone through the tablecloth), when it
/// fell asleep, and the contacts between the cloths.
inline GameScene makeTowelTablecloth() {
    GameScene s;
    s.world = std::make_unique<GameWorld>();
    s.world->addBody(std::make_unique<btBoxShape>(btVector3(0.4f, 0.4f, 0.4f)), 0.0f,
                     at(0.0, 0.4, 0.0));
    SheetSpec sheet;
    sheet.rows = 41;
    sheet.cols = 41;
    sheet.spacing = 0.025;
    sheet.origin = Vec3(-0.5, 0.82, -0.5);
    sheet.uAxis = Vec3::UnitX();
    sheet.vAxis = Vec3::UnitZ();
    addDefaultCloth(s, makeSheet(sheet));
    SheetSpec towelSheet = sheet;
    towelSheet.rows = 17;
    towelSheet.cols = 17;
    towelSheet.origin = Vec3(-0.1, 1.12, -0.15);
    auto towel =
        std::make_shared<Cloth>(ClothTopology::build(makeSheet(towelSheet)), ClothSettings{});
    s.others.push_back(towel);
    s.otherHandles.push_back(bullet::addCloth(s.world->world(), towel));
    struct State {
        double lowest = 1e9, asleepAt = -1.0;
        std::size_t through = 0;
    };
    auto st = std::make_shared<State>();
    s.afterFrame = [st, towel](double t) {
        if (!towel->isAsleep())
            st->asleepAt = -1.0;
        else if (st->asleepAt < 0.0)
            st->asleepAt = t;
        std::size_t through = 0;
        for (const Vec3& x : towel->positions()) {
            st->lowest = std::min(st->lowest, x.y() - 0.8);
            through += std::abs(x.x()) < 0.4 && std::abs(x.z()) < 0.4 && x.y() < 0.815;
        }
        st->through = std::max(st->through, through);
    };
    const bullet::BulletCloth* towelHandle = s.otherHandles.back().get();
    s.notes = [st, towelHandle]() {
        char buf[256];
        std::snprintf(buf, sizeof buf,
                      "towel 17 x 17 dropped from 0.3 m: lowest %.1f mm above the table's top, "
                      "%zu particles through the tablecloth at most, asleep %s, %zu contacts "
                      "between the cloths",
                      1e3 * st->lowest, st->through, timeOrNever(st->asleepAt).c_str(),
                      std::size_t(towelHandle->totalStats().clothContacts));
        return std::string(buf);
    };
    s.seconds = 6.0;
    return s;
}

/// 16. rock_drape and 17. boulder_drape: a 1 m sheet (41 x 41, 0.025 m) dropped from 0.3 m
/// above onto a static rock on the floor: a convex hull of 24 points on a 0.3 m sphere
/// (btConvexHullShape, Bullet's default margin), or a two-sphere boulder (btMultiSphereShape,
/// radii 0.25 and 0.2, centres 0.3 m apart). Notes: the nearest any particle came to the shape,
/// by Bullet's own signed distance (btGjkEpaSolver2, margin included; the contact thickness is
/// 1 cm), and when the sheet fell asleep.
inline GameScene makeDrapeOn(std::unique_ptr<btConvexShape> rock, double top) {
    GameScene s;
    s.world = std::make_unique<GameWorld>();
    s.world->addBody(std::make_unique<btStaticPlaneShape>(btVector3(0, 1, 0), btScalar(0)), 0.0f,
                     at(0.0, 0.0, 0.0));
    const btConvexShape* shape = rock.get();
    const btTransform pose = at(0.0, 0.3, 0.0);
    s.world->addBody(std::move(rock), 0.0f, pose);
    SheetSpec sheet;
    sheet.rows = 41;
    sheet.cols = 41;
    sheet.spacing = 0.025;
    sheet.origin = Vec3(-0.5, top + 0.3, -0.5);
    sheet.uAxis = Vec3::UnitX();
    sheet.vAxis = Vec3::UnitZ();
    addDefaultCloth(s, makeSheet(sheet));
    struct State {
        double closest = 1e9, asleepAt = -1.0;
    };
    auto st = std::make_shared<State>();
    const Cloth* cloth = s.cloth.get();
    s.afterFrame = [st, cloth, shape, pose](double t) {
        if (!cloth->isAsleep())
            st->asleepAt = -1.0;
        else if (st->asleepAt < 0.0)
            st->asleepAt = t;
        for (const Vec3& x : cloth->positions()) {
            btGjkEpaSolver2::sResults res;
            st->closest = std::min(st->closest, double(btGjkEpaSolver2::SignedDistance(
                                                    bullet::toBt(x), 0, shape, pose, res)));
        }
    };
    s.notes = [st]() {
        char buf[160];
        std::snprintf(buf, sizeof buf,
                      "nearest to the rock's surface %.1f mm (Bullet's signed distance), "
                      "asleep %s",
                      1e3 * st->closest, timeOrNever(st->asleepAt).c_str());
        return std::string(buf);
    };
    s.seconds = 8.0;
    return s;
}

inline GameScene makeRockDrape() {
    auto hull = std::make_unique<btConvexHullShape>();
    for (int i = 0; i < 24; ++i) {
        const double a = i * 2.399963, y = 1.0 - 2.0 * (i + 0.5) / 24.0;
        const double r = std::sqrt(1.0 - y * y);
        hull->addPoint(btVector3(btScalar(0.3 * r * std::cos(a)), btScalar(0.3 * y),
                                 btScalar(0.3 * r * std::sin(a))),
                       false);
    }
    hull->recalcLocalAabb();
    return makeDrapeOn(std::move(hull), 0.6);
}

inline GameScene makeBoulderDrape() {
    const btVector3 centres[2] = {btVector3(-0.15f, 0.0f, 0.0f), btVector3(0.15f, 0.0f, 0.0f)};
    const btScalar radii[2] = {0.25f, 0.2f};
    return makeDrapeOn(std::make_unique<btMultiSphereShape>(centres, radii, 2), 0.55);
}

/// 18. cape_skirt: a kinematic capsule character (r 0.2 m, 1.4 m tall) wearing a skirt (a cone
/// of 64 x 17 particles, 0.25 m round at the waist to 0.36 m at the hem, attached by its waist
/// row) and a cape (21 x 33, 0.025 m, attached by its top row, hanging over the skirt's back):
/// two cloths that collide with each other. It stands 1 s, then walks at 1.5 m/s and turns 90
/// degrees in 0.25 s every 2.5 s. The table's columns are the cape's; the frame's time
/// includes the skirt. Notes: the skirt's peak strain, the sub-steps either ended over the
/// strain bound (ContactStats::boundBroken) and the contacts between the cloths.
inline GameScene makeCapeSkirt() {
    GameScene s;
    s.world = std::make_unique<GameWorld>();
    s.world->addBody(std::make_unique<btStaticPlaneShape>(btVector3(0, 1, 0), btScalar(0)), 0.0f,
                     at(0.0, 0.0, 0.0));
    btRigidBody* body = s.world->addBody(std::make_unique<btCapsuleShape>(btScalar(0.2), 1.0f),
                                         0.0f, at(0.0, 1.0, 0.0), true);
    constexpr int kAround = 64, kRows = 17;
    constexpr double kWaist = 0.95, kHem = 0.45, kWaistR = 0.25, kHemR = 0.36;
    TriangleMesh skirtMesh;
    for (int r = 0; r < kRows; ++r) {
        const double f = r / double(kRows - 1), y = kWaist - (kWaist - kHem) * f;
        const double rad = kWaistR + (kHemR - kWaistR) * f;
        for (int a = 0; a < kAround; ++a) {
            const double th = 2.0 * M_PI * a / kAround;
            skirtMesh.vertices.push_back(Vec3(rad * std::sin(th), y, rad * std::cos(th)));
        }
    }
    for (int r = 0; r + 1 < kRows; ++r)
        for (int a = 0; a < kAround; ++a) {
            const Index i = Index(r * kAround + a), j = Index(r * kAround + (a + 1) % kAround);
            skirtMesh.triangles.push_back({i, i + kAround, j});
            skirtMesh.triangles.push_back({j, i + kAround, j + kAround});
        }
    auto skirt = std::make_shared<Cloth>(ClothTopology::build(skirtMesh), ClothSettings{});
    s.others.push_back(skirt);
    s.otherHandles.push_back(bullet::addCloth(s.world->world(), skirt));
    for (int a = 0; a < kAround; ++a)
        s.otherHandles.back()->attachHere(Index(a), body);
    SheetSpec sheet;
    sheet.rows = 33;
    sheet.cols = 21;
    sheet.spacing = 0.025;
    sheet.origin = Vec3(-0.25, 1.45, -0.32);
    sheet.uAxis = Vec3::UnitX();
    sheet.vAxis = Vec3(0.0, -0.8, -0.18).normalized();
    addDefaultCloth(s, makeSheet(sheet));
    for (Index c = 0; c < sheet.cols; ++c)
        s.handle->attachHere(c, body);
    struct State {
        double heading = 0.0, x = 0.0, z = 0.0, skirtStrain = 0.0;
    };
    auto st = std::make_shared<State>();
    s.beforeFrame = [st, body](double tEnd) {
        const double t = tEnd - kFrame, phase = std::fmod(t, 2.5);
        if (phase > 2.0 && phase <= 2.25) st->heading += (M_PI / 2.0) / 0.25 * kFrame;
        const double v = t < 1.0 ? 0.0 : 1.5;
        st->x += v * std::sin(st->heading) * kFrame;
        st->z += v * std::cos(st->heading) * kFrame;
        btTransform pose = at(st->x, 1.0, st->z);
        pose.setRotation(btQuaternion(btVector3(0, 1, 0), btScalar(st->heading)));
        moveKinematic(body, pose);
    };
    s.afterFrame = [st, skirt](double) {
        st->skirtStrain = std::max(st->skirtStrain, skirt->maxStrain());
    };
    const bullet::BulletCloth* capeHandle = s.handle.get();
    const bullet::BulletCloth* skirtHandle = s.otherHandles.back().get();
    s.notes = [st, capeHandle, skirtHandle]() {
        char buf[200];
        std::snprintf(buf, sizeof buf,
                      "skirt peak strain %.4f, %zu sub-steps over the bound (cape and skirt); %zu "
                      "contacts between the cloths",
                      st->skirtStrain,
                      std::size_t(capeHandle->totalStats().boundBroken +
                                  skirtHandle->totalStats().boundBroken),
                      std::size_t(capeHandle->totalStats().clothContacts));
        return std::string(buf);
    };
    s.seconds = 8.0;
    return s;
}

/// The scenes, in the order they run.
struct SceneEntry {
    const char* name;
    GameScene (*make)();
};
inline const std::vector<SceneEntry>& allScenes() {
    static const std::vector<SceneEntry> scenes = {
        {"net", &makeNet},
        {"curtain_walk", &makeCurtainWalk},
        {"flag", &makeFlag},
        {"cape_kinematic", &makeCapeKinematic},
        {"cape_dynamic", &makeCapeDynamic},
        {"cape_light", &makeCapeLight},
        {"stack", &makeStack},
        {"garment", &makeGarment},
        {"net_ball", &makeNetBall},
        {"banner", &makeBanner},
        {"banner_fast", &makeBannerFast},
        {"flag_pole", &makeFlagPole},
        {"crate_net", &makeCrateNet},
        {"cape_ragdoll", &makeCapeRagdoll},
        {"towel_tablecloth", &makeTowelTablecloth},
        {"rock_drape", &makeRockDrape},
        {"boulder_drape", &makeBoulderDrape},
        {"cape_skirt", &makeCapeSkirt},
        {"cape_snap", &makeCapeSnap},
        {"curtain_pick", &makeCurtainPick},
    };
    return scenes;
}

} // namespace drape::games
