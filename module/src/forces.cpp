// The force terms of eq. (5) and ForceModel.
#include "drape/forces.hpp"

#include "drape/contacts.hpp"

#include "drape/error.hpp"

#include "parallel.hpp"
#include "restrict.hpp"
#include "simd.hpp"
#include "spring.hpp"
#include "spring_layout.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>

namespace drape {

namespace {
/// Eq. (4) for one spring, added to both ends.
inline void addOneSpring(const Spring& sp, double k, const Vec3List& x, Vec3List& f) {
    const Vec3 d = x[sp.b] - x[sp.a];
    const double l = d.norm();
    if (l == 0.0) return; // coincident ends: no direction, no force
    const Vec3 force = detail::springForceScale(k, l, sp.restLength) * d;
    f[sp.a] += force;
    f[sp.b] -= force;
}
} // namespace

void addSpringForces(const std::vector<Spring>& springs, const std::vector<double>& stiffness,
                     const Vec3List& x, Vec3List& f) {
    for (std::size_t s = 0; s < springs.size(); ++s)
        addOneSpring(springs[s], stiffness[s], x, f);
}

namespace {
/// Springs [b, e) of a packed list; k is the common stiffness, or 0 to read stiffness[s].
void addPackedSpringForces(const std::vector<Spring>& springs, const std::vector<double>& stiffness,
                           double k, std::size_t b, std::size_t e, const Vec3List& x, Vec3List& f) {
    for (std::size_t s = b; s < e; ++s) {
        const Spring& sp = springs[s];
        const Vec3 d = x[sp.b] - x[sp.a];
        const double l = d.norm();
        if (l == 0.0) continue; // coincident ends: no direction, no force
        const Vec3 force =
            detail::springForceScale(k > 0.0 ? k : stiffness[s], l, sp.restLength) * d;
        f[sp.a] += force;
        f[sp.b] -= force;
    }
}
} // namespace

void addSpringDamping(const std::vector<Spring>& springs, double c, const Vec3List& x,
                      const Vec3List& v, Vec3List& f) {
    for (const Spring& sp : springs) {
        const Vec3 d = x[sp.b] - x[sp.a];
        const double l2 = d.squaredNorm();
        if (l2 == 0.0) continue;
        const Vec3 force = (c * (v[sp.b] - v[sp.a]).dot(d) / l2) * d;
        f[sp.a] += force;
        f[sp.b] -= force;
    }
}

namespace {
/// One sweep of spring damping flows over springs[b, e), front to back (Forward) or back to
/// front, each spring's flow run for tau with the positions x frozen. For one spring alone,
/// with n = d / l the unit vector from a to b and u = (v_b - v_a) . n its rate of extension,
///   m_a v_a' = c u n,  m_b v_b' = -c u n   =>   u' = -c (w_a + w_b) u   (w = 1/m),
/// so u(tau) = u e^{-c (w_a + w_b) tau} exactly, reached by the momentum-conserving impulse
/// J n with J = u (1 - e^{-c (w_a + w_b) tau}) / (w_a + w_b): v_a += w_a J n, v_b -= w_b J n.
/// A held end (w = 0) keeps its velocity, and the impulse it takes is added to held[] when
/// given; a spring with both ends held or of zero length is skipped (no direction, as in
/// addSpringDamping).
template <bool Forward>
void sweepSpringDamping(const std::vector<Spring>& springs, std::size_t b, std::size_t e, double c,
                        double tau, const Vec3List& x, Vec3List& v,
                        const std::vector<double>& invMass, Vec3List* held) {
    // 1 - e^{-c (w_a + w_b) tau} depends only on w_a + w_b, which is the same for most springs
    // (uniform masses): keep the last one instead of calling expm1 per spring.
    double lastW = -1.0, lastLoss = 0.0;
    for (std::size_t k = b; k < e; ++k) {
        const Spring& sp = springs[Forward ? k : b + (e - 1 - k)];
        const double wa = invMass[sp.a], wb = invMass[sp.b];
        const double w = wa + wb;
        if (w == 0.0) continue;
        const Vec3 d = x[sp.b] - x[sp.a];
        const double l2 = d.squaredNorm();
        if (l2 == 0.0) continue;
        if (w != lastW) {
            lastW = w;
            lastLoss = -std::expm1(-c * w * tau); // 1 - e^{-...} without cancellation for small tau
        }
        // J n = (u (1 - e) / w) d / l with u = (v_b - v_a) . d / l: one division by l^2.
        const Vec3 j = ((v[sp.b] - v[sp.a]).dot(d) * lastLoss / (w * l2)) * d;
        v[sp.a] += wa * j;
        v[sp.b] -= wb * j;
        if (held) {
            if (wa == 0.0) (*held)[sp.a] += j;
            if (wb == 0.0) (*held)[sp.b] -= j;
        }
    }
}
} // namespace

void addGravity(const std::vector<double>& mass, const Vec3& g, Vec3List& f) {
    for (std::size_t i = 0; i < mass.size(); ++i)
        f[i] += mass[i] * g;
}

void addLinearDamping(double cd, const Vec3List& v, Vec3List& f) {
    for (std::size_t i = 0; i < v.size(); ++i)
        f[i] -= cd * v[i];
}

void addAeroForces(const std::vector<Triangle>& triangles, const AeroSettings& aero,
                   const Vec3List& x, const Vec3List& v, Vec3List& f) {
    // With c = (x1 - x0) x (x2 - x0) (A = |c| / 2, n = c / |c|) and (c x u) x u =
    // (u . c) u - |u|^2 c, a corner's third of drag plus lift is a c + b u with
    //   a = |u|^2 (kl |u . c| - kd (u . c)) / (|c| |u|),   b = -kl |u . c| (u . c) / (|c| |u|),
    // kd = rho C_d / 12, kl = rho C_l / 12: one square root and one division a triangle.
    const double kd = aero.airDensity * aero.dragCoefficient / 12.0;
    const double kl = aero.airDensity * aero.liftCoefficient / 12.0;
    const double third = 1.0 / 3.0;
    const Vec3 wind = aero.wind;
    for (const Triangle& t : triangles) {
        const Vec3 x0 = x[t[0]];
        const Vec3 c = (x[t[1]] - x0).cross(x[t[2]] - x0);
        const double c2 = c.squaredNorm();
        const Vec3 u = third * (v[t[0]] + v[t[1]] + v[t[2]]) - wind;
        const double u2 = u.squaredNorm();
        if (c2 == 0.0 || u2 == 0.0) continue;
        const double uc = u.dot(c);
        const double per = 1.0 / std::sqrt(c2 * u2); // 1 / (|c| |u|)
        const double lift = kl * std::abs(uc);
        Vec3 force = (per * u2 * (lift - kd * uc)) * c;
        if (kl != 0.0) force -= (per * lift * uc) * u;
        f[t[0]] += force;
        f[t[1]] += force;
        f[t[2]] += force;
    }
}

Eigen::Matrix3d springJacobianBlock(const Vec3& xa, const Vec3& xb, double k, double restLength,
                                    bool clampCompression) {
    const Vec3 d = xb - xa;
    const double l = d.norm();
    if (l == 0.0) return k * Eigen::Matrix3d::Identity() * 0.0;
    const Vec3 n = d / l;
    const Eigen::Matrix3d nnT = n * n.transpose();
    double transverse = 1.0 - restLength / l;
    if (clampCompression && transverse < 0.0) transverse = 0.0;
    return k * (nnT + transverse * (Eigen::Matrix3d::Identity() - nnT));
}

double springEnergy(const std::vector<Spring>& springs, const std::vector<double>& stiffness,
                    const Vec3List& x) {
    double e = 0.0;
    for (std::size_t s = 0; s < springs.size(); ++s) {
        const double dl = (x[springs[s].b] - x[springs[s].a]).norm() - springs[s].restLength;
        e += 0.5 * stiffness[s] * dl * dl;
    }
    return e;
}

ForceModel::ForceModel(TopologyPtr topology, std::vector<double> stiffness,
                       std::vector<double> mass, const ClothSettings& settings, PhaseTimers& timers,
                       Executor* executor)
    : topology_(std::move(topology)), stiffness_(std::move(stiffness)), mass_(std::move(mass)),
      settings_(settings), timers_(timers), executor_(executor) {
    if (!stiffness_.empty() && std::all_of(stiffness_.begin(), stiffness_.end(),
                                           [&](double k) { return k == stiffness_[0]; })) {
        uniformStiffness_ = stiffness_[0];
    }
    // The force pass: family springs by slot, the loose ones by the topology's packed blocks
    // (per-cloth only the stiffness, when it varies).
    if (uniformStiffness_ == 0.0)
        for (Index s : topology_->springLayout().packedLoose.index)
            looseStiffness_.push_back(stiffness_[s]);
    {
        const auto& slotSpring = topology_->springLayout().slotSpring;
        slotStiffness_.resize(slotSpring.size());
        for (std::size_t j = 0; j < slotSpring.size(); ++j)
            slotStiffness_[j] = slotSpring[j] == kNoParticle ? 0.0 : stiffness_[slotSpring[j]];
    }
    // The blocked family pass keeps, per block, a buffer of block + offset slots for every
    // family: right for a sheet (four families, offsets about a row), wasteful for a mesh with
    // many families or offsets near the particle count, which take the whole-cloth pass. Both
    // form the same sums in the same order.
    const auto& families = topology_->springLayout().families;
    for (const detail::SpringFamily& fam : families)
        maxFamilyOffset_ = std::max<std::size_t>(maxFamilyOffset_, fam.offset);
    blockedFamilies_ = !families.empty() && families.size() <= kMaxBlockedFamilies &&
                       maxFamilyOffset_ <= kMaxBlockedOffset;
    if (settings_.springDamping > 0.0)
        dampingOrder_ =
            std::make_shared<const detail::PackedSprings>(detail::dampingSweepOrder(*topology_));
    rebuildPipeline();
}

void ForceModel::rebuildPipeline() {
    pipeline_.clear();
    auto add = [&](Term term, const std::string& name, std::size_t ext = 0) {
        pipeline_.push_back(Entry{term, timers_.slot(name), ext, name});
    };
    add(Term::Springs, "springs");
    if (settings_.springDamping > 0.0) add(Term::SpringDamping, "spring_damping");
    if (settings_.gravity != Vec3::Zero()) add(Term::Gravity, "gravity");
    if (settings_.damping > 0.0) add(Term::Damping, "damping");
    if (settings_.aero.airDensity > 0.0 &&
        (settings_.aero.dragCoefficient != 0.0 || settings_.aero.liftCoefficient != 0.0)) {
        add(Term::Aero, "aero");
    }
    if (!userIndices_.empty()) add(Term::User, "user");
    for (std::size_t e = 0; e < externals_.size(); ++e) {
        add(Term::External, externals_[e].first, e);
    }
    if (contacts_) add(Term::Contacts, "contact_force");
}

std::vector<std::string> ForceModel::activeTerms() const {
    std::vector<std::string> names;
    for (const auto& e : pipeline_)
        names.push_back(e.name);
    return names;
}

std::size_t ForceModel::passiveTermCount() const {
    std::size_t count = 0;
    for (const auto& e : pipeline_) {
        count += e.term == Term::Springs || e.term == Term::SpringDamping ||
                 e.term == Term::Gravity || e.term == Term::Damping;
    }
    return count;
}

namespace {
/// put(i, fx, fy, fz) with f_i = m_i g - C_d v_i for particles [b, e), with the terms that are
/// on (the force sum's start), component by component.
template <class Put>
void forForceStart(bool gravity, double cd, const Vec3& g, const double* m, const Vec3List& v,
                   std::size_t b, std::size_t e, Put put) {
    if (gravity && cd > 0.0) {
        for (std::size_t i = b; i < e; ++i)
            put(i, m[i] * g[0] - cd * v[i][0], m[i] * g[1] - cd * v[i][1],
                m[i] * g[2] - cd * v[i][2]);
    } else if (gravity) {
        for (std::size_t i = b; i < e; ++i)
            put(i, m[i] * g[0], m[i] * g[1], m[i] * g[2]);
    } else if (cd > 0.0) {
        for (std::size_t i = b; i < e; ++i)
            put(i, -cd * v[i][0], -cd * v[i][1], -cd * v[i][2]);
    } else {
        for (std::size_t i = b; i < e; ++i)
            put(i, 0.0, 0.0, 0.0);
    }
}
} // namespace

// f[i] = m_i g - C_d v_i for particles [b, e), with the terms that are on (the force sum's start).
void ForceModel::startForces(const ForceStart& s, std::size_t b, std::size_t e, Vec3List& f) const {
    forForceStart(s.gravity, s.damping, settings_.gravity, mass_.data(), *s.v, b, e,
                  [&](std::size_t i, double fx, double fy, double fz) { f[i] = Vec3(fx, fy, fz); });
}

// f[i] = (m_i g - C_d v_i) + (sx, sy, sz)[i - b] for particles [b, e): startForces followed by
// adding the sums, in one pass (the same operations in the same order).
void ForceModel::startForcesPlus(const ForceStart& s, std::size_t b, std::size_t e,
                                 const double* sx, const double* sy, const double* sz,
                                 Vec3List& f) const {
    forForceStart(s.gravity, s.damping, settings_.gravity, mass_.data(), *s.v, b, e,
                  [&](std::size_t i, double fx, double fy, double fz) {
                      f[i] = Vec3(fx + sx[i - b], fy + sy[i - b], fz + sz[i - b]);
                  });
}

void ForceModel::evaluate(const Vec3List& x, const Vec3List& v, Vec3List& f) {
    const std::size_t n = x.size();
    f.resize(n);
    const ForceStart start{settings_.gravity != Vec3::Zero(),
                           velocityTermsInIntegrator_ ? 0.0 : settings_.damping, &v};
    // The springs come first in the pipeline. When the blocked family pass runs, it starts the
    // sum itself (one pass over f instead of two); otherwise gravity (eq. (6)) and particle damping
    // (eq. (8)), or zero, are set here: one pass over the particles instead of three. (The sum
    // is then formed in another order than term by term: results agree to rounding.)
    if (!blockedFamilies_) {
        detail::forChunks(executor_, n,
                          [&](std::size_t b, std::size_t e) { startForces(start, b, e, f); });
    }
    for (const Entry& e : pipeline_) {
        // Applied by the integrator instead (setVelocityTermsInIntegrator), and timed there.
        if (velocityTermsInIntegrator_ &&
            (e.term == Term::SpringDamping || e.term == Term::Damping || e.term == Term::Aero)) {
            continue;
        }
        ScopedPhase timer(timers_, e.timerSlot);
        switch (e.term) {
        case Term::Springs: {
            if (blockedFamilies_) {
                addFamilySpringForces(x, start, f);
            } else if (!topology_->springLayout().families.empty()) {
                addFamilySpringForcesWhole(x, f);
            }
            const detail::PackedSprings& loose = topology_->springLayout().packedLoose;
            const std::size_t nb = loose.starts.size() - 2; // inner blocks; the last range crosses
            if (loose.springs.empty()) break;
            // Blocks in parallel (each writes only its own particles), then the crossing
            // springs: the same sums in the same order for any thread count.
            auto range = [&](std::size_t block) {
                addPackedSpringForces(loose.springs, looseStiffness_, uniformStiffness_,
                                      loose.starts[block], loose.starts[block + 1], x, f);
            };
            auto blockRange = [&](std::size_t b, std::size_t end) {
                for (std::size_t k = b; k < end; ++k)
                    range(k);
            };
            detail::forChunks(executor_, nb, blockRange, 1);
            range(nb);
            break;
        }
        case Term::SpringDamping:
            addSpringDamping(topology_->springs(), settings_.springDamping, x, v, f);
            break;
        case Term::Gravity:
            break; // applied when f was initialised above
        case Term::Damping:
            break; // applied when f was initialised above
        case Term::Aero:
            addAeroForces(topology_->triangles(), settings_.aero, x, v, f);
            break;
        case Term::User:
            for (std::size_t k = 0; k < userIndices_.size(); ++k)
                f[userIndices_[k]] += userForces_[k];
            break;
        case Term::External:
            externals_[e.external].second(x, v, f);
            break;
        case Term::Contacts:
            addContactForces(*contacts_, x, v, f);
            break;
        }
    }
}

namespace {
// The kernels of the family pass, as functions whose arrays are declared not to overlap (they
// never do: positions, slot forces and particle forces are separate buffers), so that the
// compiler vectorises them without run-time overlap checks.

/// Spring forces of m consecutive slots: a and b are the coordinate runs of the two ends.
DRAPE_WIDE_KERNEL
void familySlotForces(std::size_t m, const double* DRAPE_RESTRICT ax,
                      const double* DRAPE_RESTRICT ay, const double* DRAPE_RESTRICT az,
                      const double* DRAPE_RESTRICT bx, const double* DRAPE_RESTRICT by,
                      const double* DRAPE_RESTRICT bz, const double* DRAPE_RESTRICT k,
                      const double* DRAPE_RESTRICT l0, double* DRAPE_RESTRICT ox,
                      double* DRAPE_RESTRICT oy, double* DRAPE_RESTRICT oz) {
    for (std::size_t j = 0; j < m; ++j) {
        const double dx = bx[j] - ax[j], dy = by[j] - ay[j], dz = bz[j] - az[j];
        const double l = std::sqrt(dx * dx + dy * dy + dz * dz);
        const double t = detail::springForceScale(k[j], l, l0[j]);
        ox[j] = t * dx;
        oy[j] = t * dy;
        oz[j] = t * dz;
    }
}

DRAPE_WIDE_KERNEL
void addRun(std::size_t m, const double* DRAPE_RESTRICT in, double* DRAPE_RESTRICT out) {
    for (std::size_t j = 0; j < m; ++j)
        out[j] += in[j];
}

DRAPE_WIDE_KERNEL
void subtractRun(std::size_t m, const double* DRAPE_RESTRICT in, double* DRAPE_RESTRICT out) {
    for (std::size_t j = 0; j < m; ++j)
        out[j] -= in[j];
}

/// The slot forces of one family on particles [b, e) (one coordinate): + for the particles
/// that start a slot, - for those that end one.
void addFamilyTerms(const detail::SpringFamily& fam, const double* in, double* out, std::size_t b,
                    std::size_t e) {
    std::size_t lo = std::max<std::size_t>(b, fam.first);
    std::size_t hi = std::min<std::size_t>(e, std::size_t(fam.first) + fam.count);
    if (lo < hi) addRun(hi - lo, in + fam.slot + (lo - fam.first), out + lo);
    const std::size_t endFirst = std::size_t(fam.first) + fam.offset;
    lo = std::max<std::size_t>(b, endFirst);
    hi = std::min<std::size_t>(e, endFirst + fam.count);
    if (lo < hi) subtractRun(hi - lo, in + fam.slot + (lo - endFirst), out + lo);
}

/// out[j] += sum over the G families of (start[j] - end[j]), for m particles; run holds each
/// family's start and end pointers.
/// (A template cannot be multi-versioned under Clang: the loop is inlined into one kernel per
/// group size below.)
template <int G>
[[gnu::always_inline]] inline void fusedTermsLoop(std::size_t m, const double* const* run,
                                                  double* DRAPE_RESTRICT out) {
    const double* DRAPE_RESTRICT s0 = run[0];
    const double* DRAPE_RESTRICT e0 = run[1];
    const double* DRAPE_RESTRICT s1 = G > 1 ? run[2] : run[0];
    const double* DRAPE_RESTRICT e1 = G > 1 ? run[3] : run[1];
    const double* DRAPE_RESTRICT s2 = G > 2 ? run[4] : run[0];
    const double* DRAPE_RESTRICT e2 = G > 2 ? run[5] : run[1];
    const double* DRAPE_RESTRICT s3 = G > 3 ? run[6] : run[0];
    const double* DRAPE_RESTRICT e3 = G > 3 ? run[7] : run[1];
    for (std::size_t j = 0; j < m; ++j) {
        double sum = s0[j] - e0[j];
        if (G > 1) sum += s1[j] - e1[j];
        if (G > 2) sum += s2[j] - e2[j];
        if (G > 3) sum += s3[j] - e3[j];
        out[j] += sum;
    }
}

DRAPE_WIDE_KERNEL void fusedTerms1(std::size_t m, const double* const* run, double* out) {
    fusedTermsLoop<1>(m, run, out);
}
DRAPE_WIDE_KERNEL void fusedTerms2(std::size_t m, const double* const* run, double* out) {
    fusedTermsLoop<2>(m, run, out);
}
DRAPE_WIDE_KERNEL void fusedTerms3(std::size_t m, const double* const* run, double* out) {
    fusedTermsLoop<3>(m, run, out);
}
DRAPE_WIDE_KERNEL void fusedTerms4(std::size_t m, const double* const* run, double* out) {
    fusedTermsLoop<4>(m, run, out);
}

void addFusedTerms(std::size_t groupSize, std::size_t m, const double* const* run, double* out) {
    switch (groupSize) {
    case 1:
        fusedTerms1(m, run, out);
        break;
    case 2:
        fusedTerms2(m, run, out);
        break;
    case 3:
        fusedTerms3(m, run, out);
        break;
    default:
        fusedTerms4(m, run, out);
        break;
    }
}
} // namespace

namespace {
/// Writes the slot forces of family `fam` for the starts a in [aLo, aHi) to (ox, oy, oz)[0 ..
/// aHi - aLo): 0 where a is not a start of the family (before its first slot, after its last),
/// so that the sums may add them without checking. (px, py, pz)[i - origin] is particle i.
void familyRange(const detail::SpringFamily& fam, std::ptrdiff_t aLo, std::ptrdiff_t aHi,
                 std::size_t origin, const double* px, const double* py, const double* pz,
                 const double* kSlot, const double* rest, double* ox, double* oy, double* oz) {
    const std::ptrdiff_t first = fam.first, last = first + std::ptrdiff_t(fam.count);
    const std::ptrdiff_t lo = std::clamp(first, aLo, aHi), hi = std::clamp(last, lo, aHi);
    const std::size_t head = std::size_t(lo - aLo), m = std::size_t(hi - lo);
    std::fill(ox, ox + head, 0.0);
    std::fill(oy, oy + head, 0.0);
    std::fill(oz, oz + head, 0.0);
    if (m > 0) {
        const std::size_t a = std::size_t(lo) - origin, slot = fam.slot + std::size_t(lo - first);
        familySlotForces(m, px + a, py + a, pz + a, px + a + fam.offset, py + a + fam.offset,
                         pz + a + fam.offset, kSlot + slot, rest + slot, ox + head, oy + head,
                         oz + head);
    }
    const std::size_t done = head + m, total = std::size_t(aHi - aLo);
    std::fill(ox + done, ox + total, 0.0);
    std::fill(oy + done, oy + total, 0.0);
    std::fill(oz + done, oz + total, 0.0);
}
} // namespace

// The family springs (SpringLayout::families) as loops over plain arrays that the
// compiler vectorises, in blocks that stay in cache. Each thread walks its particles in blocks
// of B. For a block [p, q) it copies the positions the block's slots read (up to the widest
// offset on either side) into coordinate arrays (x of every particle, then y, then z); computes,
// family by family, the force k (l - L0) / l d of every slot that starts at a particle of the
// block (from two contiguous runs of particles; a hole has k = 0 and L0 = 0, so its force is 0
// unless its ends coincide, which the l > 0 test also covers) into a small buffer that still
// holds the `offset` slots before the block (carried over from the block before, computed afresh
// at the start of a thread's range); then every particle of the block adds the slots it starts
// (+) and ends (-), family by family, and the sum goes onto f, after the start of the sum
// (gravity and damping, startForces) in the same pass. Nothing but the positions and f goes
// through memory: at 1e6 particles the slot forces' round trip alone was 96 MB per step.
//
// Each particle's sum has the same terms in the same order for any split of the particles
// among threads or blocks (a slot's force is the same function of the same positions wherever
// it is computed), so results do not depend on the thread count.
void ForceModel::addFamilySpringForces(const Vec3List& x, const ForceStart& start, Vec3List& f) {
    const auto& families = topology_->springLayout().families;
    const std::size_t n = x.size();
    const std::size_t maxOffset = maxFamilyOffset_;
    // The block: at least twice the widest offset, so that carrying the offset's slots over
    // costs at most half a block's copies.
    const std::size_t block = std::max<std::size_t>(2048, 2 * maxOffset);
    const std::size_t span = block + 2 * maxOffset; // positions a block reads
    const double* rest = topology_->springLayout().slotRest.data();
    const double* kSlot = slotStiffness_.data();
    detail::forChunks(executor_, n, [&](std::size_t b, std::size_t e) {
        if (b >= e) return;
        // Per thread: the block's sums, its positions, then for each family three coordinate
        // runs of block + offset slot forces (index k holds the slot starting at particle
        // p - offset + k).
        thread_local std::vector<double> scratch;
        std::size_t need = 3 * block + 3 * span;
        for (const detail::SpringFamily& fam : families)
            need += 3 * (block + fam.offset);
        if (scratch.size() < need) scratch.resize(need);
        double* sums = scratch.data();
        double* pos = sums + 3 * block;
        double* slotBuf = pos + 3 * span;
        for (std::size_t p = b; p < e; p += block) {
            const std::size_t q = std::min(e, p + block), m = q - p;
            // Positions [lo, hi): every particle a slot of this block (or, at the start of the
            // range, of the offset's slots before it) reads. pos[i - lo] is particle i.
            const std::size_t lo = p > maxOffset ? p - maxOffset : 0;
            const std::size_t hi = std::min(n, q + maxOffset);
            double* cx = pos;
            double* cy = pos + span;
            double* cz = pos + 2 * span;
            for (std::size_t i = lo; i < hi; ++i) {
                cx[i - lo] = x[i][0];
                cy[i - lo] = x[i][1];
                cz[i - lo] = x[i][2];
            }
            double* buf = slotBuf;
            for (const detail::SpringFamily& fam : families) {
                const std::size_t len = block + fam.offset;
                double* bx = buf;
                double* by = bx + len;
                double* bz = by + len;
                const std::ptrdiff_t ip = std::ptrdiff_t(p), off = fam.offset;
                if (p == b) { // the offset's slots before the range: computed here
                    familyRange(fam, ip - off, ip, lo, cx, cy, cz, kSlot, rest, bx, by, bz);
                } else { // carried over from the (full) block before
                    for (double* c : {bx, by, bz})
                        std::copy(c + block, c + block + fam.offset, c);
                }
                familyRange(fam, ip, ip + std::ptrdiff_t(m), lo, cx, cy, cz, kSlot, rest,
                            bx + fam.offset, by + fam.offset, bz + fam.offset);
                buf += 3 * len;
            }
            for (std::size_t c = 0; c < 3; ++c) {
                double* out = sums + c * block;
                std::fill(out, out + m, 0.0);
                // Up to four families at a time. Inside the group's interior (the particles
                // that start and end a slot of every family in it) one fused pass adds all its
                // terms; the particles outside take them family by family (the slots they do
                // not start or end hold 0). Which formula a particle gets depends on its index
                // only, never on the block: the same sums for any thread count.
                const double* groupBuf = slotBuf;
                for (std::size_t g = 0; g < families.size(); g += 4) {
                    const std::size_t gEnd = std::min(families.size(), g + 4);
                    std::size_t in0 = p, in1 = q; // the group's interior in this block
                    for (std::size_t r = g; r < gEnd; ++r) {
                        const detail::SpringFamily& fam = families[r];
                        in0 = std::max<std::size_t>(in0, std::size_t(fam.first) + fam.offset);
                        in1 = std::min<std::size_t>(in1, std::size_t(fam.first) + fam.count);
                    }
                    if (in0 >= in1) in0 = in1 = q; // no interior in this block
                    const double* run[8];
                    const double* fb = groupBuf;
                    for (std::size_t r = g; r < gEnd; ++r) {
                        const std::size_t len = block + families[r].offset;
                        const double* in = fb + c * len;
                        const double* starts = in + families[r].offset; // slot of particle p
                        const double* ends = in;                        // slot ending at p
                        addRun(in0 - p, starts, out);
                        subtractRun(in0 - p, ends, out);
                        addRun(q - in1, starts + (in1 - p), out + (in1 - p));
                        subtractRun(q - in1, ends + (in1 - p), out + (in1 - p));
                        run[2 * (r - g)] = starts + (in0 - p);
                        run[2 * (r - g) + 1] = ends + (in0 - p);
                        fb += 3 * len;
                    }
                    if (in0 < in1) addFusedTerms(gEnd - g, in1 - in0, run, out + (in0 - p));
                    groupBuf = fb;
                }
            }
            startForcesPlus(start, p, q, sums, sums + block, sums + 2 * block, f);
        }
    });
}

// The family springs of a mesh whose families do not suit the blocked pass (many families, or
// offsets so wide that a block would span much of the cloth: an imported mesh in an arbitrary
// vertex order), in three passes over the whole cloth, each a loop the compiler vectorises: the
// positions are copied into coordinate arrays; each slot's force k (l - L0) / l d is computed from
// two contiguous runs of particles (a hole has k = 0 and L0 = 0, so its force is 0 unless its ends
// coincide, which the l > 0 test also covers); and every particle adds the slots it starts (+) and
// ends (-), family by family, before the forces go back onto f. Each particle's sum has the same
// terms in the same order for any split of the particles among threads, so results do not depend on
// the thread count.
void ForceModel::addFamilySpringForcesWhole(const Vec3List& x, Vec3List& f) {
    const auto& families = topology_->springLayout().families;
    const std::size_t n = x.size();
    const std::size_t slots = topology_->springLayout().slotSpring.size();
    soaF_.resize(3 * n);
    slotF_.resize(3 * slots);
    detail::toCoordinateArrays(executor_, x, soaX_);
    const double* rest = topology_->springLayout().slotRest.data();
    const double* kSlot = slotStiffness_.data();
    detail::forChunks(executor_, slots, [&](std::size_t b, std::size_t e) {
        const double* px = soaX_.data();
        const double* py = px + n;
        const double* pz = py + n;
        double* fx = slotF_.data();
        double* fy = fx + slots;
        double* fz = fy + slots;
        for (const detail::SpringFamily& fam : families) {
            const std::size_t lo = std::max(b, fam.slot), hi = std::min(e, fam.slot + fam.count);
            if (lo >= hi) continue;
            // Slot j joins particle a = first + (j - slot) to a + offset.
            const std::size_t m = hi - lo;
            const double* ax = px + (fam.first + (lo - fam.slot));
            const double* ay = py + (fam.first + (lo - fam.slot));
            const double* az = pz + (fam.first + (lo - fam.slot));
            const double* bx = ax + fam.offset;
            const double* by = ay + fam.offset;
            const double* bz = az + fam.offset;
            const double* k = kSlot + lo;
            const double* l0 = rest + lo;
            double* ox = fx + lo;
            double* oy = fy + lo;
            double* oz = fz + lo;
            familySlotForces(m, ax, ay, az, bx, by, bz, k, l0, ox, oy, oz);
        }
    });
    detail::forChunks(executor_, n, [&](std::size_t b, std::size_t e) {
        for (std::size_t c = 0; c < 3; ++c) {
            double* out = soaF_.data() + c * n;
            const double* in = slotF_.data() + c * slots;
            std::fill(out + b, out + e, 0.0);
            // Up to four families at a time. Inside the group's interior (the particles that
            // start and end a slot of every family in it) one fused pass adds all its terms;
            // the particles outside take them family by family. Which formula a particle gets
            // depends on its index only, never on the chunk: the same sums for any thread count.
            for (std::size_t g = 0; g < families.size(); g += 4) {
                const std::size_t gEnd = std::min(families.size(), g + 4);
                std::size_t lo = b, hi = e;
                for (std::size_t q = g; q < gEnd; ++q) {
                    const detail::SpringFamily& fam = families[q];
                    lo = std::max<std::size_t>(lo, std::size_t(fam.first) + fam.offset);
                    hi = std::min<std::size_t>(hi, std::size_t(fam.first) + fam.count);
                }
                if (lo >= hi) lo = hi = e; // no interior in this chunk: all family by family
                for (std::size_t q = g; q < gEnd; ++q) {
                    addFamilyTerms(families[q], in, out, b, lo);
                    addFamilyTerms(families[q], in, out, hi, e);
                }
                if (lo < hi) {
                    const double* run[8];
                    for (std::size_t q = g; q < gEnd; ++q) {
                        const detail::SpringFamily& fam = families[q];
                        run[2 * (q - g)] = in + fam.slot + (lo - fam.first); // starts
                        run[2 * (q - g) + 1] =
                            in + fam.slot + (lo - fam.first - fam.offset); // ends
                    }
                    addFusedTerms(gEnd - g, hi - lo, run, out + lo);
                }
            }
        }
        const double* px = soaF_.data();
        const double* py = px + n;
        const double* pz = py + n;
        for (std::size_t i = b; i < e; ++i) {
            f[i][0] += px[i];
            f[i][1] += py[i];
            f[i][2] += pz[i];
        }
    });
}

// Why a flow and not a force (Velocity-Verlet, see integrators.cpp): with the damping in the
// force sum, the closing half kick evaluates it at the half-step velocity v(t + dt/2), which
// differs from v(t + dt) by dt/2 a: an O(dt^2) error in every step's velocity, so the method
// is first order (measured 1.008 on the damped breathing triangle). Velocity-Verlet instead
// runs the damping as its own sub-problem, v' = -M^-1 C(x) v at frozen x, for dt/2 before the
// opening half kick and dt/2 after the closing one (splitting around the conservative
// kick-drift-kick).
//
// The sub-problem is linear in v, but its exact solution exp(-tau M^-1 C) couples the whole
// spring network. Each spring's own flow B_s(tau) is exact and cheap (sweepSpringDamping), so
// the springs are composed in a sweep: F(tau) = B_K(tau) ... B_1(tau) (spring 1 first) before
// the kicks, and the reverse R(tau) = B_1(tau) ... B_K(tau) (spring K first) after them:
//   step = L(h) R(h) V(dt) F(h) L(h)      (h = dt/2, rightmost first; V the kick-drift-kick,
//                                          L the exact particle damping)
// One sweep alone is only a first-order approximation of exp(-tau M^-1 C), but the step is
// its own adjoint: with B_s(-tau)^-1 = B_s(tau) (exact flows), F(-h)^-1 = R(h), R(-h)^-1 = F(h),
// and V and L time-symmetric, step(-dt)^-1 = step(dt). A consistent self-adjoint one-step
// method has even order, so the step is second order (local error O(dt^3)); measured 2.000 on
// the damped breathing triangle. (With aerodynamics V is symmetric only up to O(dt^3), its
// predicted end velocity, which leaves the order at 2: measured 1.97 on an irregular sheet.) It
// costs one pass over the springs on each side, two per step (a symmetric forward-and-back sweep on
// each side would be four).
//
// Every B_s only shrinks the rate of extension of its spring and conserves momentum, so a sweep
// never adds kinetic energy, at any tau: unlike the force form (stable only for
// dt lambda_max(M^-1 C) < 2) the damping sets no time-step limit. A state with no spring
// extending (rest, rigid motion) is left exactly as it is.
//
// Why not evaluate the damping at a predicted end velocity v* = v(t + dt/2) + dt/2 a instead
// (also second order, tried before): it needs a second evaluation of the velocity terms after
// the contact force term, which reads the summed force (a contact that cancels
// what presses a resting particle into a body or along it then misses the damping), it damps
// stiff modes only for dt lambda < 2, and it changed how Experiment II settled on the desk.
//
// Order of a sweep over the packed springs (by colour within each block,
// dampingSweepOrder): the inner blocks touch disjoint particles, so running them in
// parallel is the same as running them one after the other; forward = the blocks (each front to
// back), then the crossing springs; backward = the exact reverse. The result is the same for any
// thread count.
void ForceModel::applySpringDampingFlow(const Vec3List& x, Vec3List& v,
                                        const std::vector<double>& invMass, double tau,
                                        bool forward, Vec3List* heldImpulse) {
    const double c = settings_.springDamping;
    if (!(c > 0.0)) return;
    std::size_t slot = 0;
    for (const Entry& e : pipeline_) {
        if (e.term == Term::SpringDamping) slot = e.timerSlot;
    }
    ScopedPhase timer(timers_, slot);
    const detail::PackedSprings& order = *dampingOrder_;
    const std::size_t nb = order.starts.size() - 2; // inner blocks; the last range crosses
    auto range = [&](std::size_t k) {
        const std::size_t b = order.starts[k], e = order.starts[k + 1];
        if (forward) {
            sweepSpringDamping<true>(order.springs, b, e, c, tau, x, v, invMass, heldImpulse);
        } else {
            sweepSpringDamping<false>(order.springs, b, e, c, tau, x, v, invMass, heldImpulse);
        }
    };
    auto blocks = [&]() {
        auto body = [&](std::size_t b, std::size_t end) {
            for (std::size_t k = b; k < end; ++k)
                range(k);
        };
        detail::forChunks(executor_, nb, body, 1);
    };
    if (forward) {
        blocks();
        range(nb);
    } else {
        range(nb);
        blocks();
    }
}

bool ForceModel::hasAero() const {
    for (const Entry& e : pipeline_) {
        if (e.term == Term::Aero) return true;
    }
    return false;
}

void ForceModel::aeroForces(const Vec3List& x, const Vec3List& v, Vec3List& f) {
    f.assign(x.size(), Vec3::Zero());
    for (const Entry& e : pipeline_) {
        if (e.term != Term::Aero) continue;
        ScopedPhase timer(timers_, e.timerSlot);
        addAeroForces(topology_->triangles(), settings_.aero, x, v, f);
    }
}

void ForceModel::assembleJacobians(const Vec3List& x, bool clampCompression,
                                   Eigen::SparseMatrix<double>& dfdx,
                                   Eigen::SparseMatrix<double>& dfdv) const {
    const auto n3 = static_cast<Eigen::Index>(3 * x.size());
    const auto& springs = topology_->springs();
    std::vector<Eigen::Triplet<double>> kx, kv;
    kx.reserve(springs.size() * 36);
    auto addBlock = [](std::vector<Eigen::Triplet<double>>& out, Index r, Index c,
                       const Eigen::Matrix3d& b) {
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)
                out.emplace_back(3 * static_cast<Eigen::Index>(r) + i,
                                 3 * static_cast<Eigen::Index>(c) + j, b(i, j));
    };
    for (std::size_t s = 0; s < springs.size(); ++s) {
        const Spring& sp = springs[s];
        const Eigen::Matrix3d K =
            springJacobianBlock(x[sp.a], x[sp.b], stiffness_[s], sp.restLength, clampCompression);
        addBlock(kx, sp.a, sp.a, -K);
        addBlock(kx, sp.a, sp.b, K);
        addBlock(kx, sp.b, sp.a, K);
        addBlock(kx, sp.b, sp.b, -K);
    }
    if (settings_.springDamping > 0.0) {
        kv.reserve(springs.size() * 36 + x.size() * 3);
        for (const Spring& sp : springs) {
            const Vec3 d = x[sp.b] - x[sp.a];
            const double l2 = d.squaredNorm();
            if (l2 == 0.0) continue;
            const Eigen::Matrix3d C = settings_.springDamping * (d * d.transpose()) / l2;
            addBlock(kv, sp.a, sp.a, -C);
            addBlock(kv, sp.a, sp.b, C);
            addBlock(kv, sp.b, sp.a, C);
            addBlock(kv, sp.b, sp.b, -C);
        }
    }
    if (settings_.damping > 0.0) {
        for (Eigen::Index i = 0; i < n3; ++i)
            kv.emplace_back(i, i, -settings_.damping);
    }
    dfdx.resize(n3, n3);
    dfdx.setFromTriplets(kx.begin(), kx.end());
    dfdv.resize(n3, n3);
    dfdv.setFromTriplets(kv.begin(), kv.end());
}

void ForceModel::setUserForce(Index i, const Vec3& force) {
    if (i >= mass_.size()) {
        throw Error(ErrorCode::IndexOutOfRange, "user force on particle " + std::to_string(i) +
                                                    " but the cloth has " +
                                                    std::to_string(mass_.size()) + " particles");
    }
    if (!force.allFinite()) {
        throw Error(ErrorCode::NonFinite,
                    "user force on particle " + std::to_string(i) + " is not finite");
    }
    for (std::size_t k = 0; k < userIndices_.size(); ++k) {
        if (userIndices_[k] == i) {
            userForces_[k] = force;
            return;
        }
    }
    const bool wasEmpty = userIndices_.empty();
    userIndices_.push_back(i);
    userForces_.push_back(force);
    if (wasEmpty) rebuildPipeline();
}

void ForceModel::clearUserForces() {
    userIndices_.clear();
    userForces_.clear();
    rebuildPipeline();
}

void ForceModel::setWind(const Vec3& wind) {
    if (!wind.allFinite()) throw Error(ErrorCode::NonFinite, "wind velocity is not finite");
    settings_.aero.wind = wind;
}

void ForceModel::setAero(const AeroSettings& aero) {
    settings_.aero = aero;
    rebuildPipeline();
}

void ForceModel::setGravity(const Vec3& g) {
    if (!g.allFinite()) throw Error(ErrorCode::NonFinite, "gravity is not finite");
    settings_.gravity = g;
    rebuildPipeline();
}

void ForceModel::addExternalForce(std::string name, ExternalForce force) {
    if (!force) throw Error(ErrorCode::InvalidArgument, "external force '" + name + "' is empty");
    externals_.emplace_back(std::move(name), std::move(force));
    rebuildPipeline();
}

void ForceModel::setContacts(std::shared_ptr<ContactSet> contacts) {
    contacts_ = std::move(contacts);
    rebuildPipeline();
}

} // namespace drape
