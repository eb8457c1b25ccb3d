// attachments.hpp (private to drape::bullet): particles attached to bodies. An attached
// particle is a kinematic particle of the cloth whose target is its point on the body: at the
// start of every Bullet sub-step the target moves from where the point was to where it is now,
// and the particle's path interpolates between the two over the sub-step. For a dynamic body
// the force the cloth puts on the particle (springs and its own weight) and the strain
// limiter's reaction on it (Cloth::constraintImpulses) go to the body.
#pragma once

#include "body_snapshot.hpp"

#include "drape/bullet/settings.hpp"
#include "drape/cloth.hpp"

#include <algorithm>
#include <memory>
#include <vector>

namespace drape::bullet::detail {

/// The attachment point at the start and end of the current Bullet sub-step [m].
struct KinematicTarget {
    Vec3 from = Vec3::Zero(), to = Vec3::Zero();
};

/// The current Bullet sub-step [s].
struct StepWindow {
    double t0 = 0.0, t1 = 1.0;
};

/// An attached particle's path (the cloth's KinematicPath): its target, interpolated over the
/// sub-step's window. Holds plain pointers into Attachments, which keeps every target at a
/// fixed address while it is attached and unpins the particle (dropping the path) before the
/// target goes.
struct TargetPath {
    const KinematicTarget* target = nullptr;
    const StepWindow* window = nullptr;
    Vec3 operator()(double t) const {
        const double span = window->t1 - window->t0;
        const double s = span > 0.0 ? std::clamp((t - window->t0) / span, 0.0, 1.0) : 1.0;
        return Vec3(target->from + s * (target->to - target->from));
    }
};

class Attachments {
  public:
    const std::vector<Attachment>& list() const { return list_; }
    /// Attaches a.particle to a.body (replacing an attachment it had); the arguments are checked.
    void attach(Cloth& c, const Attachment& a);
    /// Returns the particle to free motion (nothing if it is not attached).
    void detach(Cloth& c, Index particle);
    /// Detaches every particle.
    void clear(Cloth& c);
    /// A Bullet sub-step from t0 to t0 + dt begins: every target moves on to its point on the
    /// body as the body is now.
    void advance(double t0, double dt);
    /// After a cloth step of h [s]: dynamic bodies get the impulse of the force the cloth put
    /// on their attached particles (through their snapshot, or directly when the body is not
    /// among them), counted in stats.impulseOnBodies.
    void pushBodies(const Cloth& c, double h, std::vector<BodySnapshot>& bodies,
                    ContactStats& stats) const;

  private:
    std::vector<Attachment> list_;
    std::vector<std::unique_ptr<KinematicTarget>> targets_; ///< per attachment, fixed addresses
    StepWindow window_;
};

/// Where attachment a's point on its body is now [m].
Vec3 attachmentPoint(const Attachment& a);

} // namespace drape::bullet::detail
