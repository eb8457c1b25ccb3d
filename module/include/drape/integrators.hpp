// drape/integrators.hpp: the time integrators behind one interface.
//
// A step is split in two so that strain limiting and collisions act between the position
// update and the evaluation of the new forces (the paper's section 5 loop):
//   advance()  x(t) -> x(t+dt), v(t) -> v(t+dt) (Velocity-Verlet: the half-step velocity),
//              using f(t), which the caller keeps valid at the start of every step;
//   ... strain limiting and collision stages move x and fix v ...
//   the caller evaluates f(t+dt) at the corrected state;
//   finish()   Velocity-Verlet's closing half kick v += f(t+dt) dt / (2m); no-op for others.
// Particles with zero inverse mass (pinned, kinematic) get no acceleration.
// Velocity-Verlet applies the velocity-dependent terms itself so that it stays second order:
// the linear particle damping and the spring damping as exact or symmetric velocity flows dt/2
// before the opening kick (in advance) and dt/2 after the closing one (in finish), and the
// aerodynamics inside the kicks, the closing one at a predicted end velocity. bind() takes them
// out of the force model's sum for it (the cached f then holds the other terms only, except for
// held particles, which get these terms added to f in finish()).
#pragma once

#include "drape/forces.hpp"
#include "drape/settings.hpp"

#include <memory>

namespace drape {

/// What an integrator reads and writes during one step.
struct IntegratorContext {
    Vec3List& x; ///< positions [m], updated in place
    Vec3List& v; ///< velocities [m/s], updated in place
    /// Forces at the start of the step [N]; read only, except that Velocity-Verlet's finish()
    /// adds the damping of held particles to f(t+dt) (see integrators.cpp).
    Vec3List& f;
    const std::vector<double>& invMass; ///< 1/m, 0 for pinned and kinematic particles [1/kg]
    double dt;                          ///< time step [s]
    ForceModel& forces;                 ///< for integrators that evaluate forces more than once
    Executor* executor = nullptr; ///< splits particle loops over threads when set (executor.hpp)
    /// Where Velocity-Verlet's closing kick leaves its aerodynamic forces for the next step's
    /// opening kick (ClothState::aero; null: nowhere), and whether they hold the forces of the
    /// state this step starts from (the caller knows: nothing changed it since).
    Vec3List* aeroCarry = nullptr;
    bool aeroCarried = false;
    /// Set by finish() when it found a non-finite value in x, v or f while it passed over them
    /// (integrators whose finish() does not look leave it false: the caller checks).
    bool nonFiniteSeen = false;
};

/// One time integrator; holds its own scratch buffers, so one instance per cloth.
class Integrator {
  public:
    virtual ~Integrator() = default;
    virtual IntegratorKind kind() const = 0;
    /// Called once with the cloth's force model before any force is evaluated, so an
    /// integrator that applies some force terms itself can take them out of the model's sum.
    virtual void bind(ForceModel& forces) { (void)forces; }
    virtual void advance(IntegratorContext& ctx) = 0;
    /// advance() reading the state at t from x0, v0 and writing the new state to ctx.x,
    /// ctx.v (same sizes), so the caller keeps the old state without copying it. Returns false
    /// if this integrator only works in place (the caller then copies and calls advance()).
    virtual bool advanceFrom(IntegratorContext& ctx, const Vec3List& x0, const Vec3List& v0) {
        (void)ctx;
        (void)x0;
        (void)v0;
        return false;
    }
    /// Runs after forces are re-evaluated at the end of the step; ctx.f holds f(t+dt).
    virtual void finish(IntegratorContext& ctx) { (void)ctx; }
    /// Whether finish() checks x, v and f for non-finite values (ctx.nonFiniteSeen).
    virtual bool finishChecksFinite() const { return false; }
    /// Solver statistics of the last step (CG iterations for implicit Euler, else 0).
    virtual int lastIterations() const { return 0; }
};

std::unique_ptr<Integrator> makeIntegrator(IntegratorKind kind, const ImplicitSettings& implicit);

} // namespace drape
