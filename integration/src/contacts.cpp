// The contact stage's pass over bodies and particles, and the re-limiting (see contacts.hpp).
#include "contacts.hpp"

#include "attachments.hpp"
#include "validate.hpp"

#include <btBulletCollisionCommon.h>

#include "drape/error.hpp"
#include "drape/timers.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>

namespace drape::bullet::detail {

ContactSolver::ContactSolver(const BulletClothSettings& settings, double band)
    : records(std::make_shared<ContactSet>()), contact_(settings.contact), band_(band),
      boxes_(settings.contact.thickness, band, settings.contact.continuous) {
    records->thickness = settings.contact.thickness;
    records->band = band;
}

void ContactSolver::detect(Cloth& c, double dt) {
    const std::size_t n = c.particleCount();
    records->planes.reset(n);
    if (contact_.triangles) trianglePlane_.assign(n, 0);
    planeBody_.clear();
    planePoint_.clear();
    triangleBody_.clear();
    trianglePoint_.clear();
    anyTouching_ = false;
    edgeHits_.clear();
    exitLast_.swap(exitNow_);
    exitNow_.assign(n, 0);
    if (exitLast_.size() != n) exitLast_.assign(n, 0);
    if (!inStep) return; // the cloth was stepped outside the world: no bodies to collide with
    from_ = &c.stepStartPositions();
    records->contacts.clear();
    records->dt = dt;
    if (bodies.empty()) return; // no rigid collider near the cloth: no work at all
    // A free dynamic body (in no Bullet contact: a projectile, a thrown rod) gives way in the
    // walk with its mass; a supported one is held by Bullet's contacts, and Bullet moves it;
    // one the cloth is attached to moves the attached particles (below: a carrier).
    // It gives way by shifting only: it turns through the impulses its planes hand it after the
    // walk (flushPlane, at their points). Turning in the walk too, a box resting on a net on
    // many planes rocked from corner to corner within every walk (Gauss-Seidel between opposite
    // sides) until the walk's cap (integration/README.md: "a box rocked within every walk").
    moverOf_.assign(bodies.size(), -1);
    carrierOf_.assign(bodies.size(), -1);
    for (std::size_t bi = 0; bi < bodies.size(); ++bi) {
        const BodySnapshot& b = bodies[bi];
        if (!b.dynamicBody || b.supported || b.attached || !(b.invMass > 0.0)) continue;
        moverOf_[bi] = static_cast<std::int32_t>(records->planes.movers.size());
        records->planes.movers.push_back(
            ContactPlanes::Mover{b.invMass, Eigen::Matrix3d::Zero(), b.com});
        records->planes.movers.back().lighten = b.lighten;
    }
    // A carrier (a free body the cloth hangs from) gives way to its attached particles'
    // springs, turning too: its inertia through their levers is what the cloth pulls on (a
    // light sphere turns under a sheet hanging off its centre).
    if (attached)
        for (std::size_t bi = 0; bi < bodies.size(); ++bi) {
            const BodySnapshot& b = bodies[bi];
            if (!b.carrier) continue;
            const auto m = static_cast<std::int32_t>(records->planes.movers.size());
            carrierOf_[bi] = m;
            records->planes.movers.push_back(ContactPlanes::Mover{b.invMass, b.invInertia, b.com});
            carriedParticles(*attached, c, b, carried_, carriedLevers_, carriedMasses_);
            for (Index i : carried_)
                records->planes.carry(m, i, c.positions()[i]);
            // Its particles are part of it (their masses move and turn with it).
            ContactPlanes::Mover& mover = records->planes.movers[std::size_t(m)];
            mover.composite = true;
            CarrierMatrices whole =
                carrierMatrices(b.invMass, b.invInertia, carriedLevers_, carriedMasses_);
            constrainToJoints(whole, b.joints); // only as its joints let it
            mover.mobility = whole.mobility;
        }
    // A body thinner across than the longest spring (its second-smallest half extent plus the
    // thickness below that length: a rod, a small ball) fits between two particles.
    // Small: its largest half extent too (a small ball, a short stub), so that it fits inside
    // a triangle.
    thin_.assign(bodies.size(), 0);
    small_.assign(bodies.size(), 0);
    for (std::size_t bi = 0; bi < bodies.size(); ++bi) {
        if (bodies[bi].plane) continue;
        btTransform identity;
        identity.setIdentity();
        btVector3 lo, hi;
        shapeAabb(bodies[bi].object->getCollisionShape(), identity, lo, hi);
        Vec3 half = 0.5 * toVec(hi - lo);
        std::sort(half.data(), half.data() + 3);
        thin_[bi] = half[1] + contact_.thickness < longestSpring(c);
        small_[bi] = half[2] + contact_.thickness < longestSpring(c);
        if (moverOf_[bi] >= 0)
            records->planes.movers[std::size_t(moverOf_[bi])].backed = !thin_[bi];
    }
    // The free mass decides which dynamic bodies get limiter planes: only needed near one.
    clothMass_ = 0.0;
    if (std::any_of(bodies.begin(), bodies.end(),
                    [](const BodySnapshot& b) { return b.dynamicBody != nullptr; }))
        for (std::size_t i = 0; i < n; ++i)
            if (c.inverseMasses()[i] != 0.0) clothMass_ += c.masses()[i];

    weightPush_ = totalMass(c) * c.settings().gravity.norm() * dt * dt;

    QueryCounters counters;
    collideParticles(c, dt, counters);
    solveHeld(c);
    if (contact_.continuous) sweepBodies(c, dt, counters);
    straddledSprings(c, dt);
    if (contact_.triangles) {
        const ScopedFlag friction(pushFriction_);
        collideTriangles(c, dt, counters);
    }
    if (contact_.boxEdges) collideEdges(c);
    for (unsigned char t : touching_)
        anyTouching_ = anyTouching_ || t != 0;
    stats.narrowphaseQueries += counters.queries;
    stats.triangleQueries += counters.triangleQueries;
}

void ContactSolver::finish(Cloth& c, double dt) {
    if (!inStep || bodies.empty()) return;
    settleMovers(c, dt);
    QueryCounters counters;
    const auto& lim = c.settings().limiter;
    if (anyTouching_ && lim.kind != LimiterKind::None) {
        // The stress-ordered walk kept every particle above its contact plane: what it moved
        // is projected again (a curved body, a box's other face, a body it had no plane of, a
        // dynamic body lighter than the cloth, which gets none). The comparison limiters keep
        // no planes and list no moves: every free particle is projected again after them.
        const bool planes = lim.kind == LimiterKind::StressOrdered;
        if (!planes) {
            everyParticle_.clear();
            for (std::size_t i = 0; i < c.particleCount(); ++i)
                if (c.inverseMasses()[i] != 0.0) everyParticle_.push_back(static_cast<Index>(i));
        }
        collideMoved(c, dt, planes ? c.limiter().movedIndex() : everyParticle_, counters);
        if (planes && contact_.triangles) collideTriangles(c, dt, counters);
        // Only where that moved particles does the limiter run again from them, and so on (at
        // most kRelimitPasses).
        for (int pass = 0; pass < kRelimitPasses && !projected_.empty(); ++pass) {
            StrainLimitStats st;
            {
                ScopedPhase timeLimiter(c.timers(), limiterSlot);
                st = c.relimit(projected_, dt, planes ? &records->planes : nullptr);
            }
            ++stats.relimitWalks;
            settleMovers(c, dt);
            // Nothing left to correct; or the walk used its whole budget (maxRounds, counted
            // as a cap hit): another pass would spend it again.
            if (st.corrections == 0 || st.capHit) break;
            collideMoved(c, dt, c.relimitMoved(), counters);
            if (contact_.triangles) collideTriangles(c, dt, counters);
        }
    }

    stats.planesLetGo += records->planes.letGo;
    // What the contact planes held in the limiter's walk: the particle got m push / dt (its
    // velocity follows its position), the body gets the opposite.
    for (std::size_t k = 0; k < records->planes.size(); ++k)
        flushPlane(c, k, dt);
    for (std::size_t t = 0; t < records->planes.triangles.size(); ++t)
        flushTriangle(t, dt);
    stopEdgeApproach(c);

    // How fast the particles touching a dynamic body move against it, once the step's
    // constraints are met (BodySnapshot::contactSpeed: a sleeping body wakes at its threshold).
    const double h = contact_.thickness;
    for (const ContactRecord& r : records->contacts) {
        BodySnapshot& b = bodies[r.body];
        if (!b.dynamicBody) continue;
        const Vec3& xi = c.positions()[r.particle];
        if ((xi - r.point).dot(r.normal) - h > kTouching * h) continue;
        b.contactSpeed =
            std::max(b.contactSpeed, (c.velocities()[r.particle] - b.velocityAt(r.point)).norm());
    }

    stats.narrowphaseQueries += counters.queries;
    stats.triangleQueries += counters.triangleQueries;
}

void ContactSolver::straddledSprings(Cloth& c, double dt) {
    ContactPlanes& pl = records->planes;
    if (pl.size() == 0) return;
    const double bound = 1.0 + c.settings().limiter.maxStrain;
    const ClothTopology& topo = c.topology();
    const auto& offsets = topo.adjacencyOffsets();
    // The springs between two planes of one body, each once (from its lower end). Only a thin
    // body (thin_) fits between two particles. (keepPlane below replaces a plane of that body
    // in place.)
    for (std::size_t k = 0; k < pl.size(); ++k) {
        if (!thin_[planeBody_[k]]) continue;
        const Index a = pl.particle(k);
        for (Index e = offsets[a]; e < offsets[a + 1]; ++e) {
            const Index other = topo.adjacentParticles()[e];
            if (other < a) continue;
            const Spring& s = topo.springs()[topo.adjacentSprings()[e]];
            const std::int32_t ka = pl.of[s.a], kb = pl.of[s.b];
            if (ka < 0 || kb < 0) continue;
            const std::uint32_t bi = planeBody_[std::size_t(ka)];
            if (planeBody_[std::size_t(kb)] != bi) continue;
            const Vec3 na = pl.normal[std::size_t(ka)], nb = pl.normal[std::size_t(kb)];
            if (!(na.dot(nb) < -0.2)) continue;
            const BodySnapshot& b = bodies[bi];
            // How far apart the two planes hold the ends, across the body: each plane's distance
            // from the body's centre along its normal.
            const double da = pl.offsetNow(std::size_t(ka)) - na.dot(b.com);
            const double db = pl.offsetNow(std::size_t(kb)) - nb.dot(b.com);
            if (s.restLength * bound >= 0.5 * (da + db) * (na - nb).norm()) continue;
            // They cannot both hold within the bound: the spring passes the body on one side, the
            // side both normals share.
            Vec3 m = na + nb;
            const double len = m.norm();
            if (!(len > 1e-6)) continue;
            m /= len;
            const btCollisionShape* shape = b.object->getCollisionShape();
            if (!shape->isConvex()) continue;
            const Vec3 local = b.pose.R.transpose() * m;
            const Vec3 support = b.pose.toWorld(toVec(
                static_cast<const btConvexShape*>(shape)->localGetSupportingVertex(toBt(local))));
            const double offset = m.dot(support) + contact_.thickness;
            for (Index i : {s.a, s.b})
                keepPlane(c, bi, i, m, offset, support, false, dt);
        }
    }
}

void ContactSolver::flushTriangle(std::size_t t, double dt) {
    ContactPlanes::TrianglePlane& tri = records->planes.triangles[t];
    if (tri.push == Vec3::Zero()) return;
    exchange(bodies[triangleBody_[t]], tri.push / dt, trianglePoint_[t]);
    tri.push = Vec3::Zero();
}

void ContactSolver::settleMovers(Cloth& c, double dt) {
    ContactPlanes& pl = records->planes;
    if (pl.movers.empty()) return;
    // A walk that moved a body to a non-finite place (or turned it past half a turn: the core's
    // movers may turn; this stage's only shift, see detect) is past what first-order planes
    // describe: the body stays, and its planes give what they held as a body's that does not
    // give way (flushPlane's inelastic bound).
    for (std::size_t k = 0; k < pl.size(); ++k)
        if (pl.mover[k] >= 0 && !pl.movers[std::size_t(pl.mover[k])].applied()) pl.mover[k] = -1;
    for (ContactPlanes::TrianglePlane& t : pl.triangles)
        if (t.mover >= 0 && !pl.movers[std::size_t(t.mover)].applied()) t.mover = -1;
    for (std::size_t k = 0; k < pl.size(); ++k)
        if (pl.mover[k] >= 0) flushPlane(c, k, dt);
    for (std::size_t t = 0; t < pl.triangles.size(); ++t)
        if (pl.triangles[t].mover >= 0) flushTriangle(t, dt);
    for (std::size_t bi = 0; bi < bodies.size(); ++bi)
        if (const std::int32_t m = moverOf_[bi] >= 0 ? moverOf_[bi] : carrierOf_[bi]; m >= 0) {
            const ContactPlanes::Mover& mv = pl.movers[std::size_t(m)];
            if (moverOf_[bi] >= 0) bodies[bi].lighten = mv.lighten;
            if (mv.applied())
                bodies[bi].displace(mv.shift, mv.turn);
            else
                ++stats.refusedBodyImpulses;
        }
    pl.settleMovers();
    for (std::size_t k = 0; k < pl.size(); ++k)
        if (pl.mover[k] >= 0) planePoint_[k] = bodies[planeBody_[k]].com + pl.lever[k];
    for (std::size_t t = 0; t < pl.triangles.size(); ++t)
        if (pl.triangles[t].mover >= 0)
            trianglePoint_[t] = bodies[triangleBody_[t]].com + pl.triangles[t].lever;
}

void ContactSolver::collideParticles(Cloth& c, double dt, QueryCounters& counters) {
    const std::size_t n = c.particleCount();
    const Vec3List& x = c.positions();
    const auto& invMass = c.inverseMasses();
    touching_.assign(n, 0);
    recordOf_.assign(n, -1);
    projected_.clear();
    // Pinned, kinematic and attached particles (zero inverse mass) get empty boxes. Blocks of
    // kBlock consecutive particles (neighbours in a sheet, so their boxes are close) get the
    // union of their boxes: a body a block's box misses is not tested against its particles
    // one by one. The cloth's box is the union of all of them. Both are grown as contacts move
    // particles, so they stay supersets of the boxes the particles have when they are tested.
    boxes_.resize(n);
    Block whole;
    for (std::size_t i = 0; i < n; ++i) {
        const bool fixed = invMass[i] == 0.0;
        boxes_.update(i, x[i], stepStart()[i], fixed);
        whole.free += !fixed;
        whole.grow(boxes_[i]);
    }
    // The blocks are built when a body is near the cloth at all (not while it falls free).
    const std::size_t nBlocks = (n + kBlock - 1) / kBlock;
    bool blocksBuilt = false;
    for (std::uint32_t bi = 0; bi < bodies.size(); ++bi) {
        const BodySnapshot& b = bodies[bi];
        auto misses = [&b, this](const Block& bl) { return boxes_.misses(b, bl); };
        // Every particle's box would fail the box test: skip them (and count the tests).
        if (misses(whole)) {
            stats.particleBoxTests += whole.free;
            continue;
        }
        if (!blocksBuilt) { // before any projection of this step: from the boxes as they are
            blocks_.assign(nBlocks, Block{});
            for (std::size_t i = 0; i < n; ++i) {
                Block& bl = blocks_[i / kBlock];
                bl.free += invMass[i] != 0.0;
                bl.grow(boxes_[i]);
            }
            blocksBuilt = true;
        }
        for (std::size_t k = 0; k < nBlocks; ++k) {
            Block& bl = blocks_[k];
            if (misses(bl)) {
                stats.particleBoxTests += bl.free;
                continue;
            }
            for (std::size_t i = k * kBlock, end = std::min(n, i + kBlock); i < end; ++i) {
                if (invMass[i] == 0.0) continue;
                ++stats.particleBoxTests;
                if (!boxes_.mayTouch(b, i, x[i], stepStart()[i])) continue;
                const Vec3 before = x[i];
                collideParticle(c, bi, i, dt, counters);
                // Projected: the next bodies see where it is now.
                if (movedBy(before, x[i], contact_.thickness)) {
                    projected_.push_back(static_cast<Index>(i));
                    boxes_.update(i, x[i], stepStart()[i], false);
                    bl.grow(boxes_[i]);
                    whole.grow(boxes_[i]);
                }
            }
        }
    }
}

void ContactSolver::collideMoved(Cloth& c, double dt, const std::vector<Index>& moved,
                                 QueryCounters& counters) {
    const ScopedFlag again(reprojecting_);
    const Vec3List& x = c.positions();
    moved_.assign(moved.begin(), moved.end());
    std::sort(moved_.begin(), moved_.end());
    projected_.clear();
    // Re-project what the limiter moved, in index order per body as before; the moved
    // particles of one block are skipped together when their boxes' union misses a body.
    movedGroups_.clear();
    for (std::size_t m = 0; m < moved_.size(); ++m) {
        const std::size_t i = moved_[m];
        boxes_.update(i, x[i], stepStart()[i], false);
        if (movedGroups_.empty() || moved_[movedGroups_.back().begin] / kBlock != i / kBlock)
            movedGroups_.push_back(MovedGroup{m, m, Block{}});
        MovedGroup& g = movedGroups_.back();
        g.end = m + 1;
        ++g.box.free;
        g.box.grow(boxes_[i]);
    }
    for (std::uint32_t bi = 0; bi < bodies.size(); ++bi) {
        const BodySnapshot& b = bodies[bi];
        for (MovedGroup& g : movedGroups_) {
            if (boxes_.misses(b, g.box)) {
                stats.particleBoxTests += g.box.free;
                continue;
            }
            for (std::size_t m = g.begin; m < g.end; ++m) {
                const std::size_t i = moved_[m];
                ++stats.particleBoxTests;
                if (!boxes_.mayTouch(b, i, x[i], stepStart()[i])) continue;
                const Vec3 before = x[i];
                collideParticle(c, bi, i, dt, counters);
                if (movedBy(before, x[i], contact_.thickness)) {
                    projected_.push_back(static_cast<Index>(i));
                    boxes_.update(i, x[i], stepStart()[i], false);
                    g.box.grow(boxes_[i]);
                }
            }
        }
    }
    solveHeld(c);
}

void ContactSolver::applyContactForces(const Cloth& c, double h) {
    frictionLeft_.assign(c.particleCount(), 0.0);
    for (const auto& pc : records->contacts) {
        if (pc.impulses)
            frictionLeft_[pc.particle] += std::max(0.0, pc.mu * pc.force - pc.friction.norm());
    }
    for (const auto& pc : records->contacts) {
        if (pc.force == 0.0) continue;
        exchange(bodies[pc.body], (pc.force * pc.normal + pc.friction) * h, pc.point);
    }
}

std::vector<unsigned char> ContactSolver::saveState() const {
    // The friction left per particle (n doubles, or none); then, only while some particle is
    // on a slow exit, one byte per particle saying which.
    const bool exits = std::any_of(exitNow_.begin(), exitNow_.end(), [](auto e) { return e; });
    std::vector<double> left = frictionLeft_;
    if (exits) left.resize(exitNow_.size(), 0.0);
    std::vector<unsigned char> out(left.size() * sizeof(double));
    if (!left.empty()) std::memcpy(out.data(), left.data(), out.size());
    if (exits) out.insert(out.end(), exitNow_.begin(), exitNow_.end());
    return out;
}

void ContactSolver::loadState(std::size_t n, const std::vector<unsigned char>& bytes) {
    exitNow_.clear();
    if (bytes.empty()) {
        frictionLeft_.clear();
        return;
    }
    const std::size_t row = n * sizeof(double);
    require(bytes.size() == row || bytes.size() == row + n, ErrorCode::InvalidArgument,
            "expected " + std::to_string(row) + " bytes (friction left for " + std::to_string(n) +
                " particles) or " + std::to_string(row + n) +
                " (and which are on a slow exit), got " + std::to_string(bytes.size()));
    std::vector<double> left(n);
    std::memcpy(left.data(), bytes.data(), row);
    for (double l : left)
        require(std::isfinite(l) && l >= 0.0, ErrorCode::InvalidArgument,
                "a particle's friction left is negative or not finite");
    if (bytes.size() == row + n) {
        exitNow_.assign(bytes.begin() + std::ptrdiff_t(row), bytes.end());
        for (unsigned char e : exitNow_)
            require(e <= 1, ErrorCode::InvalidArgument,
                    "a particle's slow-exit flag is neither 0 nor 1");
    }
    frictionLeft_ = std::move(left);
}

} // namespace drape::bullet::detail
