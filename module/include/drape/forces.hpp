// drape/forces.hpp: the force terms of eq. (5) as small free functions over plain arrays,
// their Jacobians for the implicit integrator, energies, and ForceModel, which sums the
// terms a cloth actually uses.
#pragma once

#include "drape/settings.hpp"
#include "drape/timers.hpp"
#include "drape/topology.hpp"

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include <functional>
#include <memory>
#include <vector>

namespace drape {

struct ContactSet; // drape/contacts.hpp
class Executor;    // drape/executor.hpp

namespace detail {
struct PackedSprings; // spring_layout.hpp
} // namespace detail

using Vec3List = std::vector<Vec3>;

/// Eq. (4), Hooke's linked springs: particle a gets k (l - L0) n with n the unit vector from a
/// to b and l the current length; b gets the opposite. The energy is k (l - L0)^2 / 2.
void addSpringForces(const std::vector<Spring>& springs, const std::vector<double>& stiffness,
                     const Vec3List& x, Vec3List& f);

/// Damping along springs: a gets c ((v_b - v_a) . n) n, b the opposite. Dissipates relative
/// motion along the spring only, so rigid motion is not damped.
void addSpringDamping(const std::vector<Spring>& springs, double c, const Vec3List& x,
                      const Vec3List& v, Vec3List& f);

/// Eq. (6): m_i g.
void addGravity(const std::vector<double>& mass, const Vec3& g, Vec3List& f);

/// Eq. (8): -C_d v_i.
void addLinearDamping(double cd, const Vec3List& v, Vec3List& f);

/// Aerodynamic force per triangle, shared equally by its corners. With u the triangle's
/// velocity relative to the wind, n its unit normal and A its current area:
///   drag = -rho/2 C_d A |u| (u . n) n         (pressure on the face; zero for edge-on flow)
///   lift = -rho/2 C_l A |u . n| (n x u) x u / |u| (across the flow, in the plane of u and n)
void addAeroForces(const std::vector<Triangle>& triangles, const AeroSettings& aero,
                   const Vec3List& x, const Vec3List& v, Vec3List& f);

/// d f_a / d x_b for one spring (= -d f_a / d x_a): k [n n^T + (1 - L0/l)(I - n n^T)].
/// With clampCompression the transverse term is dropped for compressed springs (l < L0),
/// which keeps the assembled stiffness matrix negative semi-definite (needed by CG).
Eigen::Matrix3d springJacobianBlock(const Vec3& xa, const Vec3& xb, double k, double restLength,
                                    bool clampCompression);

/// Spring potential energy sum k (l - L0)^2 / 2 [J].
double springEnergy(const std::vector<Spring>& springs, const std::vector<double>& stiffness,
                    const Vec3List& x);

/// Sum of the force terms a cloth uses, each one timed as its own phase. Terms a cloth does
/// not use (zero damping, no aerodynamics, no user forces) are not in the list and cost nothing.
class ForceModel {
  public:
    /// Extra per-particle forces from outside the core (contact penalties from a collision
    /// stage, for example): called with (x, v, f) and adds to f.
    using ExternalForce = std::function<void(const Vec3List& x, const Vec3List& v, Vec3List& f)>;

    /// `executor` (may be null: this thread) runs the spring, gravity and damping terms on
    /// several threads; the result is bit-identical for any executor (drape/executor.hpp).
    ForceModel(TopologyPtr topology, std::vector<double> stiffness, std::vector<double> mass,
               const ClothSettings& settings, PhaseTimers& timers, Executor* executor = nullptr);

    /// The executor later evaluations split their loops on (null: this thread).
    void setExecutor(Executor* executor) { executor_ = executor; }

    /// f = sum of all active terms at state (x, v).
    void evaluate(const Vec3List& x, const Vec3List& v, Vec3List& f);

    /// Hands the velocity-dependent terms (linear particle damping of eq. (8), spring damping,
    /// aerodynamics) over to the integrator: with `on`, evaluate() leaves them out and the
    /// integrator applies them itself (Velocity-Verlet, see integrators.cpp, so that it stays
    /// second order). They stay in activeTerms() and keep their timer names. Off by default:
    /// every other integrator, and the Jacobians, treat them as forces.
    void setVelocityTermsInIntegrator(bool on) { velocityTermsInIntegrator_ = on; }
    bool velocityTermsInIntegrator() const { return velocityTermsInIntegrator_; }
    /// C_d of eq. (8) and c of the spring damping [N s/m] (0 when off).
    double linearDamping() const { return settings_.damping; }
    double springDamping() const { return settings_.springDamping; }

    /// Spring damping alone acting on v for a time tau with the positions frozen at x,
    /// dv_i/dt = invMass_i * (sum of the spring damping forces on i), as one sweep over the
    /// springs, each spring's own flow solved exactly, front to back (forward) or back to
    /// front. A forward sweep on one side of Velocity-Verlet's kicks and a backward one on the
    /// other make a symmetric, second-order step (derivation next to the code); a sweep never
    /// adds kinetic energy, at any tau. Particles with zero inverse mass keep their velocity;
    /// the impulse [N s] the springs' damping puts on them is added to heldImpulse when given
    /// (what a pinned or attached particle passes on to whatever holds it). Timed as the
    /// "spring_damping" phase.
    void applySpringDampingFlow(const Vec3List& x, Vec3List& v, const std::vector<double>& invMass,
                                double tau, bool forward, Vec3List* heldImpulse = nullptr);

    /// Whether the aerodynamic term is active (air density and a coefficient set).
    bool hasAero() const;
    /// f = the aerodynamic forces alone at (x, v) (addAeroForces with the current wind), timed
    /// as the "aero" phase.
    void aeroForces(const Vec3List& x, const Vec3List& v, Vec3List& f);

    /// Assembles d f / d x and d f / d v (3n x 3n) of the springs, spring damping and linear
    /// damping at state x. Gravity, user forces and aerodynamics are treated explicitly.
    void assembleJacobians(const Vec3List& x, bool clampCompression,
                           Eigen::SparseMatrix<double>& dfdx,
                           Eigen::SparseMatrix<double>& dfdv) const;

    /// Sets a persistent user force on particle i [N] (a mouse pull, a push).
    void setUserForce(Index i, const Vec3& force);
    void clearUserForces();
    void setWind(const Vec3& wind);
    /// Replaces the aerodynamic settings (the wind with them); the term is on while
    /// airDensity > 0 and a coefficient is non-zero.
    void setAero(const AeroSettings& aero);
    void setGravity(const Vec3& g);
    void addExternalForce(std::string name, ExternalForce force);
    /// The contact force term ("contact_force", after every other term) reads `contacts` and
    /// writes each record's force back (drape/contacts.hpp); null removes the term.
    void setContacts(std::shared_ptr<ContactSet> contacts);
    ContactSet* contacts() const { return contacts_.get(); }

    const std::vector<double>& stiffness() const { return stiffness_; }
    const std::vector<double>& mass() const { return mass_; }
    const ClothSettings& settings() const { return settings_; }
    /// Names of the force terms in the pipeline, in evaluation order.
    std::vector<std::string> activeTerms() const;
    /// Number of active terms that cannot add energy (springs, damping, gravity).
    std::size_t passiveTermCount() const;

  private:
    enum class Term { Springs, SpringDamping, Gravity, Damping, Aero, User, External, Contacts };
    struct Entry {
        Term term;
        std::size_t timerSlot;
        std::size_t external = 0; ///< index into externals_ for Term::External
        std::string name;
    };
    void rebuildPipeline();

    TopologyPtr topology_;
    std::vector<double> stiffness_;
    std::vector<double> mass_;
    ClothSettings settings_;
    PhaseTimers& timers_;
    std::vector<Index> userIndices_;
    Vec3List userForces_;
    std::vector<std::pair<std::string, ExternalForce>> externals_;
    std::shared_ptr<ContactSet> contacts_;
    std::vector<Entry> pipeline_;
    Executor* executor_ = nullptr;
    /// The stiffness of each spring of the layout's packedLoose, in its order (empty when every
    /// spring has the same); the layout itself is the topology's, built once.
    std::vector<double> looseStiffness_;
    /// The springs in the damping sweep's order (detail::dampingSweepOrder), when
    /// springDamping > 0.
    std::shared_ptr<const detail::PackedSprings> dampingOrder_;
    /// Per family slot: the spring's stiffness (0 for a hole, whose force is then 0).
    std::vector<double> slotStiffness_;
    /// The start of the force sum: gravity, and particle damping at velocities v (0 when the
    /// integrator applies it).
    struct ForceStart {
        bool gravity;
        double damping;
        const Vec3List* v;
    };
    void startForces(const ForceStart& s, std::size_t b, std::size_t e, Vec3List& f) const;
    void startForcesPlus(const ForceStart& s, std::size_t b, std::size_t e, const double* sx,
                         const double* sy, const double* sz, Vec3List& f) const;
    void addFamilySpringForces(const Vec3List& x, const ForceStart& start, Vec3List& f);
    void addFamilySpringForcesWhole(const Vec3List& x, Vec3List& f);
    /// Whether the family springs take the blocked pass (addFamilySpringForces, which also
    /// starts the force sum) or the whole-cloth one (see the constructor).
    bool blockedFamilies_ = false;
    std::size_t maxFamilyOffset_ = 0; ///< the widest offset b - a of a spring family
    static constexpr std::size_t kMaxBlockedFamilies = 8;
    static constexpr std::size_t kMaxBlockedOffset = 16384;
    /// Scratch of the whole-cloth family pass: positions and forces as coordinate arrays, and
    /// each slot's spring force.
    std::vector<double> soaX_, soaF_, slotF_;
    /// The common stiffness when every spring has the same (the step then reads no
    /// per-spring stiffness), else 0.
    double uniformStiffness_ = 0.0;
    bool velocityTermsInIntegrator_ = false;
};

} // namespace drape
