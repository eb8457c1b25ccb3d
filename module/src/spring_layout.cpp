// The kernels' spring layouts (spring_layout.hpp): families, packed blocks, the damping sweep's
// order and the rest lengths in the forms the kernels read, built once per topology.
#include "spring_layout.hpp"

#include <algorithm>
#include <cstdint>

namespace drape::detail {

SpringBlocks makeSpringBlocks(const ClothTopology& topology, const std::vector<Index>& subset,
                              std::size_t blocks) {
    const std::size_t n = topology.particleCount();
    blocks = std::max<std::size_t>(1, std::min(blocks, n));
    SpringBlocks out;
    out.inner.resize(blocks);
    auto blockOf = [&](Index i) { return static_cast<std::size_t>(i) * blocks / n; };
    const auto& springs = topology.springs();
    for (Index s : subset) {
        const std::size_t ba = blockOf(springs[s].a), bb = blockOf(springs[s].b);
        if (ba == bb) {
            out.inner[ba].push_back(s);
        } else {
            out.crossing.push_back(s);
        }
    }
    return out;
}

SpringBlocks makeSpringBlocks(const ClothTopology& topology, std::size_t blocks) {
    std::vector<Index> all(topology.springCount());
    for (std::size_t s = 0; s < all.size(); ++s)
        all[s] = static_cast<Index>(s);
    return makeSpringBlocks(topology, all, blocks);
}

namespace {
/// The springs of `blocks` copied out range by range (inner blocks, then the crossing ones).
PackedSprings pack(const ClothTopology& topology, const SpringBlocks& blocks) {
    PackedSprings out;
    const auto& springs = topology.springs();
    auto add = [&](const std::vector<Index>& list) {
        for (Index s : list) {
            out.springs.push_back(springs[s]);
            out.index.push_back(s);
        }
        out.starts.push_back(out.springs.size());
    };
    out.starts.push_back(0);
    for (const auto& inner : blocks.inner)
        add(inner);
    add(blocks.crossing);
    return out;
}
} // namespace

std::size_t springBlockCount(std::size_t particleCount) {
    return std::min<std::size_t>(64, 1 + particleCount / 16384);
}

// The damping sweep updates each spring's two velocities from the values the springs before it
// left, so springs that share a particle form a chain the processor has to run one after the
// other (the velocity is stored, loaded again and goes through a division before the next
// spring can start). A sheet's springs come grouped by particle, so nearly every spring waits
// for the one before it. Within each packed range the sweep therefore visits the springs by
// greedy edge colour: a spring gets the lowest colour not yet taken at either of its ends, and
// the springs of one colour, which share no particle, run back to back. Any fixed order gives
// a valid sweep (the backward sweep is its exact reverse); this one only runs faster.
PackedSprings dampingSweepOrder(const ClothTopology& topology) {
    PackedSprings out;
    {
        const PackedSprings all =
            pack(topology, makeSpringBlocks(topology, springBlockCount(topology.particleCount())));
        out.starts = all.starts;
        out.springs.reserve(all.springs.size());
        out.index.reserve(all.springs.size());
        std::vector<std::uint64_t> taken(topology.particleCount(), 0); // colours at each particle
        std::vector<unsigned> colour;
        std::vector<std::size_t> order;
        for (std::size_t r = 0; r + 1 < all.starts.size(); ++r) {
            const std::size_t b = all.starts[r], e = all.starts[r + 1];
            colour.assign(e - b, 0);
            for (std::size_t s = b; s < e; ++s) {
                const Spring& sp = all.springs[s];
                const std::uint64_t used = taken[sp.a] | taken[sp.b];
                unsigned c = 0;
                while (c < 63 && ((used >> c) & 1u))
                    ++c; // more than 63 colours share the last
                colour[s - b] = c;
                taken[sp.a] |= std::uint64_t(1) << c;
                taken[sp.b] |= std::uint64_t(1) << c;
            }
            for (std::size_t s = b; s < e; ++s)
                taken[all.springs[s].a] = taken[all.springs[s].b] = 0;
            order.resize(e - b);
            for (std::size_t k = 0; k < order.size(); ++k)
                order[k] = k;
            std::stable_sort(order.begin(), order.end(),
                             [&](std::size_t p, std::size_t q) { return colour[p] < colour[q]; });
            for (std::size_t k : order) {
                out.springs.push_back(all.springs[b + k]);
                out.index.push_back(all.index[b + k]);
            }
        }
    }
    return out;
}

namespace {

// Families: the springs grouped by offset b - a, each group split into runs wherever more
// than kMaxGap consecutive slots would be empty. A run becomes a family when it has at least
// kMinSprings springs and fills at least 40 % of its slots (a sheet's alternating diagonals
// fill about half); its springs are then evaluated in contiguous memory. The rest stay loose.
void bakeFamilies(const std::vector<Spring>& springs, SpringLayout& out) {
    constexpr Index kMaxGap = 4;
    constexpr std::size_t kMinSprings = 8;
    out.families.clear();
    out.slotSpring.clear();
    out.slotRest.clear();
    out.slotInverseSquaredRest.clear();
    out.looseSprings.clear();
    out.springSlot.assign(springs.size(), kNoSlot);
    std::vector<Index> order(springs.size());
    for (std::size_t s = 0; s < order.size(); ++s)
        order[s] = static_cast<Index>(s);
    auto offsetOf = [&](Index s) { return springs[s].b - springs[s].a; };
    std::sort(order.begin(), order.end(), [&](Index p, Index q) {
        const Index op = offsetOf(p), oq = offsetOf(q);
        return op != oq ? op < oq : springs[p].a < springs[q].a;
    });
    std::vector<unsigned char> inFamily(springs.size(), 0);
    for (std::size_t i = 0; i < order.size();) {
        // One run: same offset, gaps of at most kMaxGap empty slots.
        std::size_t j = i + 1;
        while (j < order.size() && offsetOf(order[j]) == offsetOf(order[i]) &&
               springs[order[j]].a - springs[order[j - 1]].a <= kMaxGap + 1) {
            ++j;
        }
        const Index first = springs[order[i]].a;
        const Index span = springs[order[j - 1]].a - first + 1;
        const std::size_t count = j - i;
        if (count >= kMinSprings && 5 * count >= 2 * std::size_t(span)) {
            SpringFamily f{offsetOf(order[i]), first, span, out.slotSpring.size()};
            out.slotSpring.resize(f.slot + span, kNoParticle);
            out.slotRest.resize(f.slot + span, 0.0);
            out.slotInverseSquaredRest.resize(f.slot + span, 0.0);
            for (std::size_t k = i; k < j; ++k) {
                const Index s = order[k];
                const std::size_t slot = f.slot + (springs[s].a - first);
                out.slotSpring[slot] = s;
                out.slotRest[slot] = springs[s].restLength;
                out.slotInverseSquaredRest[slot] = out.inverseSquaredRest[s];
                out.springSlot[s] = slot;
                inFamily[s] = 1;
            }
            out.families.push_back(f);
        }
        i = j;
    }
    for (std::size_t s = 0; s < springs.size(); ++s)
        if (!inFamily[s]) out.looseSprings.push_back(static_cast<Index>(s));
}

} // namespace

std::shared_ptr<const SpringLayout> optimise(const ClothTopology& topology) {
    auto out = std::make_shared<SpringLayout>();
    const auto& springs = topology.springs();
    out->inverseSquaredRest.resize(springs.size());
    for (std::size_t s = 0; s < springs.size(); ++s)
        out->inverseSquaredRest[s] = 1.0 / (springs[s].restLength * springs[s].restLength);
    const auto& adjacent = topology.adjacentSprings();
    out->adjacentInverseSquaredRest.resize(adjacent.size());
    for (std::size_t k = 0; k < adjacent.size(); ++k)
        out->adjacentInverseSquaredRest[k] = out->inverseSquaredRest[adjacent[k]];
    bakeFamilies(springs, *out);
    out->packedLoose = pack(topology, makeSpringBlocks(topology, out->looseSprings,
                                                       springBlockCount(topology.particleCount())));
    return out;
}

} // namespace drape::detail
