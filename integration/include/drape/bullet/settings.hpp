// drape/bullet/settings.hpp: the plain data of a cloth in a Bullet world: its settings
// (contacts, self-collision, sub-steps, collision filter, sleep), the work counts of its
// steps, and an attachment record. No Bullet header; included by bullet_cloth.hpp.
#pragma once

#include "drape/mesh.hpp"
#include "drape/settings.hpp"

#include <cstdint>
#include <optional>

class btCollisionObject;

namespace drape::bullet {

/// Contacts between cloth particles and rigid bodies.
struct ContactSettings {
    /// Distance a particle keeps from every body surface [m]. Particles nearer than this are
    /// projected out to it; it is the cloth's collision thickness. Must be > 0. Keep it
    /// between about a twentieth and a third of the cloth's spacing over boxes (README: a 4 cm
    /// mesh at 1 mm crept off a box table through its box-edge contacts).
    double thickness = 0.01;
    /// Width of the band above `thickness` in which eq. (7)'s penalty force acts [m]; > 0
    /// unless the penalty is off. Not given: equal to `thickness`.
    std::optional<double> penaltyBand;
    /// C_p of eq. (7): the most the penalty pushes a particle at the bottom of the band [N].
    /// It slows particles coming down into the band and holds them where it can carry their
    /// load (a cloth landing on a body rests inside the band), but against static and kinematic
    /// bodies it never pushes more than stops the particle: a cloth placed at the thickness
    /// stays there. Not given: twice the particle's weight under the cloth's gravity. 0 turns
    /// the penalty off (particles then rest at the thickness); must be >= 0.
    std::optional<double> penaltyForce;
    /// Multiplies the body's btCollisionObject friction coefficient (Coulomb mu) [-].
    double frictionScale = 1.0;
    /// How fast a particle that starts a cloth step inside a body (a cloth placed or teleported
    /// into a body, a body moved, grown or created round a cloth) is moved out of it [m/s]: at
    /// most this far per second, all the way out to the thickness (a spring with an end on its
    /// way out is not pushed off a box's edge meanwhile). Moved out in one step, it dragged
    /// its neighbours with it through the strain limiter at the depth over the step (a sheet
    /// placed inside a 2 m box left it at 1,460 m/s; a box moved 4 cm up under a resting
    /// cloth threw it 2 m high). Must be > 0 and finite.
    double depenetrationSpeed = 1.0;
    /// Ray-test the path of particles that moved more than `thickness` in a step, so that a
    /// fast particle does not pass through a thin body between two steps; and sweep every
    /// moving convex body that moves more than `thickness` in a step, or is thinner across
    /// than the cloth's longest spring, against the cloth's triangles on its way (a
    /// projectile, a thin rod, a small ball: none passes between the particles).
    bool continuous = true;
    /// Also keep the cloth's triangles (their edges and interiors) `thickness` away from
    /// convex bodies and the convex children of compounds, so that a feature thinner than the
    /// particle spacing (a rod, a box's edge) cannot pass between particles. The response is
    /// shared among the triangle's particles by their barycentric weights, two-way with dynamic
    /// bodies. Off by default: it costs a box test per triangle and body near the cloth, and
    /// a GJK query per triangle within reach of a body that not all its particles touch
    /// (review 15: a 41 x 41 tablecloth settling on a box table, 56 ms a frame instead of 3.5;
    /// a curtain and a cape on moving bodies, 2-3 times the cost).
    bool triangles = false;
    /// Keep every spring with an end touching a box (btBoxShape) `thickness` away from the
    /// box along its whole length, so that the box's edges and corners do not show through the
    /// cloth between particles draped over them (a segment-box test per such spring; the
    /// spring's ends share the push and the stopping impulse by their weights, two-way with
    /// dynamic boxes). On by default: it costs a few box distance evaluations per spring
    /// touching a box. Other convex shapes need `triangles` for their edges.
    bool boxEdges = true;
    /// Margin added around the cloth's bounding box for its broadphase proxy [m] (>= 0). Not
    /// given: the cloth's mean spring rest length plus four thicknesses.
    std::optional<double> broadphaseMargin;
};

/// Collision of the cloth's particles with its own triangles is the cloth's own
/// (drape::SelfCollisionSettings, ClothSettings:: selfCollision): the name stays here for programs
/// written against drape::bullet.
using SelfCollisionSettings = drape::SelfCollisionSettings;

/// How a cloth joins a world. The defaults are in SI units (metres); a world in another
/// length unit starts from inUnits().
struct BulletClothSettings {
    /// The defaults for a world whose lengths are in units of 1 / unitsPerMetre metres (100:
    /// centimetres): the contact thickness and the self-collision thickness (1 cm) times
    /// unitsPerMetre; with ClothSettings::inUnits for the cloth, a cloth in a centimetre world
    /// behaves as the same cloth in metres. Values set afterwards are in the world's units.
    /// Throws drape::Error (InvalidArgument) unless unitsPerMetre is in [1e-6, 1e6].
    static BulletClothSettings inUnits(double unitsPerMetre);
    /// The world's lengths per metre (inUnits sets it; 1: metres): the unit of the speeds
    /// drape::bullet compares with on its own (the 1 m/s floor of ContactStats::
    /// refusedBodyImpulses). Must be in [1e-6, 1e6]. Set without inUnits while two or more of
    /// the lengths and speeds below (contact.thickness, contact.depenetrationSpeed,
    /// teleportSpeed, selfCollision.thickness, clothCollision.thickness) keep their defaults
    /// in metres, addCloth refuses it, naming them.
    double unitsPerMetre = 1.0;

    ContactSettings contact; ///< particle-body contacts
    /// Particle-triangle self-collision: when enabled, addCloth sets it as the cloth's own
    /// ClothSettings::selfCollision (Cloth::setSelfCollision), which the cloth's step runs.
    SelfCollisionSettings selfCollision;
    /// Cloth steps per internal Bullet sub-step (>= 1, and at most the cloth's
    /// ClothSettings::substeps.maxSubsteps, 1000 by default; addCloth refuses more with a
    /// drape::Error InvalidArgument): a stiff cloth runs at
    /// fixedTimeStep / substeps while the rigid bodies keep the world's step. Not given (the
    /// default): Cloth::substepsFor, chosen in every sub-step: the fewest cloth steps within
    /// ClothSettings::substeps.fraction (90 %) of the cloth's stability limit, or 1 if the
    /// cloth's automatic sub-steps are off. Cloths that may meet in a sub-step
    /// (collideWithCloths) take the most that any of them asks for. With the cloth's automatic
    /// sub-steps on, each of these steps is split further as the cloth needs; with them off, a
    /// count whose steps exceed the cloth's stability limit is refused in the world step
    /// (drape::Error UnstableTimeStep) with the least count that is stable.
    std::optional<int> substeps;
    /// The cloth's exact time step [s] (> 0). Bullet hands its sub-step to the cloth as a
    /// btScalar (a float in Debian's build): 1/60 s arrives as 0.016666668. When the sub-step
    /// equals this value rounded to btScalar, the cloth steps with this double instead, so a
    /// cloth in a world stepped by stepSimulation follows the same path as one stepped alone
    /// with this dt. Not given (or another sub-step): the btScalar step, widened to double.
    std::optional<double> timeStep;
    /// Use the world's gravity for the cloth: copied when it is added and whenever the world's
    /// changes (btDynamicsWorld::setGravity to another value), so a gravity the program sets on
    /// the cloth itself (Cloth::setGravity) holds until the world's next change. drape's
    /// default gravity is -9.81 m/s^2 along y, Bullet's is -10.
    bool useWorldGravity = true;
    /// Broadphase filter group and mask of the cloth's proxy (Bullet's collision filtering).
    int collisionGroup = 1; ///< btBroadphaseProxy::DefaultFilter
    int collisionMask = -1; ///< btBroadphaseProxy::AllFilter
    /// Turn the cloth's sleeping on when it is added (with the thresholds of its
    /// ClothSettings::sleep); false leaves the cloth's own setting.
    bool sleep = true;
    /// Threads (>= 1) on which the cloths of this cloth's world take their steps: every
    /// Bullet sub-step, each cloth's steps are one task, run on up to the largest `threads`
    /// among the world's cloths, and at most the machine's hardware threads (a oneTBB arena of
    /// that many threads, the calling thread included). Each cloth's result is bit-identical for
    /// any count. 1 (the default): every cloth steps on the thread that calls stepSimulation, one
    /// after the other. A cloth whose ClothSettings::threads is more than 1 and that has no
    /// executor of its program (Cloth::setExecutor) splits its own passes in the world's arena
    /// (nested, isolated tasks: one set of threads for both levels; the arena then has the
    /// largest of both settings, and it exists for that cloth even when this is 1); taken out
    /// of the world, it runs on its own pool again.
    int threads = 1;
    /// Teleports [m/s, times unitsPerMetre]: when every body the cloth is attached to
    /// (BulletCloth::attach) moved by one rigid motion in a Bullet sub-step, and a point of an
    /// attachment on it moved faster than this (a game that sets a character's transform to
    /// where it respawns), the whole cloth is moved with the body before the sub-step, its
    /// velocities turned with it: a cape comes along with its character instead of being
    /// dragged there by its attached row at the speed of the jump (a 2 m jump of a kinematic
    /// capsule was 120 m/s and cost up to 1.6 s of CPU a frame). Not for a cloth that is also
    /// pinned by the program or attached to bodies that moved differently. A body truly this fast
    /// is carried too (its cloth does not trail). Counted in ContactStats::teleports.
    /// A kinematic body the cloth is not attached to whose fastest point moves faster than this
    /// (or that turns by more than teleportTurn) in a Bullet sub-step is taken as put where it
    /// is, not swept there (a game that sets a platform's or a door's motion state to where it
    /// resets: Bullet's velocity is the jump over the sub-step; a box set 2 m across a curtain
    /// swept through it at 120 m/s, 4 s of CPU in that frame and the curtain thrown at 200
    /// m/s): particles it lands on come out at contact.depenetrationSpeed. Counted in
    /// ContactStats::jumpedBodies. A kinematic body that truly moves this fast needs a higher
    /// value. 0 turns both off; must be >= 0 and finite.
    double teleportSpeed = 50.0;
    /// Snap turns [rad]: when every body the cloth is attached to turned by one rigid motion
    /// by more than this in a Bullet sub-step (a game that sets its character facing the
    /// other way in one frame), the cloth is carried with it as for a teleport: a skirt on a
    /// character flipped half a turn was twisted round by its attached ring, 0.4-0.6 s of CPU
    /// in that frame, its hem thrown above the hips. Pi / 4 (45 degrees a 60 Hz frame, 47
    /// rad/s) is far beyond a body turning by physics; 0 turns it off; must be in [0, pi].
    double teleportTurn = 0.7853981633974483;
    /// Collision with the world's other cloths: after every Bullet sub-step, each pair of
    /// cloths whose paths came within reach of each other and whose filters let them meet
    /// (collisionGroup and collisionMask, both ways) is kept apart by drape::collideCloths
    /// (drape/cloth_pair.hpp): the particles of each keep the larger of the two cloths'
    /// clothCollision.thickness from the other's triangles, on the side they were on, with
    /// the geometric mean of their frictions, in the larger of their iterations. A cape over a
    /// skirt, a towel dropped on a tablecloth. false for either cloth: the two pass through
    /// each other. Counted in ContactStats::clothContacts.
    bool collideWithCloths = true;
    /// Thickness (scaled by inUnits), friction and iterations of the collision with other
    /// cloths; validated when the cloth is added.
    ClothPairSettings clothCollision;
};

/// Work done in the last Bullet sub-step (all cloth sub-steps summed). Counts, not times, so
/// tests can check that the broadphase is used.
struct ContactStats {
    std::size_t candidateBodies = 0;    ///< bodies among the proxy's broadphase overlaps
    std::size_t particleBoxTests = 0;   ///< particle against body-AABB rejection tests
    std::size_t narrowphaseQueries = 0; ///< closest-point queries against body shapes
    std::size_t rayQueries = 0;         ///< continuous (swept) ray tests
    std::size_t triangleQueries = 0;    ///< triangle-body GJK queries (contact.triangles)
    std::size_t triangleContacts = 0;   ///< triangle-body contacts that moved a triangle
    /// Triangles a body faster than the thickness per cloth step reached on its way and moved
    /// ahead of it (contact.continuous; their queries count in triangleQueries).
    std::size_t sweptTriangles = 0;
    std::size_t edgeContacts = 0; ///< springs moved out of a box they cut into (boxEdges)
    /// Sub-steps in which the cloth was carried with the bodies it is attached to
    /// (BulletClothSettings::teleportSpeed).
    std::size_t teleports = 0;
    /// Kinematic bodies near the cloth taken as put where they are in a sub-step, not swept
    /// there: they moved faster than teleportSpeed or turned by more than teleportTurn
    /// (BulletClothSettings::teleportSpeed), once per body and Bullet sub-step.
    std::size_t jumpedBodies = 0;
    /// Particle-body contacts: particles touching a body (projected, or resting at the
    /// thickness) or, with eq. (7) on, inside its band; once per particle and body per cloth
    /// step, summed over the sub-steps.
    std::size_t contacts = 0;
    std::size_t projections = 0; ///< contacts that moved a particle out of a body
    /// Contacts of a dynamic body with a particle that a static or kinematic body holds from
    /// behind (a crate landing on, or resting on, a rug on the floor): the body's approach is
    /// stopped there as against the body behind, and the particle is not moved into it.
    std::size_t heldBetween = 0;
    /// Deepest a particle (or a triangle, with contact.triangles) was found inside a body's
    /// contact thickness before it was moved out: thickness - distance, 0 without
    /// projections; in totalStats() the largest of any sub-step [m].
    double maxDepth = 0.0;
    /// The largest spring strain (l - L0) / L0 at the end of the Bullet sub-step, measured
    /// (Cloth::maxStrain(), one pass over the springs per sub-step); in totalStats() the
    /// largest at the end of any sub-step [-]. Compare with the limit
    /// (ClothSettings::limiter.maxStrain) to see whether the bound held in every world step.
    double maxStrain = 0.0;
    /// Bullet sub-steps that ended with a spring beyond the limiter's promise,
    /// limiter.maxStrain + limiter.tolerance (maxStrain above it; 0 without a limiter): the
    /// bound broken, whatever broke it (a walk stopped at its cap, counted in
    /// Cloth::limiterCapHits(), or contacts after the walk, which no cap counts).
    std::size_t boundBroken = 0;
    std::size_t selfContacts = 0;  ///< particle-triangle self contacts resolved
    std::size_t selfPairTests = 0; ///< particle-triangle pairs tested by self-collision
    /// Particle-triangle contacts with the world's other cloths (collideWithCloths), summed
    /// over both ways and the passes; the other cloth counts them too.
    std::size_t clothContacts = 0;
    std::size_t clothPairTests = 0; ///< particle-triangle pairs between cloths tested
    /// Total linear impulse the cloth gave dynamic bodies, through contacts and through
    /// attachments [N s].
    Vec3 impulseOnBodies = Vec3::Zero();
    /// Total linear impulse bodies (static, kinematic and dynamic) gave the cloth through
    /// contacts: velocity response, friction and contact forces over the step [N s]. With only
    /// dynamic bodies and no attachments it is exactly -impulseOnBodies.
    Vec3 impulseOnCloth = Vec3::Zero();
    /// Dynamic bodies whose impulses from the cloth in a Bullet sub-step were refused: they
    /// would have left a point of the body moving more than twice as fast as anything in the
    /// contact (the body's fastest point and the cloth's fastest particle before the sub-step,
    /// and 1 m/s: unitsPerMetre), which no cloth can do (an elastic bounce off an infinitely
    /// heavy wall gives twice its speed); the body
    /// keeps Bullet's state, and the cloth keeps the momentum the body did not take (not in
    /// impulseOnBodies). Also counted: a free body's share of one strain-limiter walk that would
    /// have turned it by more than half a turn (or to a non-finite place), which is not applied to
    /// it. Seen with thin fast bodies wedged between particles (integration/README.md, "Fast
    /// bodies"); 0 in every shipped scene and game.
    std::size_t refusedBodyImpulses = 0;
    /// Contact planes of static, kinematic and attached bodies that the strain limiter's walk
    /// let go of in a cloth step because they had pushed their particle out by more than the
    /// cloth's longest spring and more than carrying the whole cloth's weight over the step
    /// would push it, |g| M dt^2 / m (ContactPlanes::pushLimit): the walk was fighting the plane
    /// against springs it cannot satisfy together with it (a neighbour attached across the
    /// plane, two bodies pressing one particle from both sides), which is no contact. The particle
    /// is projected out of the body after the walk, and the springs stay as long as they are
    /// (maxStrain says by how much); what the plane pushed is exchanged with the body up to that
    /// length.
    std::size_t planesLetGo = 0;
    /// Strain-limiter walks run again inside the contact stage: after the walk, what it moved
    /// is projected against the bodies again (a curved body, a particle the walk pulled into a
    /// body it had no plane of), and where that moved particles the walk runs again from them
    /// (at most 8 a cloth step). Each is a round trip between the contacts and the limiter that
    /// the step as data (integration/README.md) would not need; 0 where the planes the walk
    /// kept were enough.
    std::size_t relimitWalks = 0;
    std::uint64_t steps = 0; ///< cloth steps taken by this handle since it was added
    /// Cloth steps per Bullet sub-step in the last sub-step, in all: BulletClothSettings::
    /// substeps (or the automatic count) times the steps the cloth's own automatic sub-steps
    /// split each into (1 when they are off).
    int substeps = 0;
    /// Sub-steps in which the cloth would have swept out of its proxy, so the proxy was moved
    /// and the broadphase queried directly (btBroadphaseInterface::aabbTest).
    std::size_t proxyRefreshes = 0;
};

/// A particle held at a point fixed in a body's frame.
struct Attachment {
    Index particle = 0;                      ///< cloth particle
    const btCollisionObject* body = nullptr; ///< the body it is fixed to
    Vec3 localPoint = Vec3::Zero();          ///< point in the body's frame [m]
};

} // namespace drape::bullet
