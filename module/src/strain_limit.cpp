// Strain limiters: the paper's stress-ordered walk and Provot's iterative fix.
#include "drape/strain_limit.hpp"

#include "drape/settings.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

namespace drape {

double maxSpringStrain(const ClothTopology& topology, const std::vector<Vec3>& x) {
    double m = -std::numeric_limits<double>::infinity();
    for (const Spring& s : topology.springs()) {
        m = std::max(m, (x[s.b] - x[s.a]).norm() / s.restLength - 1.0);
    }
    return m;
}

double meanSpringStrain(const ClothTopology& topology, const std::vector<Vec3>& x) {
    double sum = 0.0;
    for (const Spring& s : topology.springs()) sum += (x[s.b] - x[s.a]).norm() / s.restLength - 1.0;
    return topology.springCount() ? sum / static_cast<double>(topology.springCount()) : 0.0;
}

StrainLimitStats limitStrainStressOrdered(const ClothTopology& topology,
                                          const std::vector<double>& invMass,
                                          const std::vector<double>& stiffness,
                                          const LimiterSettings& s, std::vector<Vec3>& x,
                                          StressOrderScratch& scratch, bool oneSided) {
    StrainLimitStats stats;
    const double stretchLimit = 1.0 + s.maxStrain;
    const double stopLimit = 1.0 + s.maxStrain + s.tolerance;
    const auto& springs = topology.springs();
    const auto& off = topology.adjacencyOffsets();
    const auto& nbr = topology.adjacentParticles();
    const auto& spr = topology.adjacentSprings();
    const std::size_t n = x.size();

    // One pass over the springs gives both the stress keys and the largest strain.
    auto& key = scratch.key;
    key.assign(n, 0.0);
    double worst = 0.0;
    for (std::size_t si = 0; si < springs.size(); ++si) {
        const Spring& sp = springs[si];
        const double l = (x[sp.b] - x[sp.a]).norm();
        worst = std::max(worst, l / sp.restLength);
        const double t = stiffness[si] * std::abs(l - sp.restLength);
        key[sp.a] += t;
        key[sp.b] += t;
    }
    stats.maxStrainBefore = worst - 1.0;
    stats.maxStrainAfter = stats.maxStrainBefore;
    if (worst <= stopLimit) return stats;

    for (std::size_t i = 0; i < n; ++i) {
        if (invMass[i] == 0.0) key[i] = std::numeric_limits<double>::infinity();
    }
    auto& order = scratch.order;
    order.resize(n);
    for (std::size_t i = 0; i < n; ++i) order[i] = static_cast<Index>(i);
    std::sort(order.begin(), order.end(),
              [&](Index a, Index b) { return key[a] != key[b] ? key[a] > key[b] : a < b; });

    auto& fixed = scratch.fixed;
    for (int round = 0; round < s.maxRounds; ++round) {
        fixed.assign(n, 0);
        for (std::size_t i = 0; i < n; ++i) fixed[i] = invMass[i] == 0.0;
        // Each spring is looked at once per round, from whichever end is visited first. The
        // largest strain seen decides whether another round is needed.
        worst = 0.0;
        for (std::size_t step = 0; step < n; ++step) {
            // Odd rounds walk the order backwards (a symmetric Gauss-Seidel sweep), which
            // carries corrections back up toward the anchors and converges faster.
            const Index p = order[(round % 2 == 0 || oneSided) ? step : n - 1 - step];
            for (Index k = off[p]; k < off[p + 1]; ++k) {
                const Index q = nbr[k];
                if (fixed[q]) continue;
                const Vec3 d = x[q] - x[p];
                const double l = d.norm();
                const double rest = springs[spr[k]].restLength;
                worst = std::max(worst, l / rest);
                const double lmax = stretchLimit * rest;
                if (l <= lmax) continue;
                if (oneSided || invMass[p] == 0.0) {
                    x[q] = x[p] + (lmax / l) * d; // pull q along the spring toward p
                    fixed[q] = 1;
                } else {
                    // Provot's rule for two free ends: both move, by inverse-mass share.
                    const double wp = invMass[p], wq = invMass[q];
                    const Vec3 corr = ((l - lmax) / (l * (wp + wq))) * d;
                    x[p] += wp * corr;
                    x[q] -= wq * corr;
                }
                ++stats.corrections;
            }
            fixed[p] = 1; // regulated: later particles no longer adjust it this round
        }
        stats.rounds = round + 1;
        // Corrections later in a round can re-stretch springs looked at earlier, so the
        // strain seen during the walk is only a lower bound: measure before stopping.
        if (worst <= stopLimit) {
            stats.maxStrainAfter = maxSpringStrain(topology, x);
            if (stats.maxStrainAfter + 1.0 <= stopLimit) return stats;
        }
    }
    stats.maxStrainAfter = maxSpringStrain(topology, x);
    return stats;
}

StrainLimitStats limitStrainProvot(const ClothTopology& topology,
                                   const std::vector<double>& invMass, const LimiterSettings& s,
                                   std::vector<Vec3>& x) {
    StrainLimitStats stats;
    const double stretchLimit = 1.0 + s.maxStrain;
    const double stopLimit = 1.0 + s.maxStrain + s.tolerance;
    stats.maxStrainBefore = maxSpringStrain(topology, x);
    stats.maxStrainAfter = stats.maxStrainBefore;
    if (stats.maxStrainBefore + 1.0 <= stopLimit) return stats;
    for (int sweep = 0; sweep < s.maxRounds; ++sweep) {
        for (const Spring& sp : topology.springs()) {
            const double wa = invMass[sp.a], wb = invMass[sp.b];
            const Vec3 d = x[sp.b] - x[sp.a];
            const double l = d.norm();
            const double lmax = stretchLimit * sp.restLength;
            if (l <= lmax || wa + wb == 0.0) continue;
            const Vec3 corr = ((l - lmax) / (l * (wa + wb))) * d;
            x[sp.a] += wa * corr;
            x[sp.b] -= wb * corr;
            ++stats.corrections;
        }
        stats.rounds = sweep + 1;
        stats.maxStrainAfter = maxSpringStrain(topology, x);
        if (stats.maxStrainAfter + 1.0 <= stopLimit) break;
    }
    return stats;
}

} // namespace drape
