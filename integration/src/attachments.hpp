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

#include <vector>

namespace drape::bullet::detail {

class Attachments {
  public:
    const std::vector<Attachment>& list() const { return list_; }
    /// Attaches a.particle to a.body (replacing an attachment it had); the arguments are checked.
    void attach(Cloth& c, const Attachment& a);
    /// Returns the particle to free motion (nothing if it is not attached).
    void detach(Cloth& c, Index particle);
    /// Detaches every particle.
    void clear(Cloth& c);
    /// A Bullet sub-step of dt begins: every attached particle gets its point on the body as
    /// the body is now as the target it reaches at the end of the sub-step.
    void advance(Cloth& c, double dt) const;
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
                    ContactStats& stats, std::vector<OutsideImpulse>& outside) const;

  private:
    std::vector<Attachment> list_;
};

/// Where attachment a's point on its body is now [m].
Vec3 attachmentPoint(const Attachment& a);

} // namespace drape::bullet::detail
