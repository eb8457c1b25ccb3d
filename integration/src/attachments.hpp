// attachments.hpp (private to drape::bullet): particles attached to bodies. An attached
// particle is a kinematic particle of the cloth driven by data: at the start of every Bullet
// sub-step it gets its point on the body as it is now as the target it reaches at the end of
// the sub-step (Cloth::setKinematicTarget; the cloth's sub-steps interpolate). For a dynamic body
// the force the cloth puts on the particle (springs and its own weight) and the strain
// limiter's reaction on it (Cloth::constraintImpulses) go to the body.
#pragma once

#include "body_snapshot.hpp"

#include "drape/bullet/settings.hpp"
#include "drape/cloth.hpp"

#include <cstdint>
#include <optional>
#include <unordered_map>
#include <vector>

class btDynamicsWorld;

namespace drape::bullet::detail {

class Attachments {
  public:
    const std::vector<Attachment>& list() const { return list_; }
    /// Within a Bullet sub-step: each particle attached to a carrier (BodySnapshot::carrier,
    /// one of `bodies`) gets its point on the body's snapshot as its kinematic target
    /// at `arrival` [s] (the snapshot moves with what the cloth gave the body).
    void followBodies(Cloth& c, const std::vector<BodySnapshot>& bodies, double arrival);
    /// Attaches a.particle to a.body (replacing an attachment it had); the arguments are checked.
    void attach(Cloth& c, const Attachment& a);
    /// Returns the particle to free motion (nothing if it is not attached).
    void detach(Cloth& c, Index particle);
    /// Detaches every particle.
    void clear(Cloth& c);
    /// A Bullet sub-step of dt begins: every attached particle gets its point on the body as
    /// the body is now as the target it reaches at the end of the sub-step.
    void advance(Cloth& c, double dt) const;
    /// Before a Bullet sub-step (before carryTeleported): an attached particle of a static or
    /// kinematic body that is neither where the body's pose at the last call put it nor where
    /// its pose now puts it was moved by the program (a reset to the rest shape, a snapshot
    /// restored after the body moved): it is put on its point now as a teleport of a held
    /// particle (Cloth::setPosition: the next step brings the rest of the cloth within the
    /// bound as positions), not pulled there by its target at the speed of the gap; when all
    /// were moved, the whole cloth first goes with the rigid motion that best puts them there.
    void placeMoved(Cloth& c) const;
    /// Before a Bullet sub-step of dt [s] (before advance): when every attachment body moved
    /// by one rigid motion since the last sub-step and a point of an attachment moved faster
    /// than `speed` [m/s] or the motion turned by more than `turn` [rad] (a teleport or a
    /// snap turn; 0: never), moves the whole cloth with it (positions
    /// carried, velocities turned) and returns that motion (world to world). Not for a cloth
    /// with particles the program pinned. Remembers every attachment body's pose for the next
    /// call.
    std::optional<Pose> carryTeleported(Cloth& c, double dt, double speed, double turn);
    /// The poses kinematic bodies have in this Bullet sub-step (followKinematic): the
    /// attachments' points follow them. The map must live while the sub-step's calls above
    /// (placeMoved, carryTeleported, advance) use it.
    void followPoses(const std::unordered_map<const btCollisionObject*, Pose>* poses) {
        followed_ = poses;
    }
    /// The body's pose in this sub-step: followed, or its world transform.
    Pose poseOf(const btCollisionObject* body) const;
    /// The attachment's point in this sub-step (poseOf its body).
    Vec3 pointOf(const Attachment& a) const { return poseOf(a.body).toWorld(a.localPoint); }
    /// An impulse j [N s] at `at` for a dynamic body that is not among the snapshots.
    struct OutsideImpulse {
        btRigidBody* body = nullptr;
        Vec3 j = Vec3::Zero(), at = Vec3::Zero();
    };
    /// After a cloth step of h [s]: dynamic bodies get the impulse of the force the cloth put
    /// on their attached particles (through their snapshot, or, when the body is not among
    /// them, appended to `outside` for the caller to apply after the sub-step: the cloth's
    /// steps touch no Bullet body, so cloths can step in parallel), counted in
    /// stats.impulseOnBodies.
    void pushBodies(const Cloth& c, double h, std::vector<BodySnapshot>& bodies,
                    ContactStats& stats, std::vector<OutsideImpulse>& outside);
    /// After the cloth's steps of a Bullet sub-step of dt [s]: a spring whose two ends are
    /// attached to two different bodies, one of them dynamic, has no free end, so no
    /// strain-limiter walk can hold it; it holds the bodies instead, as a rope: beyond
    /// (1 + maxStrain) L0, the two bodies (their snapshots) get equal and opposite impulses
    /// along it that stop their ends' separation and take the stretch beyond the limit back
    /// in the next step (at most kTetherCatchUp L0 per step). Without it two light bodies
    /// holding one cloth (a banner between two hanging posts) swing apart under the cloth's
    /// weight and that spring passes the bound at rest (strain 0.56). The impulses act one
    /// Bullet step late, after Bullet's solver (as every impulse of the cloth), so they are
    /// solved with the world's joints on those bodies and the next step's gravity
    /// (solveTautWithJoints, `world` given): alone, Bullet's next solve turned hanging posts
    /// on their joints and left the spring a step's drift beyond the limit (0.11).
    ///
    /// The same rope holds a body the cloth carries from elsewhere (a weight hanging from a
    /// pinned cloth, a lantern under a banner): every particle attached to a body has a reach,
    /// (1 + maxStrain) times the rest length of the spring path to the nearest held particle
    /// that is not on the same body (pinned, or attached to another body), as the limiter's
    /// long-range attachments measure it (geodesicAnchors). Beyond it, the body gets the
    /// impulse that stops it moving away (and the rest of the stretch back, as above), two
    /// steps' fall of gravity along the rope (kReachMargin g dt^2) inside the reach but never
    /// shorter than the rest path, so that Bullet's next step does not carry it beyond; a
    /// dynamic body at the other end the opposite one. The taut ropes are solved together. The
    /// limiter cannot: it moves neither end. Without it the body fell through, drawing the cloth to
    /// strain 3.4 in 0.5 s (10 kg under a 0.16 kg sheet), and a light one (0.05 to 1 kg) was thrown
    /// about.
    void holdTethers(const Cloth& c, double dt, std::vector<BodySnapshot>& bodies,
                     btDynamicsWorld* world = nullptr);
    static constexpr double kTetherCatchUp = 0.1;
    /// A reach's rope holds its body this many times g dt^2 inside the reach (see holdTethers).
    static constexpr double kReachMargin = 2.0;
    /// Passes over the taut reaches (projected Gauss-Seidel, see holdTethers).
    static constexpr int kReachIterations = 8;
    /// Passes of solveTautWithJoints.
    static constexpr int kJointPasses = 20;

  private:
    std::vector<Attachment> list_;
    std::vector<const BodySnapshot*> carriers_; ///< followBodies' scratch
    std::vector<Index> carried_;                ///< pushBodies' scratch: a carrier's particles,
    std::vector<Vec3> levers_;                  ///< their levers
    std::vector<double> masses_;                ///< and masses
    /// Each attachment body's pose at the last carryTeleported.
    std::vector<std::pair<const btCollisionObject*, Pose>> seen_;
    /// The pose of each body attached to since the last carryTeleported (and not seen then),
    /// where its attachments put their particles: a static or kinematic body moved before the
    /// first step after it was attached to is placed, and carries the cloth (review 21: a kinematic
    /// box created at the origin and set 0.4 m away before the first step dragged its cape at 24
    /// m/s, 14 ms).
    std::vector<std::pair<const btCollisionObject*, Pose>> attachedAt_;
    /// Of BulletClothSettings::teleportSpeed, the speed beyond which such a move is a
    /// placement (slower, it is motion: a hand that picks a cloth up and moves on).
    static constexpr double kPlacementShare = 0.2;
    /// Kinematic bodies' poses in this Bullet sub-step (followKinematic), set by the world's
    /// step (followPoses); null: every body at its world transform.
    const std::unordered_map<const btCollisionObject*, Pose>* followed_ = nullptr;
    /// The springs between particles attached to two different bodies and their two
    /// attachments' indices in list_, rebuilt after list_ changes.
    struct Tether {
        Index spring;
        std::size_t a, b;
    };
    std::vector<Tether> tethers_;
    /// The reach of attachment k: the held particle `anchor` (its attachment index, or -1 for
    /// a particle pinned by the program) and the rest length of the path between them.
    struct Reach {
        std::size_t k;
        Index anchor;
        std::int64_t anchorK;
        double length;
    };
    std::vector<Reach> reaches_;
    /// The held particles and the slack the reaches were measured for (a pin set or removed
    /// by the program changes them).
    std::vector<Index> reachHeld_;
    double reachSlack_ = 0.0;
    bool tethersValid_ = false;
    void buildTethers(const Cloth& c);
    /// A rope between the bodies at pa (A, null for a pin moving at va) and pb (B), taut
    /// beyond `room`: listed in taut_ when it is, with its catch-up (the stretch beyond, at
    /// most catchUpLimit [m], taken back in the step).
    void addTaut(BodySnapshot* A, const Vec3& pa, const Vec3& va, BodySnapshot& B, const Vec3& pb,
                 double room, double catchUpLimit, double dt);
    /// Equal and opposite impulses on the bodies of taut_ that stop their ends' separation,
    /// over `passes` passes (see holdTethers).
    void solveTaut(int passes);
    /// solveTaut for the ropes between two bodies, with the world's joints on their bodies and
    /// the next Bullet step's gravity in the same projected Gauss-Seidel (on copies of the
    /// velocities): the ropes' impulses are what keeps their ends together after Bullet's next
    /// solve turns the bodies on their joints. Only the ropes' impulses are applied.
    void solveTautWithJoints(btDynamicsWorld& world, std::vector<BodySnapshot>& bodies, double dt);
    /// The catch-up of a reach per step: kTetherCatchUp of the cloth's shortest spring.
    double reachCatchUp_ = 0.0;
    /// A taut rope in this step: its bodies (A null for a pin moving at va), ends, direction
    /// from A to B, catch-up speed, inverse mass along it and the impulse it has given.
    struct Taut {
        BodySnapshot* A;
        BodySnapshot* B;
        Vec3 pa, pb, va, u;
        double catchUp, k, impulse;
    };
    std::vector<Taut> taut_;
};

/// Where attachment a's point on its body is now [m].
Vec3 attachmentPoint(const Attachment& a);

/// The particles of `attached` that body b carries (BodySnapshot::carrier; kinematic: zero
/// inverse mass in c), with their levers from its centre of mass where they are now and their
/// masses (what carrierMatrices reads).
void carriedParticles(const std::vector<Attachment>& attached, const Cloth& c,
                      const BodySnapshot& b, std::vector<Index>& particles,
                      std::vector<Vec3>& levers, std::vector<double>& masses);

} // namespace drape::bullet::detail
