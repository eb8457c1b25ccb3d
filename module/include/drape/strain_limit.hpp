// drape/strain_limit.hpp: strain limiters against "hyper elasticity" (paper section 3).
//
// Every limiter shortens springs longer than (1 + maxStrain) L0 by moving particles; a
// particle with zero inverse mass never moves. Limiters only touch positions and list what
// they moved: the step turns each displacement into a velocity change (v += dx / dt) so that
// velocities stay consistent with the corrected positions.
#pragma once

#include "drape/error.hpp"
#include "drape/topology.hpp"

#include <Eigen/Geometry>

#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace drape {
class Executor; // drape/executor.hpp

struct LimiterSettings;

/// What a limiter did in one step (or in one call of StrainLimiter::relimit).
struct StrainLimitStats {
    int rounds = 0;              ///< worklist waves (stress-ordered) or sweeps (Provot)
    std::size_t corrections = 0; ///< spring corrections applied
    std::size_t work = 0;        ///< spring (and attachment) length evaluations
    bool capHit = false;         ///< stopped by LimiterSettings::maxRounds: bound not promised
    /// Stopped early (capHit is set too): two particles that never move in the limiter (pinned,
    /// kinematic, attached) are farther apart than (1 + maxStrain + tolerance) times the
    /// shortest chain at rest of springs the walk corrects (a spring between two such
    /// particles is none: the walk leaves it as it is), so no walk can bring every spring
    /// within the bound (a pin or a body moved away from the rest: a teleport, a post pulled
    /// off). Looked for only in a walk that has run StrainLimiter::kApartCheck sweeps.
    bool pinsApart = false;
    /// Largest (l - L0) / L0 the first scan saw (stress-ordered: after the attachments and
    /// the warm start) [-].
    double maxStrainBefore = 0.0;
    /// Largest (l - L0) / L0 when it ended [-]: measured when the walk stopped at the safety
    /// cap (or a comparison limiter ran); when the stress-ordered walk finished, every spring
    /// passed a check after its last move and this is the band's top, maxStrain + tolerance
    /// (a bound, not a measurement; Cloth::maxStrain() measures).
    double maxStrainAfter = 0.0;
};

/// One-sided constraints n . x >= offset on some particles: the tangent planes of their
/// contacts. StrainLimiter::limit and relimit keep them while they correct springs, so a
/// contact stage gets the strain bound and non-penetration from one walk instead of
/// alternating the two (Cloth passes its ContactSet's planes to the step's walk).
/// For a convex body the tangent plane lies outside the body, so staying above it is staying
/// outside the body.
struct ContactPlanes {
    std::vector<std::int32_t> of; ///< per particle: its plane, or -1 (empty: no planes)
    std::vector<Vec3> normal;     ///< per plane: unit outward normal
    std::vector<double> offset;   ///< per plane: the particle stays where n . x >= offset [m]
    /// Per plane, filled by the walk: the sum of the displacements by which the plane pushed
    /// its particle back out [m] (the contact's share of the constraint: an impulse
    /// m push / dt on the particle, and its opposite on the body). A vector, so that a plane
    /// replaced by set() keeps what its earlier normals pushed.
    std::vector<Vec3> push;
    /// Per plane of a mover, filled by the walk: what the pins behind its particle pushed the
    /// body with (giveWay's room: the particle's long-range attachment taut) [kg m]. The
    /// body's walk moved it by that; its impulse is at most what stops its approach there
    /// (flushPlane: a net does not throw back what it holds).
    std::vector<Vec3> held;
    /// Per plane: a push in one step past this [m] lets the plane go for the rest of the
    /// step (its offset becomes -infinity; push keeps what it held): the walk was fighting it
    /// against springs it cannot satisfy together with it (a neighbour pinned across the
    /// plane, a second body pressing the particle the other way), wave after wave, at the
    /// cost of the whole budget and with a push that is no contact's. The strain those springs
    /// are left with is measured, as every strain. Infinite (set's default): never; the glue
    /// sets, for bodies that do not move in the walk and are not free (static, kinematic,
    /// attached to the cloth), the larger of the cloth's longest spring and the push that
    /// carries the whole cloth's weight over the step, |g| M dt^2 / m_i (a plane holding up
    /// the cloth hanging below it pushes up to that in a walk: no fight).
    std::vector<double> pushLimit;
    /// Planes let go by pushLimit since the last reset.
    std::size_t letGo = 0;

    /// A body that gives way in the walk (a free dynamic body: a projectile, a thrown rod): a
    /// plane of it pushing particle i out by `below` moves i by w_i lambda and the body by
    /// lambda against its inverse mass and inertia, lambda = below / (w_i + w_body(n, r))
    /// (Gauss-Seidel with the body's mass, momentum conserved), so the body's planes recede
    /// with it. A net catching a body stops it at the strain bound instead of fighting it.
    struct Mover {
        double invMass = 0.0;                                 ///< [1/kg]
        Eigen::Matrix3d invInertia = Eigen::Matrix3d::Zero(); ///< world frame [1/(kg m^2)]
        Vec3 centre = Vec3::Zero(); ///< centre of mass, before the walk [m]
        Vec3 shift = Vec3::Zero();  ///< moved in the walk [m]
        Vec3 turn = Vec3::Zero();   ///< turned in the walk [rad]
        bool broken = false;        ///< the walk turned it too far (giveWay): not applied
        /// Its planes' particles are backed by their long-range attachments (keepAbove): a
        /// particle taut from its pin does not give way to it, the body does. Off for a body
        /// thinner than the spacing (a rod wedged between particles: pins pushing it from
        /// both sides would spin it).
        bool backed = true;
        /// How many times lighter it counts where the pins hold its particle (keepAbove's
        /// `pinned`: the cloth has held particles, the body is backed and pushed through its
        /// centre) [-]. 1 until a walk has run StrainLimiter::kLightenAfter waves; each wave
        /// after that multiplies it by kLightenRate, and it stays for the caller's later walks
        /// with this mover (the glue keeps it for a body through its world step). In
        /// Gauss-Seidel a body 4,000 particle masses heavy pressed into a cloth at its bound (a
        /// ball in a net) recedes by 1/4,000 of each push, and a walk took thousands of waves
        /// (up to 4.9 million spring checks) to move it; counted lighter it recedes within
        /// tens. The converged state differs only where the cloth is not at its bound yet (the
        /// body stops a little early). What it moves beyond its own share is pushed by the pins
        /// behind the particle (held: at most what stops its approach, flushHeld): no momentum
        /// from the cloth, nothing thrown back.
        double lighten = 1.0;
        /// What the walk did to it can be applied: not broken, finite, at most kBrokenTurn.
        bool applied() const {
            return !broken && shift.allFinite() && turn.allFinite() && turn.norm() <= kBrokenTurn;
        }
        /// Takes -lambda n [kg m] at `arm` from its centre of mass: it shifts and turns.
        /// Past half a turn in one walk the first-order planes describe nothing (a thin bar
        /// wedged between particles, light about its axis): it is then left out of the rest of
        /// the walk (broken: its planes hold, and the caller does not apply what it took), and
        /// take returns false, as it does for a broken mover.
        bool take(double lambda, const Vec3& n, const Vec3& arm) {
            if (broken) return false;
            Vec3 t, linear;
            if (composite) {
                const Vec3 rxn = arm.cross(n);
                t = turn - (mobility.bottomLeftCorner<3, 3>() * n +
                            mobility.bottomRightCorner<3, 3>() * rxn) *
                               lambda;
                linear =
                    (mobility.topLeftCorner<3, 3>() * n + mobility.topRightCorner<3, 3>() * rxn) *
                    lambda;
            } else { // (the same operations as before composite movers: the same bits)
                t = turn - invInertia * (arm.cross(n) * lambda);
                linear = (invMass * lambda) * n;
            }
            if (!(t.squaredNorm() <= kBrokenTurn * kBrokenTurn) || !shift.allFinite()) {
                broken = true;
                return false;
            }
            turn = t;
            shift -= linear;
            return true;
        }
        /// Its carried particles: entries [carriedBegin, carriedEnd) of ContactPlanes::carried.
        std::size_t carriedBegin = 0, carriedEnd = 0;
        /// A body with the particles it carries as one rigid body (their masses are part of it,
        /// as their motion is): `mobility` is its inverse mass over (linear, angular about
        /// `centre`), CarrierMatrices::mobility; invMass and invInertia are then not used.
        bool composite = false;
        Eigen::Matrix<double, 6, 6> mobility = Eigen::Matrix<double, 6, 6>::Zero();
        /// Its inverse mass along unit n at `arm` from its centre of mass [1/kg].
        double giveAlong(const Vec3& n, const Vec3& arm) const {
            const Vec3 rxn = arm.cross(n);
            if (composite) {
                Eigen::Matrix<double, 6, 1> g;
                g << n, rxn;
                return g.dot(mobility * g);
            }
            return invMass + rxn.dot(invInertia * rxn);
        }
        /// How far a point at `arm` from its centre of mass has moved along n in the walk (first
        /// order) [m].
        double moved(const Vec3& n, const Vec3& arm) const {
            return n.dot(shift + turn.cross(arm));
        }
    };
    std::vector<Mover> movers;
    /// Per plane: the mover it belongs to, or -1 (a body that does not give way).
    std::vector<std::int32_t> mover;
    /// Per plane of a mover: its contact point from the mover's centre of mass [m], and the
    /// mover's inverse mass along the normal there, 1/M + (r x n) . I^-1 (r x n) [1/kg].
    std::vector<Vec3> lever;
    std::vector<double> give;

    /// A particle a mover carries: attached to the body (zero inverse mass in the cloth), it
    /// moves with it. In the walk a spring or long-range attachment that pulls it pulls the
    /// body (Gauss-Seidel with the body's inverse mass along the pull at the particle, as at a
    /// plane of a mover), and every particle the body carries moves with it: a cloth hanging
    /// from a light free body moves it by its share instead of being held by it as by a pin
    /// (whose reaction, handed to the body after the walk, threw a body lighter than the cloth
    /// about). `at` is where it was when the mover started from rest (settleMovers), `lever`
    /// the same point from the mover's centre of mass [m].
    struct Carried {
        Index particle = 0;
        std::int32_t mover = -1;
        Vec3 at = Vec3::Zero();
        Vec3 lever = Vec3::Zero();
    };
    std::vector<Carried> carried;
    /// Per particle: its entry in `carried`, or -1 (empty while nothing is carried).
    std::vector<std::int32_t> carriedOf;
    /// Mover m carries particle i (zero inverse mass), now at x; a mover's particles are added
    /// one after another, before the next mover's. Throws drape::Error (InvalidArgument) for a
    /// mover or particle out of range, a particle carried already, or a mover's particles
    /// interleaved with another's.
    void carry(std::int32_t m, Index i, const Vec3& x) {
        if (m < 0 || std::size_t(m) >= movers.size() || std::size_t(i) >= of.size())
            throw Error(ErrorCode::InvalidArgument,
                        "ContactPlanes::carry: mover or particle out of range (reset(n) and "
                        "movers first)");
        if (carriedOf.size() != of.size()) carriedOf.assign(of.size(), -1);
        Mover& b = movers[std::size_t(m)];
        if (carriedOf[i] >= 0)
            throw Error(ErrorCode::InvalidArgument,
                        "ContactPlanes::carry: particle " + std::to_string(i) +
                            " is carried already (one body carries a particle)");
        if (b.carriedEnd != b.carriedBegin && b.carriedEnd != carried.size())
            throw Error(ErrorCode::InvalidArgument,
                        "ContactPlanes::carry: mover " + std::to_string(m) +
                            "'s particles must be added one after another, before the next "
                            "mover's");
        if (b.carriedEnd == b.carriedBegin) b.carriedBegin = b.carriedEnd = carried.size();
        carriedOf[i] = static_cast<std::int32_t>(carried.size());
        carried.push_back(Carried{i, m, x, x - b.centre});
        b.carriedEnd = carried.size();
    }
    /// Carried entry c's lever now: turned with its mover (exactly: a light body can turn
    /// far in one walk, and first order would stretch what it carries) [m].
    Vec3 carriedLever(const Carried& c) const {
        const Vec3& turn = movers[std::size_t(c.mover)].turn;
        const double angle = turn.norm();
        return angle > 0.0 ? Vec3(Eigen::AngleAxisd(angle, turn / angle) * c.lever) : c.lever;
    }
    /// Where carried entry c is now: moved and turned with its mover [m].
    Vec3 carriedNow(const Carried& c) const {
        const Mover& b = movers[std::size_t(c.mover)];
        return b.centre + b.shift + carriedLever(c);
    }

    /// A triangle's plane: the point sum_k beta_k x_k of the triangle (corners `corner`) stays
    /// where n . x >= offset -- a body thinner than the triangle, which touches no corner,
    /// keeps the triangle's point ahead of its tangent plane. The walk moves the point back
    /// out with the least-mass-weighted change, corner k by beta_k w_k lambda n (a mover
    /// takes its share of lambda, as for particle planes); `push` sums lambda n [kg m]: the
    /// triangle got the impulse push / dt, the body the opposite.
    struct TrianglePlane {
        Triangle corner = {0, 0, 0};
        Vec3 beta = Vec3::Zero();
        Vec3 normal = Vec3::UnitY();
        double offset = 0.0;
        std::int32_t mover = -1;
        Vec3 lever = Vec3::Zero(); ///< a mover's: the contact point from its centre of mass [m]
        double give = 0.0;         ///< a mover's inverse mass along n at the point [1/kg]
        Vec3 push = Vec3::Zero();
    };
    std::vector<TrianglePlane> triangles;
    /// Per particle: its first entry 3 t + k (corner k of triangle plane t), or -1; per entry:
    /// the particle's next one. Empty while there are no triangle planes.
    std::vector<std::int32_t> triangleHead, triangleNext;
    /// Adds a triangle plane (no mover); returns its index.
    std::size_t addTriangle(const Triangle& corners, const Vec3& beta, const Vec3& n, double off) {
        const std::size_t t = triangles.size();
        TrianglePlane tri;
        tri.corner = corners;
        tri.beta = beta;
        tri.normal = n;
        tri.offset = off;
        triangles.push_back(tri);
        if (triangleHead.size() != of.size()) triangleHead.assign(of.size(), -1);
        for (int k = 0; k < 3; ++k) {
            triangleNext.push_back(triangleHead[corners[k]]);
            triangleHead[corners[k]] = static_cast<std::int32_t>(3 * t) + k;
        }
        return t;
    }
    /// Triangle plane t belongs to mover m, touching it at r from its centre of mass.
    void triangleMoveWith(std::size_t t, std::int32_t m, const Vec3& r) {
        TrianglePlane& tri = triangles[t];
        tri.mover = m;
        tri.lever = r;
        tri.give = movers[std::size_t(m)].giveAlong(tri.normal, r);
    }
    /// Triangle plane t's offset now (a mover's has moved with it).
    double triangleOffsetNow(const TrianglePlane& t) const {
        return t.mover < 0 ? t.offset
                           : t.offset + movers[std::size_t(t.mover)].moved(t.normal, t.lever);
    }
    /// Whether there is any plane, of a particle or a triangle, or a carried particle.
    bool any() const { return !normal.empty() || !triangles.empty() || !carried.empty(); }

    /// Forgets every plane and mover; `of` gets one entry per particle.
    void reset(std::size_t particles) {
        if (of.size() != particles) of.assign(particles, -1);
        for (const TrianglePlane& t : triangles)
            for (Index i : t.corner)
                triangleHead[i] = -1;
        triangles.clear();
        triangleNext.clear();
        for (const Carried& c : carried)
            carriedOf[c.particle] = -1;
        carried.clear();
        if (!carriedOf.empty() && carriedOf.size() != particles) carriedOf.clear();
        if (!triangleHead.empty() && triangleHead.size() != particles) triangleHead.clear();
        for (std::size_t k = 0; k < normal.size(); ++k)
            of[particle_[k]] = -1;
        normal.clear();
        offset.clear();
        push.clear();
        held.clear();
        pushLimit.clear();
        letGo = 0;
        mover.clear();
        lever.clear();
        give.clear();
        movers.clear();
        particle_.clear();
    }
    /// Plane k belongs to mover m, touching it at r from its centre of mass.
    void moveWith(std::size_t k, std::int32_t m, const Vec3& r) {
        mover[k] = m;
        lever[k] = r;
        give[k] = movers[std::size_t(m)].giveAlong(normal[k], r);
    }
    /// Plane k's offset now: a mover's plane has moved with it.
    double offsetNow(std::size_t k) const {
        const std::int32_t m = mover[k];
        if (m < 0) return offset[k];
        const Mover& b = movers[std::size_t(m)];
        return offset[k] + b.moved(normal[k], lever[k]);
    }
    /// Plane k of a mover pushes its particle (inverse mass w) out of `below` [m]: the body
    /// takes its share; returns the particle's [m].
    /// A particle with at most `room` [m] to go along the normal (its long-range attachment
    /// taut) moves that far, and the body takes the rest of `below` (pushed by what holds
    /// the particle).
    double giveWay(std::size_t k, double below, double w,
                   double room = std::numeric_limits<double>::infinity(), double lighter = 1.0) {
        // In a long walk the body counts lighter (Mover::lighten), never below kLightest
        // particles.
        const double g = std::max(give[k], std::min(give[k] * lighter, w / kLightest));
        double lambda = below / (w + g); // [kg m]
        double own = w * lambda;
        const bool backed = own > room;
        if (backed) {
            own = room;
            lambda = (below - room) / g;
        }
        const double body = lambda * (g / give[k]); // moves the body g lambda along n
        if (!movers[std::size_t(mover[k])].take(body, normal[k], lever[k])) return below;
        // The body took `body`; the particle's share of it is what it moves (the caller adds
        // that to push), the rest is what holds the particle (held).
        if (backed || g != give[k]) held[k] += (body - own / w) * normal[k];
        return own;
    }
    /// The lightest a mover counts: its give at most the particle's inverse mass over this
    /// (it weighs at least this many of the particles it presses) [-].
    static constexpr double kLightest = 10.0;
    /// A walk that turns a mover further than this [rad] is not applied to it.
    static constexpr double kBrokenTurn = 3.14159265358979323846;
    /// After a walk: each mover's planes move and turn with it, exactly (the caller moves the
    /// bodies by shift and turn), and the movers start again from rest.
    void settleMovers() {
        std::vector<Eigen::Matrix3d> rotation(movers.size());
        for (std::size_t m = 0; m < movers.size(); ++m) {
            const double angle = movers[m].turn.norm();
            rotation[m] = angle > 0.0
                              ? Eigen::AngleAxisd(angle, movers[m].turn / angle).toRotationMatrix()
                              : Eigen::Matrix3d::Identity();
        }
        // offset = n . (centre + lever) + h, h the plane's distance from the surface.
        auto follow = [&](std::int32_t m, Vec3& n, Vec3& r, double& off) {
            if (m < 0) return;
            const Mover& b = movers[std::size_t(m)];
            const Eigen::Matrix3d& R = rotation[std::size_t(m)];
            const double h = off - n.dot(b.centre + r);
            n = R * n;
            r = R * r;
            off = n.dot(b.centre + b.shift + r) + h;
        };
        for (std::size_t k = 0; k < normal.size(); ++k)
            follow(mover[k], normal[k], lever[k], offset[k]);
        for (TrianglePlane& t : triangles)
            follow(t.mover, t.normal, t.lever, t.offset);
        for (Carried& c : carried) {
            const Mover& b = movers[std::size_t(c.mover)];
            c.lever = rotation[std::size_t(c.mover)] * c.lever;
            c.at = b.centre + b.shift + c.lever;
        }
        // (carriedNow reads centre + shift + lever: the same point once the movers start
        // again from rest below.)
        for (Mover& b : movers) {
            b.centre += b.shift;
            b.shift = Vec3::Zero();
            b.turn = Vec3::Zero();
            b.broken = false;
        }
    }
    /// Gives particle i the plane n . x >= offset (replacing one it had); returns its index.
    std::int32_t set(Index i, const Vec3& n, double off) {
        std::int32_t k = of[i];
        if (k < 0) {
            k = static_cast<std::int32_t>(normal.size());
            of[i] = k;
            normal.push_back(n);
            offset.push_back(off);
            push.push_back(Vec3::Zero());
            held.push_back(Vec3::Zero());
            pushLimit.push_back(std::numeric_limits<double>::infinity());
            mover.push_back(-1);
            lever.push_back(Vec3::Zero());
            give.push_back(0.0);
            particle_.push_back(i);
        } else {
            normal[std::size_t(k)] = n;
            offset[std::size_t(k)] = off;
            pushLimit[std::size_t(k)] = std::numeric_limits<double>::infinity();
            mover[std::size_t(k)] = -1;
        }
        return k;
    }
    Index particle(std::size_t k) const { return particle_[k]; }
    std::size_t size() const { return normal.size(); }

  private:
    std::vector<Index> particle_;
};

/// A rigid body (inverse mass and world inverse inertia about its centre of mass) carrying
/// point masses fixed to it (attached particles) at levers from its centre of mass: W =
/// diag(invMass, invInertia) the body's own 6 x 6 inverse mass, A the point masses' mass matrix
/// about the centre (sum m [1, -[r]x; [r]x, -[r]x [r]x]).
struct CarrierMatrices {
    /// The whole's inverse mass, (W^-1 + A)^-1 = W (1 + A W)^-1: what a push on the body or on
    /// the particles moves and turns.
    Eigen::Matrix<double, 6, 6> mobility;
    /// (1 + A W)^-1: of an impulse (linear, angular about the centre) on the whole, the part
    /// the body itself takes (the rest moves the point masses with it).
    Eigen::Matrix<double, 6, 6> share;
};
CarrierMatrices carrierMatrices(double invMass, const Eigen::Matrix3d& invInertia,
                                const std::vector<Vec3>& levers, const std::vector<double>& masses);
/// What a body's joints keep of its motion: rows J, each a 6-vector over its twist (linear
/// velocity, then angular velocity about its centre of mass, world frame), and how far the
/// joints' other bodies give way along them.
struct JointRows {
    std::vector<Eigen::Matrix<double, 6, 1>> rows;
    /// rows x rows: J_o W_o J_o^T, the other bodies' own inverse mass seen through the rows
    /// (a joint to a light body gives way as that body moves). Empty: they are held still.
    Eigen::MatrixXd give;
    bool empty() const { return rows.empty(); }
    void clear() {
        rows.clear();
        give.resize(0, 0);
    }
};
/// Restricts a carrier (or a body alone: carrierMatrices with no levers) to the motions its
/// joints allow. An impulse f on the whole then moves it by u = M f + M J^T lambda, the joints
/// keeping J u + G lambda = 0 (G = joints.give, the other bodies' part): mobility M -> M -
/// M J^T K^+ J M, K = J M J^T + G (its pseudo-inverse: two ball joints on one axis give six rows
/// of rank five), and the body's own part of f, share S -> S - S J^T K^+ J M (still W S = M).
/// No rows: unchanged.
void constrainToJoints(CarrierMatrices& m, const JointRows& joints);

/// Where each particle's long-range attachment goes: its nearest anchor over the cloth
/// (kNoParticle if no anchor reaches it) and the rest distance of the attachment [m].
struct AnchorField {
    std::vector<Index> anchor;
    std::vector<double> restDistance; ///< min(pathLength, slack * geodesic) for the given slack
    std::vector<double> pathLength;   ///< rest length of the spring path the front followed
    std::vector<double> geodesic;     ///< geodesic rest distance to the anchor
};

/// Geodesic rest distances from a set of anchor particles, computed once per anchor set.
/// Each particle gets the anchor with the shortest geodesic (a Dijkstra front over the
/// springs, refined across triangles by unfolding the pair (a, b) of a triangle (a, b, c)
/// into its plane and measuring from the virtual source that lies at distances d_a, d_b:
/// exact on a flat mesh, the usual first-order approximation on a curved one).
/// restDistance = min(P, slack * G), P the rest length of the spring path the front followed
/// (a spring path: the strain limit on its springs implies |x_i - x_a| <= (1 + maxStrain) P)
/// and G the geodesic. slack > 1 leaves room for the shear a spring lattice allows (a straight
/// line across a triangulated sheet can stretch more than its springs do when the lattice
/// shears); slack = 1 is the plain geodesic of Kim, Chentanez and Mueller (2012).
AnchorField geodesicAnchors(const ClothTopology& topology, const std::vector<Index>& anchors,
                            double slack);
/// Sets field.restDistance = min(pathLength, slack * geodesic) for another slack (O(n)).
void setSlack(AnchorField& field, double slack);

/// The default limiter: the paper's stress-ordered Provot corrections (section 3.2), run as a
/// worklist so that a step costs a few sweeps over the springs and the bound is a promise.
///
/// A step (limit()):
///   1. long-range attachments (optional, LimiterSettings::longRangeAttachments): a particle
///      farther than (1 + maxStrain) r_i from its anchor (AnchorField) is moved onto that
///      sphere. An anchor has infinite mass, so this is the exact projection of one
///      particle: it carries a hanging cloth's load from its pins in one pass instead of the
///      O(N^2) Gauss-Seidel sweeps a chain of N springs needs.
///   2. warm start (LimiterSettings::warmStart = w): every spring that the last step had to
///      pull in is pulled in again by w times last step's correction, along its current
///      direction (the limiter's share of a lasting load, such as a hanging sheet's weight).
///      All of them are measured on the positions the warm start finds, then applied (Jacobi:
///      no correction waits for the one before it).
///   3. one scan of the springs queues every spring longer than (1 + maxStrain + tolerance) L0
///      and every warm-started spring shorter than (1 + maxStrain - tolerance) L0.
///   4. waves: the queued springs are sorted by stress k (l - L0), most stressed first (the
///      paper's load order; tensions equal to float precision by index, so the walk is a
///      pure function of the state),
///      and each is set to exactly (1 + maxStrain) L0 by Provot's rule: both ends move by
///      their inverse-mass shares (only the free end if the other is pinned). The correction
///      lambda of a spring accumulates over the step and never turns into a push (lambda >= 0:
///      a warm-started spring is let out to the limit, not beyond). The springs of every
///      particle a correction moved are checked at once and queued for the next wave if they
///      need it ("regulated once unless needed again").
///   The walk stops when the queue is empty: every spring is then within
///   (1 + maxStrain + tolerance) L0, the promised bound. A safety cap of maxRounds
///   sweep-equivalents of spring evaluations stops a walk that cannot converge (it is
///   counted in the stats: capHit).
///
/// Energy: corrections aim exactly at the limit, never below, and the band of width
/// `tolerance` is never used to shorten a spring it holds, so the limiter only removes
/// kinetic energy (an inelastic projection) except for the warm start's overshoot, which the
/// let-out in step 4 bounds by the band. Measured on Experiment I: samples/benchmarks/LIMITER.md.
///
/// Contact planes found before the step's walk are kept by it (limit()'s `planes`); stages
/// that move particles after it call relimit() with the particles they moved: their springs
/// go into the same worklist, and the walk runs again from there. With contact planes, a
/// correction never takes a particle below its plane: a particle lying on
/// its plane counts with the inverse mass w (1 - (u . n)^2) for a correction along u into the
/// plane (it can only slide), so the correction still reaches the limit to first order, and
/// what is left below the plane is pushed back out along n (recorded in ContactPlanes::push).
/// Both sets are convex (|x_a - x_b| <= l and n . x >= c), so the projections converge to a
/// point of both when there is one.
class StrainLimiter {
  public:
    /// A walk that has run this many sweep-equivalents checks whether its held particles are
    /// too far apart for the bound (StrainLimitStats::pinsApart) and stops if they are: it
    /// would only spend the rest of its budget (maxRounds) on a bound that cannot hold.
    static constexpr int kApartCheck = 8;
    /// Waves a walk runs with free bodies at their own masses; after them each wave counts
    /// the bodies kLightenRate times lighter than the last (ContactPlanes::Mover::lighten, up
    /// to kMaxLighten). A walk that converges within them is unchanged (every game scene's
    /// but net_ball's and the banners'). At 16 the ball in the net stopped 1.6 cm higher and a
    /// box in a hammock slid more (samples/benchmarks/PERF.md).
    static constexpr int kLightenAfter = 32;
    static constexpr double kLightenRate = 1.25;
    static constexpr double kMaxLighten = 1e12;
    /// More held particles than this are not checked (their pairwise paths would cost more
    /// than they save).
    static constexpr std::size_t kMaxApartPins = 512;
    /// Threads for the scan of every spring (the walk itself is sequential); null: this thread.
    void setExecutor(Executor* executor) { executor_ = executor; }
    /// Runs one step's limiter on x. The long-range attachments are recomputed whenever the
    /// set of zero-inverse-mass particles differs from the last call's (the slack is applied
    /// per step: it may change from step to step at no cost).
    /// With `planes`, every move (long-range attachments, warm start, the waves) keeps the
    /// particles above their contact planes, as relimit() does.
    StrainLimitStats limit(const ClothTopology& topology, const std::vector<double>& invMass,
                           const std::vector<double>& stiffness, const LimiterSettings& s,
                           std::vector<Vec3>& x, ContactPlanes* planes = nullptr);
    /// Queues the springs of `touched` (particles a stage moved) and runs the waves again.
    StrainLimitStats relimit(const ClothTopology& topology, const std::vector<double>& invMass,
                             const std::vector<double>& stiffness, const LimiterSettings& s,
                             const std::vector<Index>& touched, std::vector<Vec3>& x,
                             ContactPlanes* planes = nullptr);
    /// Forgets the warm start (after the state was edited from outside).
    void resetWarmStart() {
        lambda_.assign(lambda_.size(), 0.0);
        warmLeft_.assign(warmLeft_.size(), 0.0);
        clearWarmBits();
        warmListValid_ = false;
    }

    /// Particles moved since the last clearMoved(), each with where it was before its first
    /// move: the caller adds (x - from) / dt to their velocities.
    const std::vector<Index>& movedIndex() const { return movedIndex_; }
    const std::vector<Vec3>& movedFrom() const { return movedFrom_; }
    /// Held particles (zero inverse mass: pinned, kinematic, attached) that corrections pulled
    /// on since the last clearMoved(), and what each took [kg m]: a correction that moves a
    /// free particle by dx with a held one at the spring's other end (or as its long-range
    /// anchor) changes the free particle's momentum by m dx / dt, and the held one takes the
    /// opposite, heldPull / dt [N s]. Whatever holds the particle (a body) must take it too,
    /// or the limiter's share of the load is lost to the momentum balance.
    const std::vector<Index>& heldIndex() const { return heldIndex_; }
    /// Whether heldIndex()/heldPull() are recorded (off by default: a pin's reaction goes
    /// nowhere; Cloth turns it on while it has kinematic particles, which a body may hold).
    void setRecordHeld(bool on) { recordHeld_ = on; }
    const std::vector<Vec3>& heldPull() const { return heldPull_; }
    void clearMoved();

    /// Accumulated correction of each spring in the last step [m kg^-1 ... as lambda: the
    /// displacement of an end is its inverse mass times lambda]; the warm start's memory, part
    /// of a snapshot.
    const std::vector<double>& warmStartState() const { return lambda_; }
    void setWarmStartState(std::vector<double> lambda) {
        lambda_ = std::move(lambda);
        warmListValid_ = false;
    }
    // (warmLeft_ needs no saving: it is rebuilt at the start of every step.)
    const AnchorField& anchors() const { return anchors_; }
    /// How far particle i, moved to `at`, can go along unit n before its long-range
    /// attachment (anchors(), at the last walk's limit) is taut [m] (infinite without an
    /// anchor, 0 past it); x: the positions, its anchor's among them.
    double anchorRoom(Index i, const Vec3& at, const Vec3& n, const std::vector<Vec3>& x) const;

  private:
    void prepare(const ClothTopology& topology, const std::vector<double>& invMass,
                 const LimiterSettings& s);
    void move(Index i, const Vec3& dx, std::vector<Vec3>& x) {
        if (!moved_[i]) firstMove(i, x);
        x[i] += dx;
    }
    /// Held particle i takes the pull p [kg m] (see heldPull()).
    void pullHeld(Index i, const Vec3& p) {
        if (!pulled_[i]) {
            pulled_[i] = 1;
            heldIndex_.push_back(i);
        }
        heldPull_[i] += p;
    }
    /// Records particle i's position before its first move of the step.
    void firstMove(Index i, const std::vector<Vec3>& x);
    /// The scan of step 3 over the spring families: queues the family springs that need a
    /// correction and returns the largest (l / L0)^2 among them.
    double scanFamilies(const ClothTopology& topology, const std::vector<double>& invMass,
                        const std::vector<double>& stiffness, const std::vector<Vec3>& x,
                        StrainLimitStats& st);
    /// Whether particle i has a contact plane of a body that does not give way in the walk.
    bool onStillPlane(Index i) const {
        const std::int32_t k = planes_->of[i];
        return k >= 0 && planes_->mover[std::size_t(k)] < 0;
    }
    /// Inverse mass of particle i for a move along unit dir: w, or w (1 - (dir . n)^2) when it
    /// lies on its contact plane (within eps) and dir goes into it.
    double slidingWeight(Index i, double w, const Vec3& dir, const std::vector<Vec3>& x,
                         double eps) const;
    /// The move dx of particle i in a correction, kept above its contact plane (if any).
    Vec3 keepAbove(Index i, const Vec3& dx, const std::vector<Vec3>& x) const;
    /// keepAbove when the walk has planes, else dx.
    Vec3 abovePlanes(Index i, const Vec3& dx, const std::vector<Vec3>& x) const {
        return planes_ ? keepAbove(i, dx, x) : dx;
    }
    /// After particle i moved: the triangle planes it is a corner of move their points back
    /// ahead of them (ContactPlanes::TrianglePlane), each corner by moveBy(corner, dx).
    template <class MoveBy>
    void holdTriangles(Index i, const std::vector<Vec3>& x, MoveBy&& moveBy) {
        if (planes_->triangleHead.empty()) return;
        for (std::int32_t e = planes_->triangleHead[i]; e >= 0;
             e = planes_->triangleNext[std::size_t(e)])
            holdTriangle(planes_->triangles[std::size_t(e) / 3], x, moveBy);
    }
    template <class MoveBy>
    void holdTriangle(ContactPlanes::TrianglePlane& t, const std::vector<Vec3>& x,
                      MoveBy&& moveBy) {
        const std::vector<double>& w = *planeInvMass_;
        Vec3 p = Vec3::Zero();
        double weight = 0.0;
        // A corner its long-range attachment holds at full length cannot go further along n
        // from its anchor: it moves on the attachment's sphere only (n without its part along
        // the attachment), and the point's weight along n counts that part.
        Vec3 dir[3];
        for (int k = 0; k < 3; ++k) {
            const Index c = t.corner[k];
            p += t.beta[k] * x[c];
            dir[k] = t.normal;
            double wk = w[c];
            if (wk > 0.0 && !anchorList_.empty() && anchors_.anchor[c] != kNoParticle) {
                const Vec3 d = x[c] - x[anchors_.anchor[c]];
                const double r = limit_ * anchors_.restDistance[c], l2 = d.squaredNorm();
                const double dn = d.dot(t.normal);
                if (dn > 0.0 && l2 >= r * r * (1.0 - 1e-9) && l2 > 0.0) {
                    const Vec3 u = d / std::sqrt(l2);
                    const double un = u.dot(t.normal);
                    dir[k] = t.normal - un * u;
                    wk *= std::max(0.0, 1.0 - un * un);
                }
            }
            weight += t.beta[k] * t.beta[k] * wk;
        }
        const double below = planes_->triangleOffsetNow(t) - t.normal.dot(p);
        if (!(below > 0.0)) return;
        double lambda = 0.0;
        if (t.mover >= 0) {
            lambda = below / (weight + t.give);
            if (!planes_->movers[std::size_t(t.mover)].take(lambda, t.normal, t.lever))
                lambda = 0.0;
        }
        if (lambda == 0.0) {
            if (!(weight > 0.0)) return;
            lambda = below / weight;
        }
        for (int k = 0; k < 3; ++k) {
            const Index c = t.corner[k];
            if (w[c] > 0.0 && t.beta[k] != 0.0) moveBy(c, (t.beta[k] * w[c] * lambda) * dir[k]);
        }
        t.push += lambda * t.normal;
    }
    /// Particle i's entry in planes_->carried (a particle a mover carries), or -1.
    std::int32_t carriedEntry(Index i) const {
        return planes_->carriedOf.empty() ? -1 : planes_->carriedOf[i];
    }
    /// Whether a spring between particles a and b, both held, links something the walk can
    /// move: an end a body carries, the other held elsewhere (posts a banner hangs between, a
    /// post and a pin). A spring whose ends one body carries moves rigidly with it: no link.
    bool carriedApart(Index a, Index b) const {
        if (!planes_ || planes_->carriedOf.empty()) return false;
        const std::int32_t ca = planes_->carriedOf[a], cb = planes_->carriedOf[b];
        if (ca < 0 || cb < 0) return ca >= 0 || cb >= 0;
        return planes_->carried[std::size_t(ca)].mover != planes_->carried[std::size_t(cb)].mover;
    }
    /// Whether the walk can correct the spring between a and b (inverse masses wa, wb).
    bool linked(Index a, Index b, double wa, double wb) const {
        return wa + wb != 0.0 || carriedApart(a, b);
    }
    /// Mover m's carried particles follow it: each moved by moveBy(particle, dx).
    template <class MoveBy>
    void moveCarried(std::int32_t m, const std::vector<Vec3>& x, MoveBy&& moveBy) {
        const ContactPlanes::Mover& b = planes_->movers[std::size_t(m)];
        const double angle = b.turn.norm();
        const Eigen::Matrix3d R = angle > 0.0
                                      ? Eigen::AngleAxisd(angle, b.turn / angle).toRotationMatrix()
                                      : Eigen::Matrix3d::Identity();
        const Vec3 centre = b.centre + b.shift;
        for (std::size_t k = b.carriedBegin; k < b.carriedEnd; ++k) {
            const ContactPlanes::Carried& c = planes_->carried[k];
            const Vec3 dx = centre + R * c.lever - x[c.particle];
            if (dx != Vec3::Zero()) moveBy(c.particle, dx);
        }
    }
    /// A correction that would move free particle i (inverse mass wi) by dx toward the
    /// particle of carried entry c: its body takes its share (Gauss-Seidel with the body's
    /// inverse mass along dx there) and moves its carried particles by moveBy. Returns i's
    /// share of dx (dx itself when the body cannot take it: ContactPlanes::Mover::take).
    template <class MoveBy>
    Vec3 shareWithCarrier(std::int32_t c, const Vec3& dx, double wi, const std::vector<Vec3>& x,
                          MoveBy&& moveBy) {
        const double len = dx.norm();
        if (!(len > 0.0)) return dx;
        const Vec3 u = dx / len;
        const ContactPlanes::Carried& e = planes_->carried[std::size_t(c)];
        ContactPlanes::Mover& b = planes_->movers[std::size_t(e.mover)];
        const Vec3 lever = planes_->carriedLever(e);
        const double lambda = len / (wi + b.giveAlong(u, lever)); // [kg m]
        if (!b.take(lambda, u, lever)) return dx;                 // the body's point moves along -u
        moveCarried(e.mover, x, moveBy);
        return (wi * lambda / len) * dx;
    }
    /// The walk keeps `planes` when there are any, one entry of `of` per particle (n).
    void usePlanes(ContactPlanes* planes, const std::vector<double>& invMass) {
        planes_ = planes != nullptr && planes->any() && planes->of.size() == invMass.size()
                      ? planes
                      : nullptr;
        planeInvMass_ = &invMass;
    }
    /// Applies the corrections of the sorted wave order_; returns how many particles it moved
    /// (listed in dirty_). kPlanes: contact planes are set (planes_); kRecordHeld: held ends
    /// take the corrections' reactions (heldPull()).
    template <bool kPlanes, bool kRecordHeld>
    std::size_t correctWave(const std::vector<Spring>& springs, const std::vector<double>& invMass,
                            std::vector<Vec3>& x, StrainLimitStats& st);
    /// Checks the springs of the first movedCount particles of dirty_ and queues those that
    /// need a correction into the next wave.
    void checkMoved(const ClothTopology& topology, const std::vector<double>& invMass,
                    const std::vector<double>& stiffness, const std::vector<Vec3>& x,
                    std::size_t movedCount, StrainLimitStats& st);
    void runWaves(const ClothTopology& topology, const std::vector<double>& invMass,
                  const std::vector<double>& stiffness, const LimiterSettings& s,
                  std::vector<Vec3>& x, StrainLimitStats& st);
    /// Queues spring si if it needs a correction at the current x; returns its (l / L0)^2
    /// (0 if it was queued already).
    double check(std::size_t si, const ClothTopology& topology, const std::vector<double>& invMass,
                 const std::vector<double>& stiffness, const std::vector<Vec3>& x,
                 StrainLimitStats& st);

    /// Spring si at (l / L0)^2 = ratio2 is beyond the band, or a warm-started spring below it.
    bool needs(std::size_t si, double ratio2) const {
        return ratio2 > upper2_ || (warmLeft_[si] > 0.0 && ratio2 < lower2_);
    }
    /// Puts spring si into the next wave, keyed by its tension k (l - L0).
    void queue(std::size_t si, double ratio2, double restLength,
               const std::vector<double>& stiffness) {
        key_[si] = stiffness[si] * restLength * (std::sqrt(ratio2) - 1.0);
        queued_[si] = 1;
        next_.push_back(static_cast<std::uint32_t>(si));
    }
    /// Fills maxStrainAfter (see StrainLimitStats).
    void finish(const ClothTopology& topology, const std::vector<Vec3>& x,
                StrainLimitStats& st) const;

    /// The wave being walked, most stressed first: sort keys (waveKey in strain_limit.cpp),
    /// the spring's index in the low 32 bits.
    std::vector<std::uint64_t> order_;
    std::vector<double> lambda_;   ///< accumulated correction per spring
    std::vector<double> warmLeft_; ///< warm start a let-out may still undo this step
    /// The springs whose lambda may be nonzero (each once: inWarmList_); the first
    /// warmSorted_ are in index order, the rest were added by this step's walks. Rebuilt from
    /// lambda_ when !warmListValid_ (after a restore or reset).
    std::vector<std::uint32_t> warmList_;
    std::vector<unsigned char> inWarmList_;
    std::size_t warmSorted_ = 0;
    bool warmListValid_ = false;
    /// Puts warmList_ in index order (sorting only what the last step added).
    void sortWarmList();
    std::vector<unsigned char> queued_; ///< spring is in the next wave
    std::vector<std::uint32_t> wave_, next_;
    std::vector<double> key_; ///< stress of each queued spring
    /// Per spring: the wave stamp of its last check times 2, plus kWarmBit when warmLeft_ > 0
    /// (the checks after a wave read both with one load).
    std::vector<std::uint32_t> checkedAt_;
    static constexpr std::uint32_t kWarmBit = 1u;
    /// A spring's check word with its warm bit set from its warmLeft_ value.
    static std::uint32_t withWarmBit(std::uint32_t word, double left) {
        return (word & ~kWarmBit) | static_cast<std::uint32_t>(left > 0.0);
    }
    /// Every warm bit off (warmLeft_ was zeroed).
    void clearWarmBits() {
        for (std::uint32_t& c : checkedAt_)
            c &= ~kWarmBit;
    }
    static constexpr std::uint32_t kStampEnd = 0x80000000u; ///< stamps stay below (2 stamp fits)
    std::vector<std::uint32_t> dirtyAt_; ///< per particle: the wave stamp of its last move
    std::vector<Vec3> warmMove_;         ///< warm start scratch: lambda d / l of each listed spring
    std::vector<Index> dirty_;           ///< particles the current wave moved (the first of them)
    /// Adjacency entries of the springs the checks after a wave found in need of a correction
    /// (one per adjacency entry at most, +1: the last write).
    std::vector<Index> candidates_;
    std::uint32_t stamp_ = 0;
    std::vector<unsigned char> moved_;
    std::vector<Index> movedIndex_;
    std::vector<Vec3> movedFrom_;
    bool recordHeld_ = false;
    std::vector<unsigned char> pulled_; ///< per particle: listed in heldIndex_
    std::vector<Index> heldIndex_;
    std::vector<Vec3> heldPull_; ///< per particle (nonzero for heldIndex_ only) [kg m]
    AnchorField anchors_;
    Executor* executor_ = nullptr;
    std::vector<double> soa_;    ///< scan scratch: x of every particle, then y, then z
    std::vector<double> ratio2_; ///< scan scratch: (l / L0)^2 per family slot
    /// The scan's segments of kScanSegment slots and the largest ratio of each.
    static constexpr std::size_t kScanSegment = 16384;
    std::vector<double> segmentWorst_;
    ContactPlanes* planes_ = nullptr;                   ///< during a walk with planes only
    const std::vector<double>* planeInvMass_ = nullptr; ///< the particles' (with planes_)
    /// The long-range attachments are on and anchored (prepare): a mover's plane pushes a
    /// particle only as far as its attachment leaves room (keepAbove).
    bool anchorsHold_ = false;
    std::vector<Index> anchorList_;
    std::vector<Index> beyondReach_; ///< scratch: the particles beyond their anchors' reach
    /// scratch, per block of kScanSegment particles: how many are beyond reach, and how many
    /// free ones have an anchor (evaluated)
    std::vector<std::size_t> blockBeyond_, blockAnchored_;
    std::vector<std::size_t> blockHeld_; ///< scratch: held particles per block (prepare)
    bool anchorsValid_ = false;
    /// The particles with zero inverse mass of the last pinsApart check, and the shortest
    /// rest-length path through the springs between every two of them (row-major; infinity
    /// where none), rebuilt when that set changes.
    std::vector<Index> pinList_, pinScratch_;
    std::vector<double> pinPath_;
    /// Whether two of the particles that never move are farther apart than the bound lets
    /// the springs between them reach (StrainLimitStats::pinsApart). Skipped (false) for more
    /// than kMaxApartPins such particles.
    bool pinsApart(const ClothTopology& topology, const std::vector<double>& invMass,
                   const std::vector<Vec3>& x);
    double anchorSlack_ = 0.0; ///< the slack anchors_.restDistance was made with
    double upper2_ = 0.0, lower2_ = 0.0, limit_ = 0.0; ///< band edges (squared) and the limit
};

/// Provot (1995): sweeps over the springs in index order; an overstretched spring is
/// shortened to (1 + maxStrain) L0, moving both ends by their inverse-mass share (only the
/// free end if one is fixed, nothing if both are). Sweeps until every spring is within
/// maxStrain + tolerance or maxRounds sweeps have run. Kept for comparison.
StrainLimitStats limitStrainProvot(const ClothTopology& topology,
                                   const std::vector<double>& invMass, const LimiterSettings& s,
                                   std::vector<Vec3>& x);

/// The paper's figure 5 read literally (LimiterKind::StressOrderedOneSided, for comparison
/// only): particles in decreasing spring tension (pinned first); each pulls every
/// overstretched, not yet regulated neighbour the whole way to the limit and regulates it;
/// rounds repeat until within maxStrain + tolerance or maxRounds. One-sided pulls create
/// momentum: on Experiment I the sheet blows up whatever the order.
StrainLimitStats limitStrainOneSided(const ClothTopology& topology,
                                     const std::vector<double>& invMass,
                                     const std::vector<double>& stiffness, const LimiterSettings& s,
                                     std::vector<Vec3>& x);

/// Largest strain (l - L0) / L0 over all springs (negative if all are compressed).
double maxSpringStrain(const ClothTopology& topology, const std::vector<Vec3>& x);
/// Mean strain over all springs.
double meanSpringStrain(const ClothTopology& topology, const std::vector<Vec3>& x);

} // namespace drape
