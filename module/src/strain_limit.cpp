// Strain limiters: the paper's stress-ordered walk and Provot's iterative fix.
#include "drape/strain_limit.hpp"

#include "drape/settings.hpp"

#include "parallel.hpp"

#include <algorithm>
#include <cstdint>
#include <cmath>
#include <limits>
#include <mutex>
#include <numeric>

namespace drape {

double maxSpringStrain(const ClothTopology& topology, const std::vector<Vec3>& x,
                       detail::ThreadPool* pool) {
    if (topology.springCount() == 0) return -std::numeric_limits<double>::infinity();
    const auto& springs = topology.springs();
    const auto& inv2 = topology.inverseSquaredRestLengths();
    // The largest squared length ratio, one square root at the end.
    double worst2 = 0.0;
    std::mutex merge;
    auto range = [&](std::size_t b, std::size_t e) {
        double m = 0.0;
        for (std::size_t s = b; s < e; ++s) {
            m = std::max(m, (x[springs[s].b] - x[springs[s].a]).squaredNorm() * inv2[s]);
        }
        std::lock_guard<std::mutex> lock(merge);
        worst2 = std::max(worst2, m);
    };
    if (pool) {
        pool->parallelFor(springs.size(), range, 16384);
    } else {
        range(0, springs.size());
    }
    return std::sqrt(worst2) - 1.0;
}

double meanSpringStrain(const ClothTopology& topology, const std::vector<Vec3>& x) {
    double sum = 0.0;
    for (const Spring& s : topology.springs()) sum += (x[s.b] - x[s.a]).norm() / s.restLength - 1.0;
    return topology.springCount() ? sum / static_cast<double>(topology.springCount()) : 0.0;
}

namespace {

/// Sorts `order` (a permutation of [0, n)) by key descending, ties by index ascending. Starts
/// from the given permutation: an insertion sort that gives up after a budget of moves (the
/// previous step's order is usually almost right) and then uses std::sort. Either way the
/// result is the unique order the comparison defines.
void sortByStress(const std::vector<double>& key, std::vector<Index>& order) {
    auto before = [&](Index a, Index b) { return key[a] != key[b] ? key[a] > key[b] : a < b; };
    const std::size_t n = order.size();
    std::size_t budget = 8 * n + 64;
    for (std::size_t i = 1; i < n; ++i) {
        const Index v = order[i];
        std::size_t j = i;
        while (j > 0 && before(v, order[j - 1])) {
            order[j] = order[j - 1];
            --j;
            if (--budget == 0) {
                order[j] = v;
                std::sort(order.begin(), order.end(), before);
                return;
            }
        }
        order[j] = v;
    }
}

} // namespace

StrainLimitStats limitStrainStressOrdered(const ClothTopology& topology,
                                          const std::vector<double>& invMass,
                                          const std::vector<double>& stiffness,
                                          const LimiterSettings& s, std::vector<Vec3>& x,
                                          StressOrderScratch& scratch, bool oneSided,
                                          detail::ThreadPool* pool) {
    StrainLimitStats stats;
    const double stretchLimit = 1.0 + s.maxStrain;
    const double stopLimit = 1.0 + s.maxStrain + s.tolerance;
    const double stretch2 = stretchLimit * stretchLimit;
    const double stop2 = stopLimit * stopLimit;
    const double w = oneSided ? 1.0 : s.overRelaxation;
    const double floorLimit = 1.0 + 0.5 * s.maxStrain;
    const auto& springs = topology.springs();
    const auto& off = topology.adjacencyOffsets();
    const auto& nbr = topology.adjacentParticles();
    const auto& rest = topology.adjacentRestLengths();
    const std::size_t n = x.size();
    scratch.movedIndex.clear();
    scratch.movedFrom.clear();

    // The largest strain first, from squared lengths (no square roots): most steps of most
    // cloths end here.
    stats.maxStrainBefore = maxSpringStrain(topology, x, pool);
    stats.maxStrainAfter = stats.maxStrainBefore;
    if (stats.maxStrainBefore + 1.0 <= stopLimit) return stats;

    // Stress keys: the spring tension each particle receives; pinned particles first.
    auto& key = scratch.key;
    key.assign(n, 0.0);
    for (std::size_t si = 0; si < springs.size(); ++si) {
        const Spring& sp = springs[si];
        const double t = stiffness[si] * std::abs((x[sp.b] - x[sp.a]).norm() - sp.restLength);
        key[sp.a] += t;
        key[sp.b] += t;
    }
    for (std::size_t i = 0; i < n; ++i) {
        if (invMass[i] == 0.0) key[i] = std::numeric_limits<double>::infinity();
    }
    auto& order = scratch.order;
    if (order.size() != n) {
        order.resize(n);
        std::iota(order.begin(), order.end(), Index{0});
    }
    sortByStress(key, order);

    auto& moved = scratch.moved;
    moved.assign(n, 0);
    auto& rank = scratch.rank;
    rank.resize(n);
    for (std::size_t r = 0; r < n; ++r) rank[order[r]] = static_cast<Index>(r);
    // Change tracking. A spring found within the limit stays so until one of its ends moves:
    // movedAt[i] is the clock of particle i's last move, okAt[s] the clock at which spring s
    // was last found within the limit, and such a spring is skipped. A particle none of whose
    // springs can need a look is not visited at all: `pending` (by rank) holds the particles
    // still to visit in this round, `next` those for the next round; when a particle moves,
    // it and its neighbours go into both (into `pending` only if the walk has not passed them
    // yet). A skipped visit would have found nothing to do, and "regulated" is decided by the
    // rank (visited earlier in this round) rather than by a flag set on the visit, so the walk
    // and its result are exactly those of visiting every particle and every spring.
    const auto& spr = topology.adjacentSprings();
    auto& movedAt = scratch.movedAt;
    auto& okAt = scratch.okAt;
    auto& pulledRound = scratch.pulledRound;
    movedAt.assign(n, 1);
    okAt.assign(springs.size(), 0);
    pulledRound.assign(n, 0);
    std::uint32_t clock = 1;
    const std::size_t words = (n + 63) / 64;
    auto& pending = scratch.pending;
    auto& next = scratch.next;
    pending.assign(words, ~std::uint64_t{0});
    next.assign(words, 0);
    auto set = [](std::vector<std::uint64_t>& bits, std::size_t r) { bits[r >> 6] |= std::uint64_t{1} << (r & 63); };
    std::size_t pos = 0;    // rank of the particle being visited
    bool backwards = false; // direction of the current round
    // Tracking pays off when few particles move per round; while many do (more than n / 8 in
    // the last round), its bookkeeping costs more than it saves, and a plain round looks at
    // every particle and every spring instead: the same walk.
    bool tracking = true;
    auto touch = [&](Index i) {
        if (tracking) {
            movedAt[i] = ++clock;
            auto mark = [&](Index j) {
                const std::size_t r = rank[j];
                set(next, r);
                if (backwards ? r < pos : r > pos) set(pending, r);
            };
            mark(i);
            for (Index k = off[i]; k < off[i + 1]; ++k) mark(nbr[k]);
        }
        if (moved[i]) return;
        moved[i] = 1;
        scratch.movedIndex.push_back(i);
        scratch.movedFrom.push_back(x[i]);
    };
    // The next set rank at or after `from` (forwards) or at or before it (backwards); n if none.
    auto nextPending = [&](std::size_t from) -> std::size_t {
        if (!backwards) {
            for (std::size_t wd = from >> 6; wd < words; ++wd) {
                std::uint64_t bits = pending[wd];
                if (wd == (from >> 6)) bits &= ~std::uint64_t{0} << (from & 63);
                if (bits) return (wd << 6) + static_cast<std::size_t>(__builtin_ctzll(bits));
            }
            return n;
        }
        for (std::size_t wd = (from >> 6) + 1; wd-- > 0;) {
            std::uint64_t bits = pending[wd];
            if (wd == (from >> 6) && (from & 63) != 63) bits &= (std::uint64_t{1} << ((from & 63) + 1)) - 1;
            if (bits) return (wd << 6) + 63 - static_cast<std::size_t>(__builtin_clzll(bits));
        }
        return n;
    };
    // One overstretched spring p-q (q not yet regulated): Provot's rule, over-relaxed.
    auto correct = [&](Index p, Index q, const Vec3& d, double l2, double r, std::uint32_t roundTag) {
        const double l = std::sqrt(l2);
        // Over-relaxed length (w = 1: exactly the limit), never below (1 + maxStrain / 2) L0,
        // so a spring far past the limit is not flipped.
        const double target = std::max(l - w * (l - stretchLimit * r), floorLimit * r);
        if (oneSided || invMass[p] == 0.0) {
            touch(q);
            x[q] = x[p] + (target / l) * d; // pull q along the spring toward p
            pulledRound[q] = roundTag;
        } else {
            // Provot's rule for two free ends: both move, by inverse-mass share.
            const double wp = invMass[p], wq = invMass[q];
            const Vec3 corr = ((l - target) / (l * (wp + wq))) * d;
            if (wp > 0.0) touch(p);
            if (wq > 0.0) touch(q);
            x[p] += wp * corr;
            x[q] -= wq * corr;
        }
        ++stats.corrections;
    };
    auto& fixed = scratch.fixed;
    std::size_t correctionsLastRound = 0;
    for (int round = 0; round < s.maxRounds; ++round) {
        // Odd rounds walk the order backwards (a symmetric Gauss-Seidel sweep), which carries
        // corrections back up toward the anchors and converges faster.
        backwards = !oneSided && round % 2 == 1;
        const std::uint32_t roundTag = static_cast<std::uint32_t>(round) + 1;
        const std::size_t correctionsBefore = stats.corrections;
        if (round > 0) {
            const bool wasTracking = tracking;
            tracking = correctionsLastRound * 8 < n;
            if (tracking && wasTracking) {
                pending.swap(next);
            } else if (tracking) {
                // Back to tracking: everything counts as unchecked, every particle is visited.
                std::fill(pending.begin(), pending.end(), ~std::uint64_t{0});
                std::fill(movedAt.begin(), movedAt.end(), 1u);
                std::fill(okAt.begin(), okAt.end(), 0u);
                clock = 1;
            }
            std::fill(next.begin(), next.end(), 0);
        }
        if (!tracking) {
            // A plain round: one flag per particle, every spring looked at once.
            bool overStop = false;
            fixed.resize(n);
            for (std::size_t i = 0; i < n; ++i) fixed[i] = invMass[i] == 0.0;
            for (std::size_t step = 0; step < n; ++step) {
                pos = backwards ? n - 1 - step : step;
                const Index p = order[pos];
                for (Index k = off[p]; k < off[p + 1]; ++k) {
                    const Index q = nbr[k];
                    if (fixed[q]) continue;
                    const Vec3 d = x[q] - x[p];
                    const double l2 = d.squaredNorm();
                    const double r = rest[k];
                    const double r2 = r * r;
                    if (l2 <= stretch2 * r2) continue;
                    overStop = overStop || l2 > stop2 * r2;
                    correct(p, q, d, l2, r, roundTag);
                    if (oneSided || invMass[p] == 0.0) fixed[q] = 1;
                }
                fixed[p] = 1;
            }
            correctionsLastRound = stats.corrections - correctionsBefore;
            stats.rounds = round + 1;
            if (!overStop) {
                stats.maxStrainAfter = maxSpringStrain(topology, x, pool);
                if (stats.maxStrainAfter + 1.0 <= stopLimit) return stats;
            }
            continue;
        }
        if (n % 64 != 0) pending[words - 1] &= (std::uint64_t{1} << (n % 64)) - 1;
        // Regulated: pinned, visited earlier in this round, or pulled by a pinned particle.
        auto regulated = [&](Index q) {
            return invMass[q] == 0.0 || (backwards ? rank[q] > pos : rank[q] < pos) ||
                   pulledRound[q] == roundTag;
        };
        // Each spring is looked at once per round, from whichever end is visited first.
        // Whether one was seen beyond the stop limit decides whether another round is needed
        // (skipped springs are within the limit, so they cannot change that decision).
        bool overStop = false;
        for (pos = nextPending(backwards ? n - 1 : 0); pos < n;
             pos = (backwards ? (pos == 0 ? n : nextPending(pos - 1)) : nextPending(pos + 1))) {
            pending[pos >> 6] &= ~(std::uint64_t{1} << (pos & 63));
            const Index p = order[pos];
            for (Index k = off[p]; k < off[p + 1]; ++k) {
                const Index q = nbr[k];
                const Index si = spr[k];
                const bool clean = okAt[si] >= movedAt[p] && okAt[si] >= movedAt[q];
                if (regulated(q)) {
                    // The walk does not look at this spring in this round; if it may need a
                    // look, both ends are visited again in the next one (unless both are
                    // pinned: such a spring is never looked at).
                    if (!clean && (invMass[p] != 0.0 || invMass[q] != 0.0)) {
                        set(next, pos);
                        set(next, rank[q]);
                    }
                    continue;
                }
                if (clean) continue;
                const Vec3 d = x[q] - x[p];
                const double l2 = d.squaredNorm();
                const double r = rest[k];
                const double r2 = r * r; // compare squares: no division, no root
                if (l2 <= stretch2 * r2) {
                    okAt[si] = clock;
                    continue;
                }
                overStop = overStop || l2 > stop2 * r2;
                correct(p, q, d, l2, r, roundTag);
            }
        }
        correctionsLastRound = stats.corrections - correctionsBefore;
        stats.rounds = round + 1;
        // Corrections later in a round can re-stretch springs looked at earlier, so the
        // strain seen during the walk is only a lower bound: measure before stopping.
        if (!overStop) {
            stats.maxStrainAfter = maxSpringStrain(topology, x, pool);
            if (stats.maxStrainAfter + 1.0 <= stopLimit) return stats;
        }
    }
    stats.maxStrainAfter = maxSpringStrain(topology, x, pool);
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
