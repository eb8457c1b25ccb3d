// drape/strain_limit.hpp: strain limiters against "hyper elasticity" (paper section 3).
//
// Both limiters shorten springs longer than (1 + maxStrain) L0 by moving particles; a
// particle with zero inverse mass never moves. They only touch positions: the caller turns
// the displacement into a velocity change (v += dx / dt) so that velocities stay consistent.
#pragma once

#include "drape/topology.hpp"

#include <cstdint>
#include <vector>

namespace drape {

struct LimiterSettings;
namespace detail {
class ThreadPool;
}

/// What a limiter did in one step.
struct StrainLimitStats {
    int rounds = 0;               ///< rounds or sweeps run
    std::size_t corrections = 0;  ///< particle moves (stress-ordered) or spring fixes (Provot)
    double maxStrainBefore = 0.0; ///< largest (l - L0) / L0 before limiting [-]
    double maxStrainAfter = 0.0;  ///< largest (l - L0) / L0 after limiting [-]
};

/// Reusable buffers for the stress-ordered limiter (no allocation per step), and a record of
/// which particles the last call moved: movedIndex[j] moved from movedFrom[j] to where it is
/// now, so a caller can turn displacements into velocity changes without copying every
/// position before the call.
struct StressOrderScratch {
    std::vector<Index> order;  ///< stress order of the last limited step (reused as a start)
    std::vector<double> key;
    std::vector<Index> rank;   ///< position of each particle in `order`
    std::vector<unsigned char> fixed; ///< regulated in this round (plain rounds)
    std::vector<unsigned char> moved;
    std::vector<std::uint32_t> pulledRound; ///< round in which a pinned particle pulled it
    std::vector<std::uint64_t> pending, next; ///< particles (by rank) to visit, as bits
    std::vector<std::uint32_t> movedAt; ///< change tracking: clock of a particle's last move
    std::vector<std::uint32_t> okAt;    ///< clock at which a spring was last within the limit
    std::vector<Index> movedIndex;
    std::vector<Vec3> movedFrom;
};

/// The paper's stress-ordered limiter (section 3.2): "apply Provot's method and sequentially
/// update P_k1 ... P_kn" in stress order, a regulated particle not being adjusted again in the
/// same round. A round visits the particles in stress order; for the current particle p,
/// every overstretched spring to a neighbour q not yet regulated this round is shortened by
/// Provot's rule: only q moves when p is pinned (and q is then regulated), only p when q is
/// pinned, otherwise both ends move by their inverse-mass share. Then p counts as regulated.
/// Rounds repeat (same order, alternately forwards and backwards) until every spring is
/// within (1 + maxStrain + tolerance) L0, or maxRounds is reached.
///
/// A correction shortens a spring of length l > lmax = (1 + maxStrain) L0 to
/// max(l - w (l - lmax), (1 + maxStrain / 2) L0), w = LimiterSettings::overRelaxation in
/// [1, 2). The default w = 1 is Provot's rule (exactly lmax). Over-relaxing leaves springs
/// slightly below the limit and cuts the rounds (Experiment I, 10 s: 54 -> 38 per step on
/// average with w = 1.9), at a price: the walk then amplifies rounding differences
/// (Experiment I at 1e-6 scale departs from the unit-scale run by 0.1 spacing after 200
/// steps with w = 1.9, by 1e-12 with w = 1), so it is an option, not the default.
///
/// Stress: the magnitude of the spring forces a particle receives, sum_s k_s |l_s - L0_s|,
/// in the configuration being limited; pinned particles come first; ties by index, so the
/// order is a pure function of the state. We sort by the spring forces rather than by the
/// net force |f_i|: in a hanging or resting cloth the net force is near zero everywhere
/// (springs balance gravity) and sorting by it sorts noise, while the spring tension is
/// largest at the suspension points and falls off away from them, the walk of figure 5.
/// The order is found by an insertion sort that starts from the previous step's order (the
/// stress order changes little from one step to the next, so this is linear in practice);
/// when it would need more than a few moves per particle it falls back to std::sort. Both
/// give the same order, the unique one the comparison defines.
///
/// With oneSided = true, q is always pulled the whole way toward p and then fixed for the
/// round (the most literal reading of the paper's figure 5, even when p is free).
/// That variant does not conserve momentum: a particle drags its neighbours without being
/// pulled back, and on Experiment I (35 x 35, k 20) it pumps energy into the sheet until it
/// blows up, whatever the order. It is kept for comparison
/// (LimiterKind::StressOrderedOneSided), not as a default.
StrainLimitStats limitStrainStressOrdered(const ClothTopology& topology,
                                          const std::vector<double>& invMass,
                                          const std::vector<double>& stiffness,
                                          const LimiterSettings& s, std::vector<Vec3>& x,
                                          StressOrderScratch& scratch, bool oneSided = false,
                                          detail::ThreadPool* pool = nullptr);

/// Provot (1995): sweeps over the springs in index order; an overstretched spring is
/// shortened to (1 + maxStrain) L0, moving both ends by their inverse-mass share (only the
/// free end if one is fixed, nothing if both are). Sweeps until every spring is within
/// maxStrain + tolerance or maxRounds sweeps have run.
StrainLimitStats limitStrainProvot(const ClothTopology& topology,
                                   const std::vector<double>& invMass, const LimiterSettings& s,
                                   std::vector<Vec3>& x);

/// Largest strain (l - L0) / L0 over all springs (negative if all are compressed). With a
/// pool, the springs are split over its threads (the maximum does not depend on the split).
double maxSpringStrain(const ClothTopology& topology, const std::vector<Vec3>& x,
                       detail::ThreadPool* pool = nullptr);
/// Mean strain over all springs.
double meanSpringStrain(const ClothTopology& topology, const std::vector<Vec3>& x);

} // namespace drape
