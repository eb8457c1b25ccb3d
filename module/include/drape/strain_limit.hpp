// drape/strain_limit.hpp: strain limiters against "hyper elasticity" (paper section 3).
//
// Both limiters shorten springs longer than (1 + maxStrain) L0 by moving particles; a
// particle with zero inverse mass never moves. They only touch positions: the caller turns
// the displacement into a velocity change (v += dx / dt) so that velocities stay consistent.
#pragma once

#include "drape/topology.hpp"

#include <vector>

namespace drape {

struct LimiterSettings;

/// What a limiter did in one step.
struct StrainLimitStats {
    int rounds = 0;               ///< rounds or sweeps run
    std::size_t corrections = 0;  ///< particle moves (stress-ordered) or spring fixes (Provot)
    double maxStrainBefore = 0.0; ///< largest (l - L0) / L0 before limiting [-]
    double maxStrainAfter = 0.0;  ///< largest (l - L0) / L0 after limiting [-]
};

/// Reusable buffers for the stress-ordered limiter (no allocation per step).
struct StressOrderScratch {
    std::vector<Index> order;
    std::vector<double> key;
    std::vector<unsigned char> fixed;
};

/// Sorts particle indices by decreasing |f_i| (ties by increasing index, so the order is a
/// pure function of the forces).
void stressOrder(const std::vector<Vec3>& f, std::vector<Index>& order, std::vector<double>& key);

/// The paper's stress-ordered limiter (section 3.2). One round walks the particles by
/// decreasing force magnitude; the current particle p is fixed for the round, and each
/// overstretched neighbour q that is still free is pulled along the spring toward p until
/// the spring is (1 + maxStrain) L0 long, then fixed for the round. Springs whose two ends
/// were both fixed before either was visited may stay long; further rounds (same order, new
/// positions) pick them up, until every spring is within maxStrain + tolerance or
/// maxRounds is reached.
StrainLimitStats limitStrainStressOrdered(const ClothTopology& topology,
                                          const std::vector<double>& invMass,
                                          const std::vector<Vec3>& f, const LimiterSettings& s,
                                          std::vector<Vec3>& x, StressOrderScratch& scratch);

/// Provot (1995): sweeps over the springs in index order; an overstretched spring is
/// shortened to (1 + maxStrain) L0, moving both ends by their inverse-mass share (only the
/// free end if one is fixed, nothing if both are). Sweeps until every spring is within
/// maxStrain + tolerance or maxRounds sweeps have run.
StrainLimitStats limitStrainProvot(const ClothTopology& topology,
                                   const std::vector<double>& invMass, const LimiterSettings& s,
                                   std::vector<Vec3>& x);

/// Largest strain (l - L0) / L0 over all springs (negative if all are compressed).
double maxSpringStrain(const ClothTopology& topology, const std::vector<Vec3>& x);
/// Mean strain over all springs.
double meanSpringStrain(const ClothTopology& topology, const std::vector<Vec3>& x);

} // namespace drape
