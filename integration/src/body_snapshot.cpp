// Body snapshots (see body_snapshot.hpp).
#include "body_snapshot.hpp"

#include "shape_queries.hpp"
#include "validate.hpp"

#include "drape/error.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>

namespace drape::bullet::detail {
namespace {
/// The plane and box data derived from the pose.
void derivePoseData(BodySnapshot& b) {
    b.com = b.pose.t;
    if (b.plane) {
        const auto* ps = static_cast<const btStaticPlaneShape*>(b.object->getCollisionShape());
        const Vec3 nLocal = toVec(ps->getPlaneNormal()).normalized(); // as shape_queries does
        b.planeNormal = b.pose.R * nLocal;
        b.planeOffset = b.planeNormal.dot(b.pose.t) + double(ps->getPlaneConstant());
        b.planeScale = std::abs(b.planeOffset) + b.pose.t.cwiseAbs().sum();
    }
    if (b.box) {
        for (int k = 0; k < 3; ++k) {
            for (int side = 0; side < 2; ++side) {
                Vec3 n = Vec3::Zero();
                n[k] = side == 0 ? 1.0 : -1.0;
                b.boxFaceNormal[2 * k + side] = (b.pose.R * n).normalized();
            }
        }
    }
}
} // namespace

void BodySnapshot::startSweep(double dt) {
    previous = end;
    sweeping_ = !plane && !still;
    if (!sweeping_) return; // pose == end == previous
    pose = poseBefore(end, v, w, dt);
    previous = pose;
    derivePoseData(*this);
}

void BodySnapshot::advance(double h) {
    if (!sweeps()) return;
    previous = pose;
    pose = poseBefore(pose, -v, -w, h); // h after it, at the velocities it has now
    derivePoseData(*this);
}

void BodySnapshot::displace(const Vec3& shift, const Vec3& turn) {
    if (!dynamicBody) return;
    pose.t += shift;
    const double angle = turn.norm();
    if (angle > 0.0) pose.R = Eigen::AngleAxisd(angle, turn / angle).toRotationMatrix() * pose.R;
    derivePoseData(*this);
    aabbMin += shift.cwiseMin(Vec3::Zero());
    aabbMax += shift.cwiseMax(Vec3::Zero());
    moved_ = true;
}

void limitSpin(BodySnapshot& b, double gyration) {
    if (!b.dynamicBody || !(b.invMass > 0.0) || !(gyration > 0.0)) return;
    const double most = b.invMass / (gyration * gyration); // 1 / (m gyration^2)
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(b.invInertia);
    if (eig.info() != Eigen::Success || !(eig.eigenvalues().maxCoeff() > most)) return;
    // Only an elongated body's light axis: about it the body is at least 4 times lighter than
    // about its heaviest axis (a ball's contact normals pass through its centre: nothing to
    // add up).
    const double floorLight = 4.0 * eig.eigenvalues().minCoeff();
    Vec3 kept, filter;
    bool limited = false;
    for (int k = 0; k < 3; ++k) {
        const double l = eig.eigenvalues()[k];
        const bool cap = l > most && l > floorLight;
        kept[k] = cap ? most : l;
        filter[k] = cap ? most / l : 1.0;
        limited = limited || cap;
    }
    if (!limited) return;
    const Eigen::Matrix3d& q = eig.eigenvectors();
    b.invInertia = q * kept.asDiagonal() * q.transpose();
    b.spinFilter = q * filter.asDiagonal() * q.transpose();
}

void markSupported(btDispatcher& dispatcher, std::vector<BodySnapshot>& bodies) {
    bool anyDynamic = false;
    for (const BodySnapshot& b : bodies)
        anyDynamic = anyDynamic || b.dynamicBody;
    if (!anyDynamic) return;
    // The contact graph of Bullet's manifolds with points between bodies with contact response
    // (a ghost, such as a cloth's proxy, or a trigger holds nothing). A dynamic body is
    // supported when a chain of such contacts through dynamic bodies reaches a static or
    // kinematic one: only then does Bullet's solver hold it in place against the cloth. Bodies
    // that rest only on each other (items dropped in a pile on a net) are free together: the
    // cloth is what holds them, so they give way in the walk as free bodies do.
    // Union-find over the dynamic bodies in contact; a group touching the ground is supported.
    std::vector<const btCollisionObject*> nodes;
    std::vector<std::pair<const btCollisionObject*, const btCollisionObject*>> links;
    for (int k = 0; k < dispatcher.getNumManifolds(); ++k) {
        const btPersistentManifold* m = dispatcher.getManifoldByIndexInternal(k);
        if (m->getNumContacts() == 0) continue;
        const btCollisionObject* a = m->getBody0();
        const btCollisionObject* b = m->getBody1();
        if (!a->hasContactResponse() || !b->hasContactResponse()) continue;
        links.emplace_back(a, b);
        for (const btCollisionObject* o : {a, b})
            if (!o->isStaticOrKinematicObject()) nodes.push_back(o);
    }
    std::sort(nodes.begin(), nodes.end());
    nodes.erase(std::unique(nodes.begin(), nodes.end()), nodes.end());
    auto index = [&](const btCollisionObject* o) -> std::ptrdiff_t {
        const auto it = std::lower_bound(nodes.begin(), nodes.end(), o);
        return it != nodes.end() && *it == o ? it - nodes.begin() : -1;
    };
    std::vector<std::size_t> parent(nodes.size());
    for (std::size_t i = 0; i < parent.size(); ++i)
        parent[i] = i;
    auto root = [&](std::size_t i) {
        while (parent[i] != i)
            i = parent[i] = parent[parent[i]];
        return i;
    };
    std::vector<unsigned char> grounded(nodes.size(), 0);
    for (const auto& l : links) {
        const std::ptrdiff_t a = index(l.first), b = index(l.second);
        if (a >= 0 && b >= 0)
            parent[root(std::size_t(a))] = root(std::size_t(b));
        else if (a >= 0 || b >= 0) // the other end is static or kinematic
            grounded[std::size_t(a >= 0 ? a : b)] = 1;
    }
    for (std::size_t i = 0; i < nodes.size(); ++i)
        if (grounded[i]) grounded[root(i)] = 1;
    for (BodySnapshot& b : bodies) {
        if (!b.dynamicBody) continue;
        const std::ptrdiff_t i = index(b.object);
        b.supported = i >= 0 && grounded[root(std::size_t(i))] != 0;
        if (!b.supported) continue;
        const Vec3 g = toVec(b.dynamicBody->getGravity());
        b.down = g.norm() > 0.0 ? Vec3(g.normalized()) : Vec3::Zero();
        b.supportedDownSpeed = std::max(0.0, b.v.dot(b.down));
    }
}

namespace {
/// Grows b's box over the way it came in the sub-step of dt [s] at its velocities.
void growOverWay(BodySnapshot& b, double dt) {
    const Vec3 back = -dt * b.v;
    const double turn = b.w.norm() * dt * 0.5 * (b.aabbMax - b.aabbMin).norm();
    b.aabbMin = b.aabbMin.cwiseMin(b.aabbMin + back).array() - turn;
    b.aabbMax = b.aabbMax.cwiseMax(b.aabbMax + back).array() + turn;
}
} // namespace

bool snapshotBody(const btCollisionObject* obj, double reach, double frictionScale, BodySnapshot& b,
                  double dt, const Pose* at) {
    const int type = obj->getInternalType();
    if (type != btCollisionObject::CO_RIGID_BODY &&
        type != btCollisionObject::CO_COLLISION_OBJECT && !isCharacter(obj))
        return false; // other ghosts (other cloths' proxies, triggers), soft bodies, multibodies
    if (!obj->hasContactResponse() || !obj->getCollisionShape()) return false;
    b = BodySnapshot{};
    b.object = obj;
    const btTransform placed = at ? toBtTransform(*at) : obj->getWorldTransform();
    b.pose = at ? *at : toPose(placed);
    b.com = b.pose.t;
    const double mu = double(obj->getFriction());
    if (!(std::isfinite(mu) && mu >= 0.0)) { // (the message is built only then: every step)
        throw Error(ErrorCode::InvalidArgument,
                    std::string("a body the cloth may touch (") +
                        obj->getCollisionShape()->getName() + ") has friction " + num(mu) +
                        ": Coulomb's coefficient (btCollisionObject::setFriction) must be >= 0 "
                        "and finite");
    }
    b.friction = mu * frictionScale;
    const btTransform& tr = placed;
    bool finite = toVec(tr.getOrigin()).allFinite() && toMat(tr.getBasis()).allFinite();
    const btRigidBody* body = btRigidBody::upcast(obj);
    if (body)
        finite = finite && toVec(body->getLinearVelocity()).allFinite() &&
                 toVec(body->getAngularVelocity()).allFinite();
    if (!finite) { // (the message is built only then: every step)
        throw Error(ErrorCode::NonFinite,
                    std::string("a body the cloth may touch (") +
                        obj->getCollisionShape()->getName() +
                        (body ? ") has a position, orientation or velocity" : ") has a pose") +
                        " that is not finite; fix or remove the body (the cloth keeps its state "
                        "from before the step)");
    }
    btVector3 mn, mx;
    shapeAabb(obj->getCollisionShape(), placed, mn, mx);
    b.aabbMin = toVec(mn).array() - reach;
    b.aabbMax = toVec(mx).array() + reach;
    b.plane = obj->getCollisionShape()->getShapeType() == STATIC_PLANE_PROXYTYPE;
    if (obj->getCollisionShape()->getShapeType() == BOX_SHAPE_PROXYTYPE) {
        const auto* bs = static_cast<const btBoxShape*>(obj->getCollisionShape());
        b.box = true;
        b.boxHalf = toVec(bs->getHalfExtentsWithMargin());
    }
    derivePoseData(b);
    b.end = b.pose;
    b.previous = b.pose;
    if (const btRigidBody* rb = btRigidBody::upcast(obj)) {
        b.v = toVec(rb->getLinearVelocity());
        b.w = toVec(rb->getAngularVelocity());
        b.still = b.v == Vec3::Zero() && b.w == Vec3::Zero();
        if (!rb->isStaticOrKinematicObject() && rb->getInvMass() > 0.0f) {
            b.dynamicBody = const_cast<btRigidBody*>(rb); // impulses are applied after the step
            b.invMass = double(rb->getInvMass());
            b.invInertia = toMat(rb->getInvInertiaTensorWorld());
        }
        // It moved there during the sub-step at these velocities: the cloth's steps see it on
        // its way (startSweep), and its box covers the way.
        if (!b.plane && !b.still && dt > 0.0) growOverWay(b, dt);
    }
    return true;
}

bool isCharacter(const btCollisionObject* obj) {
    return obj->getInternalType() == btCollisionObject::CO_GHOST_OBJECT &&
           (obj->getCollisionFlags() & btCollisionObject::CF_CHARACTER_OBJECT) != 0;
}

void moveCharacter(BodySnapshot& b, const Pose& before, double dt) {
    if (!(dt > 0.0)) return;
    b.v = (b.pose.t - before.t) / dt;
    const Eigen::AngleAxisd turn(Eigen::Matrix3d(b.pose.R * before.R.transpose()));
    b.w = turn.angle() > 0.0 ? Vec3(turn.angle() / dt * turn.axis()) : Vec3::Zero();
    b.still = b.v == Vec3::Zero() && b.w == Vec3::Zero();
    if (!b.still) growOverWay(b, dt);
}

bool holdIfJumped(BodySnapshot& b, double dt, double speed, double turn, double reach) {
    const btRigidBody* rb = btRigidBody::upcast(b.object);
    const bool kinematic = rb ? rb->isKinematicObject() : isCharacter(b.object);
    if (!kinematic || b.still || b.plane || !(dt > 0.0)) return false;
    btVector3 centre;
    btScalar radius = 0;
    b.object->getCollisionShape()->getBoundingSphere(centre, radius);
    const double fastest = b.v.norm() + b.w.norm() * double(centre.length() + radius);
    const bool jumped = (speed > 0.0 && fastest > speed) || (turn > 0.0 && b.w.norm() * dt > turn);
    if (!jumped) return false;
    b.v.setZero();
    b.w.setZero();
    b.still = true;
    btVector3 mn, mx;
    shapeAabb(b.object->getCollisionShape(), toBtTransform(b.pose), mn, mx);
    b.aabbMin = toVec(mn).array() - reach;
    b.aabbMax = toVec(mx).array() + reach;
    return true;
}

bool BodySnapshot::applyAccumulatedImpulses(double clothSpeed, double floorSpeed,
                                            double clothWeight) {
    refused = false;
    if (!dynamicBody) return false;
    if (linearImpulse.squaredNorm() == 0.0 && angularImpulse.squaredNorm() == 0.0) return false;
    btRigidBody* rb = dynamicBody;
    // Nothing that is not finite, in Bullet's own precision, reaches Bullet (it would spread
    // through its solver): the impulses, the pose, and the velocities they give.
    const auto fits = [](const auto& m) {
        return m.allFinite() &&
               m.cwiseAbs().maxCoeff() < double(std::numeric_limits<btScalar>::max());
    };
    const Vec3 v0 = toVec(rb->getLinearVelocity()), w0 = toVec(rb->getAngularVelocity());
    const Vec3 newV = v0 + invMass * linearImpulse;
    const Vec3 newW = w0 + invInertia * angularImpulse;
    if (!(fits(linearImpulse) && fits(angularImpulse) && fits(pose.t) && fits(pose.R) &&
          fits(newV) && fits(newW))) {
        throw Error(ErrorCode::SimulationFailure,
                    std::string("the cloth's impulse on a dynamic body (") +
                        rb->getCollisionShape()->getName() +
                        ") is not finite; the body keeps its state from before the step");
    }
    // No cloth throws a body far faster than anything in the contact moved (see the header).
    btVector3 centre;
    btScalar radius = 0;
    rb->getCollisionShape()->getBoundingSphere(centre, radius);
    const double r = double(radius) + double(centre.length());
    const double before = std::max({v0.norm() + w0.norm() * r, clothSpeed, floorSpeed});
    // A supported body also takes the cloth's weight resting on it, and a quarter more (its
    // sway): its supports hold it. (Not twice: a 0.2 kg box tipped over under a 20 kg cloth
    // and given 25 m/s into the floor in one step went through it.)
    const double weightSpeed = supported ? invMass * clothWeight : 0.0;
    const double bound = std::max(kRefusedSpeedFactor * before, kWeightShare * weightSpeed);
    if (newV.norm() + newW.norm() * r > bound) {
        refused = true;
        return false;
    }
    const bool pushedActive = rb->isActive();
    // A sleeping body is not woken by nudges below its sleeping threshold.
    const double dv = linearImpulse.norm() * invMass;
    const double threshold = double(rb->getLinearSleepingThreshold());
    if (!rb->isActive() && dv < threshold && contactSpeed < threshold) return pushedActive;
    rb->applyCentralImpulse(toBt(linearImpulse));
    rb->applyTorqueImpulse(toBt(spinFilter * angularImpulse)); // (limitSpin)
    // Where the cloth's sub-steps took it (stopped on the way, pushed back out).
    if (moved_ && (!supported || liftedOut_)) rb->setCenterOfMassTransform(toBtTransform(pose));
    // Only a sleeping body is woken: activate() on an awake one would restart its
    // deactivation time, and a body the cloth rests on could never fall asleep. An awake body
    // that the cloth's impulse leaves below its sleeping thresholds sleeps as Bullet decides.
    if (!pushedActive) rb->activate();
    return pushedActive;
}

namespace {
/// A number that changes when a compound shape's children are added, removed, replaced or
/// moved (btCompoundShape's update revision, which updateChildTransform leaves alone, and each
/// child's shape and transform), at any depth; 0 for other shapes.
std::uint64_t shapeRevision(const btCollisionShape* shape) {
    if (!shape || shape->getShapeType() != COMPOUND_SHAPE_PROXYTYPE) return 0;
    const auto* compound = static_cast<const btCompoundShape*>(shape);
    std::uint64_t r = std::uint64_t(std::uint32_t(compound->getUpdateRevision())) + 1;
    const auto mix = [&r](std::uint64_t v) { r = (r ^ v) * 0x100000001b3ull; }; // FNV-1a step
    for (int c = 0; c < compound->getNumChildShapes(); ++c) {
        const btCollisionShape* child = compound->getChildShape(c);
        mix(reinterpret_cast<std::uintptr_t>(child));
        const btTransform& t = compound->getChildTransform(c);
        btScalar values[12];
        for (int k = 0; k < 3; ++k) {
            values[k] = t.getOrigin()[k];
            for (int j = 0; j < 3; ++j)
                values[3 + 3 * k + j] = t.getBasis()[k][j];
        }
        for (const btScalar v : values) {
            std::uint64_t bits = 0;
            std::memcpy(&bits, &v, sizeof v);
            mix(bits);
        }
        mix(shapeRevision(child));
    }
    return r;
}
} // namespace

bool BodyPoses::changed(const std::vector<BodySnapshot>& bodies, double tol, double dt,
                        const std::vector<Vec3>& x, double spring) const {
    const auto holdsParticle = [&x, spring](const Vec3& boxLo, const Vec3& boxHi) {
        const Vec3 lo = boxLo.array() - spring, hi = boxHi.array() + spring;
        for (const Vec3& p : x)
            if ((p.array() >= lo.array()).all() && (p.array() <= hi.array()).all()) return true;
        return false;
    };
    for (const Last& was : last_) { // gone from the candidates
        const bool gone = std::none_of(bodies.begin(), bodies.end(), [&](const BodySnapshot& b) {
            return b.object == was.object;
        });
        if (gone && holdsParticle(was.lo, was.hi)) return true;
    }
    for (const BodySnapshot& b : bodies) {
        const auto was = std::find_if(last_.begin(), last_.end(),
                                      [&](const Last& p) { return p.object == b.object; });
        if (was == last_.end()) { // a new candidate
            if (holdsParticle(b.aabbMin, b.aabbMax)) return true;
            continue;
        }
        const btCollisionShape* shape = b.object->getCollisionShape();
        bool moved = was->shape != shape || was->friction != b.friction ||
                     was->revision != shapeRevision(shape);
        // A shape grown or shrunk in place (a static box's setLocalScaling under a sleeping
        // cloth) moves its surface as motion would.
        const Vec3 grown = b.aabbMax - b.aabbMin - was->extent; // (a plane's: 0)
        moved = moved || (grown.allFinite() && grown.cwiseAbs().maxCoeff() > 2.0 * tol * dt);
        const Pose& pose = was->pose;
        // Turning is measured at the body's extent (its AABB's half diagonal; an infinite
        // plane turns only when its pose changes at all).
        const double radius = 0.5 * (b.aabbMax - b.aabbMin).norm();
        const double turn = (b.pose.R - pose.R).cwiseAbs().maxCoeff();
        moved = moved || (b.pose.t - pose.t).norm() > tol * dt ||
                (turn > 0.0 && !(turn * radius <= tol * dt)) || b.v.norm() > tol ||
                (b.w.norm() > 0.0 && !(b.w.norm() * radius <= tol));
        if (moved && (holdsParticle(b.aabbMin, b.aabbMax) || holdsParticle(was->lo, was->hi)))
            return true;
    }
    return false;
}

void BodyPoses::record(const std::vector<BodySnapshot>& bodies) {
    last_.resize(bodies.size());
    for (std::size_t k = 0; k < bodies.size(); ++k)
        last_[k] = {bodies[k].object,
                    bodies[k].object->getCollisionShape(),
                    shapeRevision(bodies[k].object->getCollisionShape()),
                    bodies[k].pose,
                    bodies[k].aabbMax - bodies[k].aabbMin,
                    bodies[k].friction,
                    bodies[k].aabbMin,
                    bodies[k].aabbMax};
}

namespace {
using Row6 = Eigen::Matrix<double, 6, 1>;

/// Bullet's rows of joint c (getInfo1 and getInfo2 at the step dt [s]) over `body`'s twist
/// (mine) and over the other end's (other), leaving out rows a bounded impulse drives (a motor,
/// friction: they give way). False when the joint gives no rows this way (an old-style
/// constraint) or `body` is in neither end.
bool jointRowsOf(btTypedConstraint& c, const btRigidBody& body, double dt, std::vector<Row6>& mine,
                 std::vector<Row6>& other) {
    const bool isA = &c.getRigidBodyA() == &body, isB = &c.getRigidBodyB() == &body;
    if (isA == isB || !(dt > 0.0)) return false; // in neither end, or a joint to itself
    btTypedConstraint::btConstraintInfo1 info1;
    info1.m_numConstraintRows = 0;
    info1.nub = 0;
    c.getInfo1(&info1);
    const int n = info1.m_numConstraintRows;
    if (n <= 0) return false;
    // One row of Bullet's solver: the four Jacobian blocks, then the right-hand side, the
    // constraint force mixing and the impulse's bounds (getInfo2 strides every array by
    // rowskip, as the solver's own rows do).
    constexpr int kJ1Linear = 0, kJ1Angular = 4, kJ2Linear = 8, kJ2Angular = 12, kError = 16,
                  kCfm = 17, kLower = 18, kUpper = 19, kSkip = 20;
    std::vector<btScalar> buf(std::size_t(n) * kSkip, btScalar(0));
    for (int r = 0; r < n; ++r) {
        buf[std::size_t(r * kSkip + kLower)] = -SIMD_INFINITY;
        buf[std::size_t(r * kSkip + kUpper)] = SIMD_INFINITY;
    }
    btTypedConstraint::btConstraintInfo2 info2;
    info2.fps = btScalar(1.0 / dt);
    info2.erp = btScalar(0.2);
    info2.m_J1linearAxis = buf.data() + kJ1Linear;
    info2.m_J1angularAxis = buf.data() + kJ1Angular;
    info2.m_J2linearAxis = buf.data() + kJ2Linear;
    info2.m_J2angularAxis = buf.data() + kJ2Angular;
    info2.rowskip = kSkip;
    info2.m_constraintError = buf.data() + kError;
    info2.cfm = buf.data() + kCfm;
    info2.m_lowerLimit = buf.data() + kLower;
    info2.m_upperLimit = buf.data() + kUpper;
    info2.m_numIterations = 10;
    info2.m_damping = btScalar(1);
    c.getInfo2(&info2);
    const int myLinear = isA ? kJ1Linear : kJ2Linear, myAngular = isA ? kJ1Angular : kJ2Angular;
    const int itsLinear = isA ? kJ2Linear : kJ1Linear, itsAngular = isA ? kJ2Angular : kJ1Angular;
    const auto rowAt = [](const btScalar* row, int linear, int angular) {
        Row6 J;
        J << double(row[linear]), double(row[linear + 1]), double(row[linear + 2]),
            double(row[angular]), double(row[angular + 1]), double(row[angular + 2]);
        return J;
    };
    for (int r = 0; r < n; ++r) {
        const btScalar* row = buf.data() + std::size_t(r * kSkip);
        const bool bounded = row[kLower] > -SIMD_INFINITY && row[kUpper] < SIMD_INFINITY;
        if (bounded) continue; // a motor or friction: gives way beyond its impulse
        const Row6 J = rowAt(row, myLinear, myAngular), Jo = rowAt(row, itsLinear, itsAngular);
        if (!J.allFinite() || !Jo.allFinite()) return false;
        if (J.squaredNorm() == 0.0) continue;
        mine.push_back(J);
        other.push_back(Jo);
    }
    return true;
}

/// A dynamic body's own 6 x 6 inverse mass (world frame, with its linear and angular factors).
Eigen::Matrix<double, 6, 6> inverseMassOf(const btRigidBody& rb) {
    Eigen::Matrix<double, 6, 6> W = Eigen::Matrix<double, 6, 6>::Zero();
    const Vec3 lf = toVec(rb.getLinearFactor()), af = toVec(rb.getAngularFactor());
    W.topLeftCorner<3, 3>() = (double(rb.getInvMass()) * lf).asDiagonal();
    Eigen::Matrix3d I;
    const btMatrix3x3& b = rb.getInvInertiaTensorWorld();
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            I(i, j) = double(b[i][j]);
    W.bottomRightCorner<3, 3>() = af.asDiagonal() * I * af.asDiagonal();
    return W;
}
} // namespace

bool jointRows(btDynamicsWorld& world, const btRigidBody& body, double dt,
               const std::vector<const btCollisionObject*>& inWalk, JointRows& out) {
    out.clear();
    // Per row: the joint's other body (null: static, kinematic or the world) and its row there.
    std::vector<const btRigidBody*> otherOf;
    std::vector<Row6> mine, other, scratchMine, scratchOther;
    for (int k = 0; k < world.getNumConstraints(); ++k) {
        btTypedConstraint* c = world.getConstraint(k);
        if (!c || !c->isEnabled()) continue;
        if (&c->getRigidBodyA() != &body && &c->getRigidBodyB() != &body) continue;
        if (!jointRowsOf(*c, body, dt, mine, other)) return false;
        const btRigidBody* o =
            &c->getRigidBodyA() == &body ? &c->getRigidBodyB() : &c->getRigidBodyA();
        if (o->isStaticOrKinematicObject() || !(o->getInvMass() > 0.0f)) o = nullptr;
        if (o && std::binary_search(inWalk.begin(), inWalk.end(),
                                    static_cast<const btCollisionObject*>(o)))
            return false;
        otherOf.resize(mine.size(), o);
    }
    if (mine.empty()) return true;
    if (std::none_of(otherOf.begin(), otherOf.end(), [](const btRigidBody* o) { return o; })) {
        // Every other end held still: the rows' span is what counts. Rows that repeat one
        // another (two ball joints on one axis: six rows of rank five) are reduced to an
        // orthonormal basis of it, so that constrainToJoints solves a regular system.
        Eigen::Matrix<double, Eigen::Dynamic, 6> J(Eigen::Index(mine.size()), 6);
        for (std::size_t r = 0; r < mine.size(); ++r)
            J.row(Eigen::Index(r)) = mine[r].transpose();
        const Eigen::JacobiSVD<Eigen::Matrix<double, Eigen::Dynamic, 6>> svd(J,
                                                                             Eigen::ComputeFullV);
        const auto& sv = svd.singularValues();
        for (Eigen::Index r = 0; r < sv.size(); ++r)
            if (sv[r] > 1e-9 * sv[0]) out.rows.push_back(svd.matrixV().col(r));
        return true;
    }
    out.rows = mine;
    const auto k = Eigen::Index(mine.size());
    out.give = Eigen::MatrixXd::Zero(k, k);
    // Each dynamic other body gives way as its own other joints let it (those held still: one
    // level, exact for a chain of two): G = J_o W_o' J_o^T over the rows it shares.
    std::vector<const btRigidBody*> done;
    for (Eigen::Index r = 0; r < k; ++r) {
        const btRigidBody* o = otherOf[std::size_t(r)];
        if (!o || std::find(done.begin(), done.end(), o) != done.end()) continue;
        done.push_back(o);
        CarrierMatrices its;
        its.mobility = inverseMassOf(*o);
        its.share.setIdentity();
        JointRows held;
        for (int j = 0; j < world.getNumConstraints(); ++j) {
            btTypedConstraint* c = world.getConstraint(j);
            if (!c || !c->isEnabled()) continue;
            if (&c->getRigidBodyA() != o && &c->getRigidBodyB() != o) continue;
            if (&c->getRigidBodyA() == &body || &c->getRigidBodyB() == &body) continue;
            scratchMine.clear();
            scratchOther.clear();
            if (jointRowsOf(*c, *o, dt, scratchMine, scratchOther))
                held.rows.insert(held.rows.end(), scratchMine.begin(), scratchMine.end());
        }
        constrainToJoints(its, held);
        for (Eigen::Index p = 0; p < k; ++p) {
            if (otherOf[std::size_t(p)] != o) continue;
            for (Eigen::Index q = 0; q < k; ++q)
                if (otherOf[std::size_t(q)] == o)
                    out.give(p, q) =
                        other[std::size_t(p)].dot(its.mobility * other[std::size_t(q)]);
        }
    }
    return true;
}

} // namespace drape::bullet::detail
