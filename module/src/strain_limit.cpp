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

void stressOrderByTension(const ClothTopology& topology, const std::vector<double>& invMass,
                          const std::vector<double>& stiffness, const std::vector<Vec3>& x,
                          std::vector<Index>& order, std::vector<double>& key) {
    const std::size_t n = x.size();
    key.assign(n, 0.0);
    const auto& springs = topology.springs();
    for (std::size_t s = 0; s < springs.size(); ++s) {
        const Spring& sp = springs[s];
        const double t = stiffness[s] * std::abs((x[sp.b] - x[sp.a]).norm() - sp.restLength);
        key[sp.a] += t;
        key[sp.b] += t;
    }
    for (std::size_t i = 0; i < n; ++i) {
        if (invMass[i] == 0.0) key[i] = std::numeric_limits<double>::infinity();
    }
    order.resize(n);
    for (std::size_t i = 0; i < n; ++i) order[i] = static_cast<Index>(i);
    std::sort(order.begin(), order.end(), [&](Index a, Index b) {
        return key[a] != key[b] ? key[a] > key[b] : a < b;
    });
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

    stats.maxStrainBefore = maxSpringStrain(topology, x);
    stats.maxStrainAfter = stats.maxStrainBefore;
    if (stats.maxStrainBefore + 1.0 <= stopLimit) return stats;

    stressOrderByTension(topology, invMass, stiffness, x, scratch.order, scratch.key);
    auto& fixed = scratch.fixed;
    for (int round = 0; round < s.maxRounds; ++round) {
        fixed.assign(n, 0);
        for (std::size_t i = 0; i < n; ++i) fixed[i] = invMass[i] == 0.0;
        for (std::size_t step = 0; step < n; ++step) {
            const Index p = scratch.order[(round % 2 == 0 || oneSided) ? step : n - 1 - step];
            for (Index k = off[p]; k < off[p + 1]; ++k) {
                const Index q = nbr[k];
                if (fixed[q]) continue;
                const Vec3 d = x[q] - x[p];
                const double l = d.norm();
                const double lmax = stretchLimit * springs[spr[k]].restLength;
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
        stats.maxStrainAfter = maxSpringStrain(topology, x);
        if (stats.maxStrainAfter + 1.0 <= stopLimit) break;
    }
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
