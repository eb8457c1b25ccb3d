// Attachments as kinematic targets set before every Bullet sub-step (see attachments.hpp).
#include "attachments.hpp"

#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

namespace drape::bullet::detail {

namespace {
/// The snapshot of body `o` among `bodies`, or null (a body outside the proxy).
BodySnapshot* snapshotOf(std::vector<BodySnapshot>& bodies, const btCollisionObject* o) {
    const auto it = std::find_if(bodies.begin(), bodies.end(),
                                 [&](const BodySnapshot& b) { return b.object == o; });
    return it == bodies.end() ? nullptr : &*it;
}

/// One projected Gauss-Seidel pass over the taut ropes: each stops its ends' separation (plus
/// its catch-up), its accumulated impulse staying >= 0 (a rope pulls, never pushes).
/// `velocityAt(body, p)` is the velocity of a body's point, `kick(body, j, p)` gives a body an
/// impulse j at p.
template <class Ropes, class VelocityAt, class Kick>
void ropePass(Ropes& taut, const VelocityAt& velocityAt, const Kick& kick) {
    for (auto& t : taut) {
        const double apart =
            (velocityAt(t.B, t.pb) - (t.A ? velocityAt(t.A, t.pa) : t.va)).dot(t.u) + t.catchUp;
        const double total = std::max(0.0, t.impulse + apart / t.k);
        if (total == t.impulse) continue;
        const Vec3 j = (total - t.impulse) * t.u;
        t.impulse = total;
        if (t.A) kick(t.A, j, t.pa);
        kick(t.B, -j, t.pb);
    }
}
} // namespace

Vec3 attachmentPoint(const Attachment& a) {
    return toPose(a.body->getWorldTransform()).toWorld(a.localPoint);
}

void carriedParticles(const std::vector<Attachment>& attached, const Cloth& c,
                      const BodySnapshot& b, std::vector<Index>& particles,
                      std::vector<Vec3>& levers, std::vector<double>& masses) {
    particles.clear();
    levers.clear();
    masses.clear();
    for (const Attachment& a : attached)
        if (a.body == b.object && c.inverseMasses()[a.particle] == 0.0) {
            particles.push_back(a.particle);
            levers.push_back(c.positions()[a.particle] - b.com);
            masses.push_back(c.masses()[a.particle]);
        }
}

void Attachments::attach(Cloth& c, const Attachment& a) {
    detach(c, a.particle);
    const auto body = [&a](const auto& p) { return p.first == a.body; };
    if (std::none_of(seen_.begin(), seen_.end(), body) &&
        std::none_of(attachedAt_.begin(), attachedAt_.end(), body))
        attachedAt_.emplace_back(a.body, toPose(a.body->getWorldTransform()));
    list_.push_back(a);
    tethersValid_ = false;
    c.setKinematicTarget(a.particle, attachmentPoint(a), c.time()); // there now
}

void Attachments::detach(Cloth& c, Index particle) {
    for (std::size_t k = 0; k < list_.size(); ++k) {
        if (list_[k].particle != particle) continue;
        c.unpin(particle);
        list_.erase(list_.begin() + static_cast<std::ptrdiff_t>(k));
        tethersValid_ = false;
        return;
    }
}

void Attachments::clear(Cloth& c) {
    for (const auto& a : list_)
        c.unpin(a.particle);
    list_.clear();
    tethersValid_ = false;
}

Pose Attachments::poseOf(const btCollisionObject* body) const {
    if (followed_)
        if (const auto found = followed_->find(body); found != followed_->end())
            return found->second;
    return toPose(body->getWorldTransform());
}

void Attachments::advance(Cloth& c, double dt) const {
    const double arrival = c.time() + dt;
    for (const auto& a : list_)
        c.setKinematicTarget(a.particle, pointOf(a), arrival);
}

void Attachments::followBodies(Cloth& c, const std::vector<BodySnapshot>& bodies, double arrival) {
    // The carriers among the bodies (a few at most: the loop below is attachments times them).
    carriers_.clear();
    for (const BodySnapshot& b : bodies)
        if (b.carrier) carriers_.push_back(&b);
    if (carriers_.empty()) return;
    for (const auto& a : list_)
        for (const BodySnapshot* b : carriers_)
            if (b->object == a.body) {
                c.setKinematicTarget(a.particle, b->pose.toWorld(a.localPoint), arrival);
                break;
            }
}

namespace {

/// Whether x is at point p to the rounding of Bullet's poses.
bool atPoint(const Vec3& p, const Vec3& x) {
    return (p - x).norm() <= 1e-9 * (1.0 + x.norm());
}

/// Moves every particle of the cloth by the rigid motion m, its velocities turned with it.
void carryCloth(Cloth& c, const Pose& m) {
    for (Vec3& x : c.mutablePositions())
        x = m.toWorld(x);
    for (Vec3& v : c.mutableVelocities())
        v = m.R * v;
}

/// The rigid motion (R, t) that best takes points `from` onto `to` (least squares, Kabsch);
/// for points on a line (or one point) the smallest turn that aligns the line, since a turn
/// about it is not determined.
Pose bestRigidMotion(const std::vector<Vec3>& from, const std::vector<Vec3>& to) {
    Vec3 cf = Vec3::Zero(), ct = Vec3::Zero();
    for (std::size_t k = 0; k < from.size(); ++k) {
        cf += from[k];
        ct += to[k];
    }
    cf /= double(from.size());
    ct /= double(to.size());
    Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
    for (std::size_t k = 0; k < from.size(); ++k)
        H += (from[k] - cf) * (to[k] - ct).transpose();
    const Eigen::JacobiSVD<Eigen::Matrix3d> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
    const Vec3 sv = svd.singularValues();
    Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
    if (sv[1] > 1e-9 * sv[0]) { // not on a line: determined
        const Eigen::Matrix3d U = svd.matrixU(), V = svd.matrixV();
        Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
        D(2, 2) = (V * U.transpose()).determinant() < 0.0 ? -1.0 : 1.0;
        R = V * D * U.transpose();
    } else if (sv[0] > 0.0) { // a line: turn its direction onto the other's, the short way
        const Vec3 a = svd.matrixU().col(0), b = svd.matrixV().col(0);
        R = Eigen::Quaterniond::FromTwoVectors(a, a.dot(b) < 0.0 ? Vec3(-b) : b).toRotationMatrix();
    }
    return Pose{R, ct - R * cf};
}

} // namespace

void Attachments::placeMoved(Cloth& c) const {
    std::vector<Vec3> from, to;
    std::vector<Index> moved;
    std::size_t held = 0; // attachments to static or kinematic bodies known since the last call
    for (const Attachment& a : list_) {
        // A free body's particles follow its snapshot, not its pose (followBodies).
        const btRigidBody* rb = btRigidBody::upcast(a.body);
        if (rb && !rb->isStaticOrKinematicObject()) continue;
        const auto was = std::find_if(seen_.begin(), seen_.end(),
                                      [&](const auto& p) { return p.first == a.body; });
        if (was == seen_.end()) continue; // attached since the last call
        ++held;
        const Vec3& x = c.positions()[a.particle];
        const Vec3 now = pointOf(a);
        if (atPoint(was->second.toWorld(a.localPoint), x) || atPoint(now, x)) continue;
        from.push_back(x);
        to.push_back(now);
        moved.push_back(a.particle);
    }
    if (moved.empty()) return;
    // Every attached particle moved (the whole cloth reset or restored) and the program pins
    // none: the cloth goes with the rigid motion that best puts them on their points, so that
    // its shape arrives as it was set. What that leaves is placed below.
    const std::vector<double>& w = c.inverseMasses();
    if (moved.size() == held && list_.size() == held &&
        std::size_t(std::count(w.begin(), w.end(), 0.0)) == held)
        carryCloth(c, bestRigidMotion(from, to));
    for (std::size_t k = 0; k < moved.size(); ++k)
        c.setPosition(moved[k], to[k]);
}

std::optional<Pose> Attachments::carryTeleported(Cloth& c, double dt, double speed, double turn) {
    // The bodies' poses now, and the one rigid motion they all made since the last call.
    std::vector<std::pair<const btCollisionObject*, Pose>> now;
    for (const Attachment& a : list_)
        if (std::none_of(now.begin(), now.end(), [&](const auto& p) { return p.first == a.body; }))
            now.emplace_back(a.body, poseOf(a.body));
    std::vector<std::pair<const btCollisionObject*, Pose>> before;
    before.swap(seen_);
    seen_ = now;
    // Static and kinematic bodies attached to since the last call: their poses at the
    // attach, and any motion since is a placement (the program set the body where it belongs
    // after attaching the cloth to it). A dynamic body also moved under Bullet's forces since
    // (posts on joints sag in the first sub-step): not a placement.
    bool placing = false;
    for (const auto& at : attachedAt_) {
        const btRigidBody* rb = btRigidBody::upcast(at.first);
        if (rb && !rb->isStaticOrKinematicObject()) continue;
        if (std::none_of(before.begin(), before.end(),
                         [&](const auto& p) { return p.first == at.first; })) {
            before.push_back(at);
            placing = true;
        }
    }
    attachedAt_.clear();
    if (list_.empty() || !(speed > 0.0 || turn > 0.0) || !(dt > 0.0)) return std::nullopt;
    Pose motion; // now = motion * before, for every body
    for (std::size_t k = 0; k < now.size(); ++k) {
        const auto was = std::find_if(before.begin(), before.end(),
                                      [&](const auto& p) { return p.first == now[k].first; });
        if (was == before.end()) return std::nullopt; // no pose to compare
        const Pose& p0 = was->second;
        const Pose& p1 = now[k].second;
        const Eigen::Matrix3d rotation = p1.R * p0.R.transpose();
        const Pose m{rotation, p1.t - rotation * p0.t};
        if (k == 0) {
            motion = m;
            continue;
        }
        // Another body that moved otherwise (to float precision: Bullet's transforms): the
        // cloth is not carried (it hangs between them).
        const double scale = 1.0 + p1.t.norm();
        if ((m.R - motion.R).cwiseAbs().maxCoeff() > 1e-5 || (m.t - motion.t).norm() > 1e-5 * scale)
            return std::nullopt;
    }
    // The attached particles are where the bodies' poses of the last call put them (else the
    // program moved them, or restored the cloth from a snapshot: nothing to carry), and fast
    // enough to be a teleport (an attachment's point moved beyond speed dt) or a snap turn.
    const Vec3List& x = c.positions();
    double jump = 0.0;
    for (const Attachment& a : list_) {
        const Pose& p0 = std::find_if(before.begin(), before.end(), [&](const auto& p) {
                             return p.first == a.body;
                         })->second;
        const Vec3& xi = x[a.particle];
        if (!atPoint(p0.toWorld(a.localPoint), xi)) return std::nullopt;
        jump = std::max(jump, (motion.toWorld(xi) - xi).norm());
    }
    const bool jumped = speed > 0.0 && jump > speed * dt;
    const bool snapped = turn > 0.0 && Eigen::AngleAxisd(motion.R).angle() > turn;
    // A placement is a move faster than a fifth of the teleport speed (10 m/s by default): a
    // hand that picks a tablecloth up and moves on at walking pace drags it, as before.
    const bool placed = placing && speed > 0.0 && jump > kPlacementShare * speed * dt;
    if (!jumped && !snapped && !placed) return std::nullopt;
    // Particles the program pinned stay where they are: no carry.
    const auto& w = c.inverseMasses();
    if (std::size_t(std::count(w.begin(), w.end(), 0.0)) != list_.size()) return std::nullopt;
    carryCloth(c, motion);
    return motion;
}

void Attachments::pushBodies(const Cloth& c, double h, std::vector<BodySnapshot>& bodies,
                             ContactStats& stats, std::vector<OutsideImpulse>& outside) {
    // The body carries the force the cloth puts on the attached particle (springs and the
    // particle's own weight) and the strain limiter's reaction on it (its corrections' pull).
    const Vec3List& held = c.constraintImpulses();
    const auto impulseOn = [&](Index i) {
        return Vec3(c.forces()[i] * h + (i < held.size() ? held[i] : Vec3::Zero()));
    };
    for (const auto& a : list_) {
        const btRigidBody* rb = btRigidBody::upcast(a.body);
        if (!rb || rb->isStaticOrKinematicObject() || rb->getInvMass() <= 0.0f) continue;
        BodySnapshot* snap = snapshotOf(bodies, a.body);
        if (snap && snap->carrier) continue; // below, with its particles
        const Vec3 j = impulseOn(a.particle);
        const Vec3 at = c.positions()[a.particle];
        stats.impulseOnBodies += j;
        if (snap) {
            snap->applyImpulse(j, at);
        } else {
            // The body is outside the proxy (possible with a long attachment).
            outside.push_back(OutsideImpulse{const_cast<btRigidBody*>(rb), j, at});
        }
    }
    // A carrier and its particles move as one rigid body (ContactPlanes::Mover::composite): of
    // what the cloth gives them, and of the body's own weight, the body takes its share
    // (CarrierMatrices::share); the rest moves its particles with it, as the walk moved them.
    // Handed it all, a light body was accelerated by its particles' weight and inertia as
    // well (a sheet hanging from a 0.2 kg ball fell 4.7 % too fast; turned by particles far
    // from a small ball's centre, it spun up).
    for (BodySnapshot& b : bodies) {
        if (!b.carrier) continue;
        carriedParticles(list_, c, b, carried_, levers_, masses_);
        if (carried_.empty()) continue;
        Vec3 linear = Vec3::Zero(), angular = Vec3::Zero();
        for (std::size_t k = 0; k < carried_.size(); ++k) {
            const Vec3 j = impulseOn(carried_[k]);
            linear += j;
            angular += levers_[k].cross(j);
        }
        CarrierMatrices whole = carrierMatrices(b.invMass, b.invInertia, levers_, masses_);
        const Vec3 weight = (h / b.invMass) * toVec(b.dynamicBody->getGravity()); // Bullet's
        Eigen::Matrix<double, 6, 1> load;
        load << linear + weight, angular;
        // In joints the whole moves as they let it, and Bullet gave the body its weight as
        // they let it (BodySnapshot::jointedWeight; free: no rows, the identity).
        constrainToJoints(whole, b.joints);
        const Eigen::Matrix<double, 6, 1> own =
            whole.share * load - b.jointedWeight.leftCols<3>() * weight;
        b.applyImpulseAboutCentre(own.head<3>(), own.tail<3>());
        stats.impulseOnBodies += own.head<3>();
    }
}

void Attachments::buildTethers(const Cloth& c) {
    tethers_.clear();
    reaches_.clear();
    std::vector<std::int64_t> of(c.particleCount(), -1);
    for (std::size_t k = 0; k < list_.size(); ++k)
        if (list_[k].particle < of.size()) of[list_[k].particle] = std::int64_t(k);
    const auto& springs = c.topology().springs();
    for (std::size_t s = 0; s < springs.size(); ++s) {
        const std::int64_t ka = of[springs[s].a], kb = of[springs[s].b];
        if (ka < 0 || kb < 0) continue;
        const Attachment &A = list_[std::size_t(ka)], &B = list_[std::size_t(kb)];
        if (A.body == B.body) continue; // (whether either is dynamic is asked each step)
        tethers_.push_back(Tether{Index(s), std::size_t(ka), std::size_t(kb)});
    }
    // The reaches: per body, the geodesic front from every held particle not on it.
    double shortest = std::numeric_limits<double>::infinity();
    for (const Spring& sp : springs)
        shortest = std::min(shortest, sp.restLength);
    reachCatchUp_ = springs.empty() ? 0.0 : kTetherCatchUp * shortest;
    std::vector<const btCollisionObject*> done;
    for (const Attachment& a : list_) {
        if (std::find(done.begin(), done.end(), a.body) != done.end()) continue;
        done.push_back(a.body);
        std::vector<Index> anchors;
        for (Index i : reachHeld_)
            if (of[i] < 0 || list_[std::size_t(of[i])].body != a.body) anchors.push_back(i);
        if (anchors.empty()) continue;
        const AnchorField field = geodesicAnchors(c.topology(), anchors, reachSlack_);
        for (std::size_t k = 0; k < list_.size(); ++k) {
            if (list_[k].body != a.body) continue;
            const Index anchor = field.anchor[list_[k].particle];
            if (anchor == kNoParticle) continue; // no path: another piece of the cloth
            reaches_.push_back(Reach{k, anchor, of[anchor], field.restDistance[list_[k].particle]});
        }
    }
}

void Attachments::addTaut(BodySnapshot* A, const Vec3& pa, const Vec3& va, BodySnapshot& B,
                          const Vec3& pb, double room, double catchUpLimit, double dt) {
    const Vec3 d = pb - pa;
    const double l = d.norm(), beyond = l - room;
    if (!(beyond > 0.0)) return;
    const Vec3 u = d / l;
    const double k = (A ? A->inverseMassAlong(pa, u) : 0.0) + B.inverseMassAlong(pb, u);
    if (!(k > 0.0)) return;
    // The stretch beyond the limit is taken back in one step, at most catchUpLimit per step:
    // a post teleported away is pulled back over many steps, not thrown.
    taut_.push_back(Taut{A, &B, pa, pb, va, u, std::min(beyond, catchUpLimit) / dt, k, 0.0});
}

void Attachments::solveTaut(int passes) {
    const auto velocityAt = [](const BodySnapshot* b, const Vec3& p) { return b->velocityAt(p); };
    const auto kick = [](BodySnapshot* b, const Vec3& j, const Vec3& p) { b->applyImpulse(j, p); };
    for (int pass = 0; pass < passes; ++pass)
        ropePass(taut_, velocityAt, kick);
}

void Attachments::solveTautWithJoints(btDynamicsWorld& world, std::vector<BodySnapshot>& bodies,
                                      double dt) {
    // The bodies the ropes hold (by their snapshot's index) and their velocities, copied.
    const auto index = [&](const BodySnapshot* b) { return std::size_t(b - bodies.data()); };
    std::vector<unsigned char> roped(bodies.size(), 0);
    for (const Taut& t : taut_) {
        roped[index(t.B)] = 1;
        if (t.A) roped[index(t.A)] = 1;
    }
    std::vector<Vec3> v(bodies.size()), w(bodies.size());
    for (std::size_t k = 0; k < bodies.size(); ++k) {
        v[k] = bodies[k].v;
        w[k] = bodies[k].w;
        // Bullet's next step gives its gravity before it solves.
        if (roped[k] && bodies[k].dynamicBody)
            v[k] += dt * toVec(bodies[k].dynamicBody->getGravity());
    }
    const auto snapshotOfBody = [&](const btRigidBody& rb) -> std::int64_t {
        for (std::size_t k = 0; k < bodies.size(); ++k)
            if (bodies[k].dynamicBody == &rb) return std::int64_t(k);
        return -1;
    };
    // The joints' rows (btTypedConstraint::getInfo2) on the roped bodies.
    struct Row {
        std::int64_t a, b;
        Vec3 la, aa, lb, ab;
        double rhs, cfm, lo, hi, k, lambda;
    };
    std::vector<Row> rows;
    std::vector<btScalar> scratch; // a joint's getInfo2 arrays, eight of 3 n each
    const btContactSolverInfo& info = world.getSolverInfo();
    for (int ci = 0; ci < world.getNumConstraints(); ++ci) {
        btTypedConstraint* tc = world.getConstraint(ci);
        if (!tc || !tc->isEnabled()) continue;
        const std::int64_t a = snapshotOfBody(tc->getRigidBodyA());
        const std::int64_t b = snapshotOfBody(tc->getRigidBodyB());
        if (!((a >= 0 && roped[std::size_t(a)]) || (b >= 0 && roped[std::size_t(b)]))) continue;
        btTypedConstraint::btConstraintInfo1 i1;
        tc->getInfo1(&i1);
        const int n = i1.m_numConstraintRows;
        if (n <= 0) continue;
        // Every array is read and written with the row stride (as Bullet's solver lays them
        // out in its rows): row r at r * rowskip.
        const std::size_t len = 3 * std::size_t(n);
        scratch.assign(8 * len, 0);
        btScalar* const j1l = scratch.data();
        btScalar* const j1a = j1l + len;
        btScalar* const j2l = j1a + len;
        btScalar* const j2a = j2l + len;
        btScalar* const err = j2a + len;
        btScalar* const cfm = err + len;
        btScalar* const lo = cfm + len;
        btScalar* const hi = lo + len;
        std::fill(cfm, cfm + len, info.m_globalCfm);
        std::fill(lo, lo + len, -SIMD_INFINITY);
        std::fill(hi, hi + len, SIMD_INFINITY);
        btTypedConstraint::btConstraintInfo2 i2;
        i2.fps = btScalar(1.0 / dt);
        i2.erp = info.m_erp;
        i2.m_J1linearAxis = j1l;
        i2.m_J1angularAxis = j1a;
        i2.m_J2linearAxis = j2l;
        i2.m_J2angularAxis = j2a;
        i2.rowskip = 3;
        i2.m_constraintError = err;
        i2.cfm = cfm;
        i2.m_lowerLimit = lo;
        i2.m_upperLimit = hi;
        i2.m_numIterations = info.m_numIterations;
        i2.m_damping = info.m_damping;
        tc->getInfo2(&i2);
        for (int r = 0; r < n; ++r) {
            const std::size_t q = 3 * std::size_t(r);
            const auto at = [&](const btScalar* m) {
                return Vec3(double(m[q]), double(m[q + 1]), double(m[q + 2]));
            };
            Row row{a,
                    b,
                    at(j1l),
                    at(j1a),
                    at(j2l),
                    at(j2a),
                    double(err[q]),
                    double(cfm[q]),
                    double(lo[q]),
                    double(hi[q]),
                    0.0,
                    0.0};
            double k = row.cfm;
            if (a >= 0) {
                const BodySnapshot& A = bodies[std::size_t(a)];
                k += A.invMass * row.la.squaredNorm() + row.aa.dot(A.invInertia * row.aa);
            }
            if (b >= 0) {
                const BodySnapshot& B = bodies[std::size_t(b)];
                k += B.invMass * row.lb.squaredNorm() + row.ab.dot(B.invInertia * row.ab);
            }
            if (!(k > 0.0) || !std::isfinite(k)) continue;
            row.k = k;
            rows.push_back(row);
        }
    }
    if (rows.empty()) {
        solveTaut(1);
        return;
    }
    // The copies' velocities: a row's impulse d along (lin, ang) on body k, a rope's at a point.
    const auto rowKick = [&](std::int64_t k, const Vec3& lin, const Vec3& ang, double d) {
        if (k < 0) return;
        const BodySnapshot& b = bodies[std::size_t(k)];
        v[std::size_t(k)] += (b.invMass * d) * lin;
        w[std::size_t(k)] += b.invInertia * (d * ang);
    };
    const auto velocityAt = [&](const BodySnapshot* b, const Vec3& p) {
        const std::size_t k = index(b);
        return Vec3(v[k] + w[k].cross(p - b->com));
    };
    const auto kick = [&](BodySnapshot* b, const Vec3& j, const Vec3& p) {
        if (!b->dynamicBody) return;
        const std::size_t k = index(b);
        v[k] += b->invMass * j;
        w[k] += b->invInertia * (p - b->com).cross(j);
    };
    const auto rowVelocity = [&](std::int64_t k, const Vec3& lin, const Vec3& ang) {
        return k < 0 ? 0.0 : lin.dot(v[std::size_t(k)]) + ang.dot(w[std::size_t(k)]);
    };
    for (int pass = 0; pass < kJointPasses; ++pass) {
        for (Row& r : rows) {
            const double jv = rowVelocity(r.a, r.la, r.aa) + rowVelocity(r.b, r.lb, r.ab);
            const double total =
                std::clamp(r.lambda + (r.rhs - jv - r.cfm * r.lambda) / r.k, r.lo, r.hi);
            const double d = total - r.lambda;
            if (d == 0.0) continue;
            r.lambda = total;
            rowKick(r.a, r.la, r.aa, d);
            rowKick(r.b, r.lb, r.ab, d);
        }
        ropePass(taut_, velocityAt, kick);
    }
    // The ropes' impulses reach the bodies with the joints' impulses they were solved with:
    // alone they are not a solution. Two bars on a hinge, a sheet along both: the hinge folding
    // stretches the rope between the bars' neighbouring attached particles, and the rope's
    // impulse alone, near the hinge's axis, turned the bars (10 kg each) with 113 J more in
    // one frame, which Bullet's joint solve then took back. (Bullet's next solve starts from
    // velocities that keep the joints, and adds what its own error terms ask.)
    for (const Row& r : rows) {
        if (r.lambda == 0.0) continue;
        if (r.a >= 0)
            bodies[std::size_t(r.a)].applyImpulseAboutCentre(r.lambda * r.la, r.lambda * r.aa);
        if (r.b >= 0)
            bodies[std::size_t(r.b)].applyImpulseAboutCentre(r.lambda * r.lb, r.lambda * r.ab);
    }
    for (const Taut& t : taut_) {
        if (!(t.impulse > 0.0)) continue;
        const Vec3 j = t.impulse * t.u;
        if (t.A) t.A->applyImpulse(j, t.pa);
        t.B->applyImpulse(-j, t.pb);
    }
}

void Attachments::holdTethers(const Cloth& c, double dt, std::vector<BodySnapshot>& bodies,
                              btDynamicsWorld* world) {
    if (list_.empty() || !(dt > 0.0)) return;
    const double slack = c.settings().limiter.longRangeSlack;
    const auto& w = c.inverseMasses();
    const std::size_t held = static_cast<std::size_t>(std::count(w.begin(), w.end(), 0.0));
    if (!tethersValid_ || reachSlack_ != slack || held != reachHeld_.size() ||
        !std::all_of(reachHeld_.begin(), reachHeld_.end(),
                     [&](Index i) { return i < w.size() && w[i] == 0.0; })) {
        reachHeld_.clear();
        for (std::size_t i = 0; i < w.size(); ++i)
            if (w[i] == 0.0) reachHeld_.push_back(Index(i));
        reachSlack_ = slack;
        buildTethers(c);
        tethersValid_ = true;
    }
    const auto& springs = c.topology().springs();
    const Vec3List& x = c.positions();
    const double limit = 1.0 + c.settings().limiter.maxStrain;
    // The springs between two bodies: one pass, each rope in turn.
    taut_.clear();
    for (const Tether& t : tethers_) {
        BodySnapshot* A = snapshotOf(bodies, list_[t.a].body);
        BodySnapshot* B = snapshotOf(bodies, list_[t.b].body);
        if (!A || !B) continue; // a body outside the proxy: left to the free particles' pulls
        const double rest = springs[t.spring].restLength;
        addTaut(A, x[list_[t.a].particle], Vec3::Zero(), *B, x[list_[t.b].particle], limit * rest,
                kTetherCatchUp * rest, dt);
    }
    if (world && !taut_.empty())
        solveTautWithJoints(*world, bodies, dt);
    else
        solveTaut(1);
    // The reaches' ropes that are taut, solved together: one body hangs from several (a bar
    // along a row), and one impulse after another, each final, over-corrects the ones before
    // it through the body's rotation (a 30 kg bar bounced back up at 1.8 m/s).
    // The rope holds the body two steps' fall of gravity along it inside the reach (never
    // shorter than the rest path): Bullet's next step lets it fall about g dt^2 before the
    // rope acts again, and a body that ends the step beyond the reach leaves the limiter's walk
    // held ends it cannot join (its cap, and no pull passed on, in every step: a 1 kg bar then
    // swung at 0.9 m/s).
    const Vec3 fall = c.settings().gravity * (dt * dt);
    taut_.clear();
    for (const Reach& r : reaches_) {
        BodySnapshot* B = snapshotOf(bodies, list_[r.k].body);
        if (!B || !B->dynamicBody) continue;
        BodySnapshot* A = nullptr;
        if (r.anchorK >= 0) {
            A = snapshotOf(bodies, list_[std::size_t(r.anchorK)].body);
            if (!A) continue;
        }
        const Vec3 pa = x[r.anchor], pb = x[list_[r.k].particle];
        const Vec3 d = pb - pa;
        const double l = d.norm();
        if (!(l > r.length)) continue; // not stretched: the room below is never shorter
        const double margin = kReachMargin * std::abs(fall.dot(d / l));
        addTaut(A, pa, c.velocities()[r.anchor], *B, pb,
                std::max(r.length, limit * r.length - margin), reachCatchUp_, dt);
    }
    solveTaut(kReachIterations);
}

} // namespace drape::bullet::detail
