// The five time integrators. See integrators.hpp for how a step is split into advance()
// and finish() around strain limiting and collisions.
#include "drape/integrators.hpp"

#include "drape/error.hpp"

#include "parallel.hpp"
#include "simd.hpp"

#include <Eigen/IterativeLinearSolvers>
#include <Eigen/SparseCholesky>

#include <atomic>
#include <cmath>

namespace drape {
namespace {

/// Runs body(i) for every particle, on the context's executor when it has one.
template <class Body> void forParticles(IntegratorContext& c, Body body) {
    detail::forChunks(c.executor, c.x.size(), [&](std::size_t b, std::size_t e) {
        for (std::size_t i = b; i < e; ++i)
            body(i);
    });
}

/// Runs body(begin, end) over chunks of the particles, on the context's executor when it has one.
template <class Body> void forRanges(IntegratorContext& c, Body body) {
    detail::forChunks(c.executor, c.x.size(), body);
}

/// exp(-C_d dt / (2 m)) of an inverse mass w (cdh = C_d dt / 2), computed again only when w
/// changes from one particle to the next (a cloth's particles mostly share one mass).
struct DecayOf {
    double cdh, lastW = -1.0, decay = 1.0;
    double operator()(double w) {
        if (w != lastW) {
            lastW = w;
            decay = std::exp(-cdh * w);
        }
        return decay;
    }
};

/// (a, a), (a, b), (b, b): the factors of particles i and i + 1 over the three two-lane vectors
/// that hold their six components (x_i y_i | z_i x_i+1 | y_i+1 z_i+1).
struct PairFactors {
    explicit PairFactors(detail::Double2 ab) : k{ab.lowBoth(), ab, ab.highBoth()} {}
    detail::Double2 k[3];
};

/// The kick factors of particles i and i + 1: (dt/2) w and exp(-C_d dt w / 2), spread.
struct PairKicks {
    PairFactors hw, decay;
};
PairKicks pairKicks(DecayOf& decayOf, const double* w, std::size_t i, detail::Double2 half) {
    const double d0 = decayOf(w[i]), d1 = decayOf(w[i + 1]);
    return {PairFactors(half * detail::Double2::load(w + i)),
            PairFactors(detail::Double2::of(d0, d1))};
}

/// Velocity-Verlet's opening kick and drift of particles [b, e), after L(dt/2) (decay
/// exp(-cdh w), 1 for cdh = 0): v = decay v0 + (dt/2) w f, x = x0 + dt v, over the flat
/// component arrays (three per particle; the outputs may be the inputs). Two particles at a
/// time (Double2): the same products and sums, in the same order, as the loop for the last
/// particle, so the same bits wherever a thread's range starts.
void kickDrift(std::size_t b, std::size_t e, const double* w, const double* xs, const double* vs,
               const double* fs, double* xd, double* vd, double cdh, double half, double dt) {
    using detail::Double2;
    DecayOf decayOf{cdh};
    std::size_t i = b;
    const Double2 vdt = Double2::splat(dt), vhalf = Double2::splat(half);
    for (; i + 1 < e; i += 2) {
        const PairKicks kick = pairKicks(decayOf, w, i, vhalf);
        for (std::size_t k = 0, at = 3 * i; k < 3; ++k, at += 2) {
            const Double2 vn =
                kick.decay.k[k] * Double2::load(vs + at) + kick.hw.k[k] * Double2::load(fs + at);
            vn.store(vd + at);
            (Double2::load(xs + at) + vdt * vn).store(xd + at);
        }
    }
    for (; i < e; ++i) {
        const double decay = decayOf(w[i]), hw = half * w[i];
        for (std::size_t j = 3 * i; j < 3 * i + 3; ++j) {
            const double vn = decay * vs[j] + hw * fs[j];
            vd[j] = vn;
            xd[j] = xs[j] + dt * vn;
        }
    }
}

/// Velocity-Verlet's closing kick and L(dt/2) of particles [b, e): v = decay (v + (dt/2) w f)
/// for a free particle; a held one (w = 0) keeps v and its f carries the damping, f -= C_d v.
/// Returns whether every x, v and f of the range is finite (their sum is). Two free particles
/// at a time (Double2), the same operations as the loop, as in kickDrift.
bool closingKick(std::size_t b, std::size_t e, const double* w, const double* xs, double* vs,
                 double* fs, double cd, double cdh, double half) {
    DecayOf decayOf{cdh};
    double sum = 0.0;
    auto one = [&](std::size_t i) {
        const std::size_t j = 3 * i;
        if (w[i] == 0.0) {
            for (std::size_t k = j; k < j + 3; ++k)
                fs[k] -= cd * vs[k];
        } else {
            const double decay = decayOf(w[i]), hw = half * w[i];
            for (std::size_t k = j; k < j + 3; ++k)
                vs[k] = decay * (vs[k] + hw * fs[k]);
        }
        for (std::size_t k = j; k < j + 3; ++k)
            sum += (xs[k] + vs[k]) + fs[k];
    };
    using detail::Double2;
    std::size_t i = b;
    Double2 acc = Double2::zero();
    const Double2 vhalf = Double2::splat(half);
    for (; i + 1 < e; i += 2) {
        if (w[i] == 0.0 || w[i + 1] == 0.0) {
            one(i);
            one(i + 1);
            continue;
        }
        const PairKicks kick = pairKicks(decayOf, w, i, vhalf);
        for (std::size_t k = 0, at = 3 * i; k < 3; ++k, at += 2) {
            const Double2 f = Double2::load(fs + at);
            const Double2 vn = kick.decay.k[k] * (Double2::load(vs + at) + kick.hw.k[k] * f);
            vn.store(vs + at);
            acc = acc + ((Double2::load(xs + at) + vn) + f);
        }
    }
    sum += acc.low() + acc.high();
    for (; i < e; ++i)
        one(i);
    return std::isfinite(sum);
}

/// Eq. (14) with the time step restored in the velocity term:
///   x(t+dt) = x(t) + v(t) dt + f(t)/(2m) dt^2
///   v(t+dt) = v(t) + (f(t) + f(t+dt))/(2m) dt
/// written as kick (v += f(t) dt/2m), drift (x += v dt), [limit, collide, f(t+dt)],
/// kick (v += f(t+dt) dt/2m). Algebraically identical to eq. (14); one force evaluation per
/// step, and f(t+dt) is evaluated at the corrected positions.
///
/// Velocity-dependent terms. f(t+dt) is evaluated before the closing kick has made v(t+dt),
/// so a damping or drag force in it acts with the half-step velocity v(t+dt/2) = v(t+dt) -
/// dt/2 a: an O(dt^2) error in every step's velocity, and the method is first order (measured
/// 1.008 on the damped breathing triangle). bind() takes these terms out of the force model's
/// sum, and the step applies them itself:
///
/// Linear particle damping L (eq. (8)) and spring damping S run as their own flows at frozen
/// positions, dt/2 on each side of the kick-drift-kick:
///   v <- S_fwd(dt/2) L(dt/2) v;  kick, drift, [limit, collide, f], kick;  v <- L(dt/2) S_bwd(dt/2)
///   v
/// The step is symmetric (its own adjoint), so it is second order (local error O(dt^3)). L is
/// m v' = -C_d v alone, solved exactly: v *= exp(-C_d dt / (2m)) at any dt, with nothing to be
/// stable about; particles with zero inverse mass get exp(0) = 1. S is the spring damping, a
/// sweep of exact per-spring flows, forward before the kicks and backward after them
/// (ForceModel::applySpringDampingFlow, derivation there). Both vanish at rest and leave
/// states with no spring extending alone, so statics are not touched.
///
/// Aerodynamics A (drag and lift) stays inside the kicks, as forces: it is not zero at rest
/// (wind on a held flag), and a split would move such equilibria and terminal velocities by
/// O(dt^2), while in the kicks a state whose forces balance stays exactly where it is. It is
/// nonlinear, with no exact flow. The opening kick takes A at (x(t), v) with v the velocity
/// after the opening damping; the closing kick takes A at x(t+dt) and the predicted end velocity
///   v* = v(t+dt/2) + dt/2 (f(t+dt) + A_open) / m,
/// which is v(t+dt) up to O(dt^2) (A_open is A at the start of the step, O(dt) from the end):
/// the kick's error is then dt/2 O(dt^2), and the step stays second order. Forces in balance
/// give v* = v exactly. For a linear drag rate lambda the two kicks multiply the velocity by
/// 1 - lambda dt + (lambda dt)^2 / 2 per step (second-order Taylor of exp(-lambda dt)): stable
/// and never reversing for lambda dt < 2, the bound of the drag as a plain force. Unlike the
/// force sum, an external term that reads the summed force (the contact penalty's support and
/// static friction) no longer sees A.
/// One evaluation of A per step, not two: without damping flows the next step's opening kick
/// takes the closing kick's A(x(t+dt), v*) (ClothState::aero), when nothing changed the state
/// in between (the caller's aeroCarried: no edit, no new wind, no relative damping). v* is
/// v(t+dt) up to dt/2 (A_close - A_open) / m = O(dt^2), so the opening kick's error is
/// dt/2 O(dt^2) as the closing one's, and the step stays second order; in balance v* = v and
/// the two are the same. With damping flows the velocity moves by O(dt) between the kicks,
/// which would cost an order: A is evaluated at both kicks.
class VelocityVerlet final : public Integrator {
  public:
    IntegratorKind kind() const override { return IntegratorKind::VelocityVerlet; }
    void bind(ForceModel& forces) override { forces.setVelocityTermsInIntegrator(true); }
    void advance(IntegratorContext& c) override { advanceFrom(c, c.x, c.v); }
    bool advanceFrom(IntegratorContext& c, const Vec3List& x0, const Vec3List& v0) override {
        const Terms t(c);
        const double h = 0.5 * c.dt;
        if (t.springs || t.aero) {
            // L(dt/2) then the forward sweep S(dt/2) at x(t), into the output velocities (v0
            // stays as it was); without them the kick starts from v0 itself.
            const Vec3List* start = &v0;
            if (t.springs || t.linear) {
                held_.resize(c.x.size());
                forParticles(c, [&](std::size_t i) {
                    c.v[i] = t.linear ? dampedBy(t.cdh, c.invMass[i]) * v0[i] : v0[i];
                    held_[i].setZero();
                });
                if (t.springs) c.forces.applySpringDampingFlow(x0, c.v, c.invMass, h, true, &held_);
                start = &c.v;
            }
            open_ = &aeroOpen_;
            if (t.aero) {
                if (carries(c, t) && c.aeroCarried)
                    open_ = c.aeroCarry; // the last closing kick's, at this state
                else
                    c.forces.aeroForces(x0, *start, aeroOpen_);
            }
            const Vec3List& open = *open_;
            const Vec3List& vs = *start; // may be c.v: each i is read before it is written
            forParticles(c, [&](std::size_t i) {
                const Vec3 fi = t.aero ? Vec3(c.f[i] + open[i]) : c.f[i];
                const Vec3 vh = vs[i] + (h * c.invMass[i]) * fi;
                c.v[i] = vh;
                c.x[i] = x0[i] + c.dt * vh;
            });
            return true;
        }
        // The common case (no spring damping, no aerodynamics): one flat pass (kickDrift).
        forRanges(c, [&](std::size_t b, std::size_t e) {
            kickDrift(b, e, c.invMass.data(), x0[0].data(), v0[0].data(), c.f[0].data(),
                      c.x[0].data(), c.v[0].data(), t.linear ? t.cdh : 0.0, h, c.dt);
        });
        return true;
    }
    /// The closing half kick, then the backward sweep S(dt/2) and L(dt/2), with the finiteness
    /// check of the whole state folded into the last pass over the particles (one pass instead
    /// of two without spring damping and aerodynamics): a NaN or infinity anywhere makes a
    /// chunk's sum non-finite.
    void finish(IntegratorContext& c) override {
        const Terms t(c);
        const double h = 0.5 * c.dt;
        std::atomic<bool> bad{false};
        auto passes = [&](auto body) {
            auto range = [&](std::size_t b, std::size_t e) {
                double sum = 0.0;
                for (std::size_t i = b; i < e; ++i) {
                    body(i);
                    sum += c.x[i].sum() + c.v[i].sum() + c.f[i].sum();
                }
                if (!std::isfinite(sum)) bad.store(true, std::memory_order_relaxed);
            };
            forRanges(c, range);
        };
        // A held particle (zero inverse mass) does not move by these terms, so for it nothing
        // is split: its f carries them as forces (the linear damping at its velocity, the
        // spring damping as the impulse the sweeps of this step put on it over dt, the
        // aerodynamics of the closing kick), which is what it passes on to whatever holds it
        // (an attachment to a rigid body reads f). Its own kicks ignore f (inverse mass 0).
        const double invDt = 1.0 / c.dt;
        // The closing kick's aerodynamics go where the next opening kick finds them when it may
        // take them (carries); else into scratch, and nothing is carried.
        const bool carry = carries(c, t);
        if (c.aeroCarry && !carry) c.aeroCarry->clear();
        Vec3List& close = carry ? *c.aeroCarry : aeroClose_;
        if (t.springs || t.aero) {
            if (t.aero) {
                const Vec3List& open = *open_;
                predicted_.resize(c.x.size());
                forParticles(c, [&](std::size_t i) {
                    predicted_[i] = c.v[i] + (h * c.invMass[i]) * (c.f[i] + open[i]);
                });
                c.forces.aeroForces(c.x, predicted_, close); // open_ is not read after this
            }
            if (!t.springs && !t.linear) {
                // Aerodynamics alone: the closing kick, the held particles' f and the check in
                // one pass.
                passes([&](std::size_t i) {
                    c.v[i] += (h * c.invMass[i]) * Vec3(c.f[i] + close[i]);
                    if (c.invMass[i] == 0.0) c.f[i] += close[i];
                });
                c.nonFiniteSeen = bad.load();
                return;
            }
            forParticles(c, [&](std::size_t i) {
                const Vec3 fi = t.aero ? Vec3(c.f[i] + close[i]) : c.f[i];
                c.v[i] += (h * c.invMass[i]) * fi;
            });
            if (t.springs) c.forces.applySpringDampingFlow(c.x, c.v, c.invMass, h, false, &held_);
            passes([&](std::size_t i) {
                if (c.invMass[i] == 0.0) {
                    if (t.springs) c.f[i] += invDt * held_[i];
                    if (t.aero) c.f[i] += close[i];
                    if (t.linear) c.f[i] -= t.cd * c.v[i];
                } else if (t.linear) {
                    c.v[i] *= dampedBy(t.cdh, c.invMass[i]);
                }
            });
        } else {
            // The closing kick and L(dt/2) in one flat pass, with the finiteness check
            // (closingKick; without linear damping C_d = 0: a decay of exactly 1).
            const double cd = t.linear ? t.cd : 0.0, cdh = t.linear ? t.cdh : 0.0;
            auto range = [&](std::size_t b, std::size_t e) {
                if (!closingKick(b, e, c.invMass.data(), c.x[0].data(), c.v[0].data(),
                                 c.f[0].data(), cd, cdh, h))
                    bad.store(true, std::memory_order_relaxed);
            };
            forRanges(c, range);
        }
        c.nonFiniteSeen = bad.load();
    }
    bool finishChecksFinite() const override { return true; }

  private:
    /// Which velocity-dependent terms this step applies itself.
    struct Terms {
        explicit Terms(const IntegratorContext& c)
            : own(c.forces.velocityTermsInIntegrator()),
              linear(own && c.forces.linearDamping() > 0.0),
              springs(own && c.forces.springDamping() > 0.0), aero(own && c.forces.hasAero()),
              cd(c.forces.linearDamping()), cdh(0.5 * c.dt * cd) {}
        bool own, linear, springs, aero;
        double cd;  ///< C_d [N s/m]
        double cdh; ///< C_d dt / 2
    };
    /// Whether this step's closing aerodynamics may serve as the next step's opening ones:
    /// aerodynamics without damping flows (with them the velocity moves by O(dt) between the
    /// two kicks) and somewhere to keep them.
    static bool carries(const IntegratorContext& c, const Terms& t) {
        return t.aero && !t.springs && !t.linear && c.aeroCarry != nullptr;
    }
    // Scratch of one step only (filled in advanceFrom, read in finish): what is carried from
    // one step to the next is in the cloth's state (ClothState::aero), so a restored snapshot
    // continues bit for bit.
    const Vec3List* open_ = nullptr; ///< the opening kick's aerodynamics (aeroOpen_ or carried)
    Vec3List held_;                  ///< impulse of the spring damping on each held particle [N s]
    Vec3List aeroOpen_;              ///< aerodynamic forces of the opening kick [N]
    Vec3List aeroClose_;             ///< aerodynamic forces of the closing kick [N]
    Vec3List predicted_;             ///< predicted end velocity v* [m/s]
    /// exp(-C_d (dt/2) / m) for cdh = C_d dt / 2: the exact decay of m v' = -C_d v over dt/2. A
    /// DecayOf per thread keeps the last value (most cloths have one mass: one exp per pass).
    static double dampedBy(double cdh, double invMass) {
        thread_local DecayOf decayOf{0.0};
        if (decayOf.cdh != cdh) decayOf = DecayOf{cdh};
        return decayOf(invMass);
    }
};

/// x(t+dt) = x + v dt, v(t+dt) = v + a dt: both from the state at t. First order.
class ExplicitEuler final : public Integrator {
  public:
    IntegratorKind kind() const override { return IntegratorKind::ExplicitEuler; }
    void advance(IntegratorContext& c) override { advanceFrom(c, c.x, c.v); }
    bool advanceFrom(IntegratorContext& c, const Vec3List& x0, const Vec3List& v0) override {
        forParticles(c, [&](std::size_t i) {
            const Vec3 vi = v0[i];
            c.x[i] = x0[i] + c.dt * vi;
            c.v[i] = vi + (c.dt * c.invMass[i]) * c.f[i];
        });
        return true;
    }
};

/// v(t+dt) = v + a dt, x(t+dt) = x + v(t+dt) dt. First order, symplectic.
class SymplecticEuler final : public Integrator {
  public:
    IntegratorKind kind() const override { return IntegratorKind::SymplecticEuler; }
    void advance(IntegratorContext& c) override { advanceFrom(c, c.x, c.v); }
    bool advanceFrom(IntegratorContext& c, const Vec3List& x0, const Vec3List& v0) override {
        forParticles(c, [&](std::size_t i) {
            const Vec3 vi = v0[i] + (c.dt * c.invMass[i]) * c.f[i];
            c.v[i] = vi;
            c.x[i] = x0[i] + c.dt * vi;
        });
        return true;
    }
};

/// Classic fourth-order Runge-Kutta on y = (x, v), y' = (v, f(x, v)/m). Four force
/// evaluations per step, the first of which is the caller's cached f(t).
class RungeKutta4 final : public Integrator {
  public:
    IntegratorKind kind() const override { return IntegratorKind::RungeKutta4; }
    void advance(IntegratorContext& c) override {
        const std::size_t n = c.x.size();
        x0_ = c.x;
        v0_ = c.v;
        xs_.resize(n);
        vs_.resize(n);
        accX_.resize(n);
        accV_.resize(n);
        const double dt = c.dt;
        // Stage 1 from the cached forces.
        for (std::size_t i = 0; i < n; ++i) {
            const Vec3 a = c.invMass[i] * c.f[i];
            accX_[i] = v0_[i];
            accV_[i] = a;
            xs_[i] = x0_[i] + 0.5 * dt * v0_[i];
            vs_[i] = v0_[i] + 0.5 * dt * a;
        }
        const double stageStep[3] = {0.5 * dt, dt, 0.0};
        const double weight[3] = {2.0, 2.0, 1.0};
        for (int s = 0; s < 3; ++s) {
            c.forces.evaluate(xs_, vs_, fs_);
            for (std::size_t i = 0; i < n; ++i) {
                const Vec3 a = c.invMass[i] * fs_[i];
                const Vec3 vStage = vs_[i];
                accX_[i] += weight[s] * vStage;
                accV_[i] += weight[s] * a;
                if (s < 2) {
                    xs_[i] = x0_[i] + stageStep[s] * vStage;
                    vs_[i] = v0_[i] + stageStep[s] * a;
                }
            }
        }
        for (std::size_t i = 0; i < n; ++i) {
            c.x[i] = x0_[i] + (dt / 6.0) * accX_[i];
            c.v[i] = v0_[i] + (dt / 6.0) * accV_[i];
        }
    }

  private:
    Vec3List x0_, v0_, xs_, vs_, fs_, accX_, accV_;
};

/// Linearised backward Euler (Baraff & Witkin 1998):
///   (M - dt df/dv - dt^2 df/dx) dv = dt (f(t) + dt df/dx v(t)),  v += dv,  x += v dt.
/// Rows and columns of particles with zero inverse mass are replaced by the identity with a
/// zero right-hand side, so they keep their velocity. Compressed springs drop their
/// transverse stiffness (clampCompression) so the matrix stays symmetric positive definite.
class ImplicitEuler final : public Integrator {
  public:
    explicit ImplicitEuler(const ImplicitSettings& s) : settings_(s) {}
    IntegratorKind kind() const override { return IntegratorKind::ImplicitEuler; }
    int lastIterations() const override { return iterations_; }

    void advance(IntegratorContext& c) override {
        using Vec = Eigen::VectorXd;
        const std::size_t n = c.x.size();
        const auto n3 = static_cast<Eigen::Index>(3 * n);
        c.forces.assembleJacobians(c.x, true, dfdx_, dfdv_);
        const Eigen::Map<const Vec> v0(c.v[0].data(), n3);
        const Eigen::Map<const Vec> f0(c.f[0].data(), n3);
        const double dt = c.dt;
        Vec b = dt * (f0 + dt * (dfdx_ * v0));
        Eigen::SparseMatrix<double> A = (-dt) * dfdv_ - (dt * dt) * dfdx_;
        Vec free(n3);
        for (std::size_t i = 0; i < n; ++i) {
            const double f = c.invMass[i] > 0.0 ? 1.0 : 0.0;
            free.segment<3>(3 * static_cast<Eigen::Index>(i)).setConstant(f);
        }
        const Eigen::DiagonalMatrix<double, Eigen::Dynamic> S(free);
        A = S * A * S;
        b = free.cwiseProduct(b);
        Vec diag(n3);
        for (std::size_t i = 0; i < n; ++i) {
            const double d = c.invMass[i] > 0.0 ? c.forces.mass()[i] : 1.0;
            diag.segment<3>(3 * static_cast<Eigen::Index>(i)).setConstant(d);
        }
        Eigen::SparseMatrix<double> M(n3, n3);
        M.reserve(Eigen::VectorXi::Constant(n3, 1));
        for (Eigen::Index i = 0; i < n3; ++i)
            M.insert(i, i) = diag[i];
        A += M;

        if (settings_.solver == LinearSolverKind::ConjugateGradient) {
            Eigen::ConjugateGradient<Eigen::SparseMatrix<double>, Eigen::Lower | Eigen::Upper> cg;
            cg.setTolerance(settings_.cgTolerance);
            cg.setMaxIterations(settings_.cgMaxIterations);
            cg.compute(A);
            // No warm start from the previous step's dv: the result then depends only on the
            // state, which keeps restored snapshots bit-identical to uninterrupted runs.
            dv_ = cg.solve(b);
            iterations_ = static_cast<int>(cg.iterations());
        } else {
            ldlt_.compute(A);
            if (ldlt_.info() != Eigen::Success) {
                throw Error(ErrorCode::SimulationFailure,
                            "implicit Euler: LDLT factorisation of the system matrix failed");
            }
            dv_ = ldlt_.solve(b);
            iterations_ = 0;
        }
        for (std::size_t i = 0; i < n; ++i) {
            c.v[i] += dv_.segment<3>(3 * static_cast<Eigen::Index>(i));
            c.x[i] += dt * c.v[i];
        }
    }

  private:
    ImplicitSettings settings_;
    Eigen::SparseMatrix<double> dfdx_, dfdv_;
    Eigen::VectorXd dv_;
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt_;
    int iterations_ = 0;
};

} // namespace

std::unique_ptr<Integrator> makeIntegrator(IntegratorKind kind, const ImplicitSettings& implicit) {
    switch (kind) {
    case IntegratorKind::VelocityVerlet:
        return std::make_unique<VelocityVerlet>();
    case IntegratorKind::ExplicitEuler:
        return std::make_unique<ExplicitEuler>();
    case IntegratorKind::SymplecticEuler:
        return std::make_unique<SymplecticEuler>();
    case IntegratorKind::RungeKutta4:
        return std::make_unique<RungeKutta4>();
    case IntegratorKind::ImplicitEuler:
        return std::make_unique<ImplicitEuler>(implicit);
    }
    throw Error(ErrorCode::InvalidArgument, "unknown integrator kind");
}

} // namespace drape
