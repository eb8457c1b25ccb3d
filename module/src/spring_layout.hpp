// The kernels' private view of a topology's springs: built once per topology by optimise()
// (ClothTopology::build calls it last, as Jolt's SoftBodySharedSettings::Optimize prepares its
// constraints), shared with the topology, never changed after. The public topology keeps the
// springs as the mesh gives them (Spring: a, b, rest length) and the adjacency; everything
// here is a layout of those for one pass, and each array says which pass reads it.
//
// The rest length is the spring list's L0 (the public topology); each kernel reads a copy made
// here in its own form and order: 1 / L0^2 per spring and per adjacency entry (the strain
// checks on squared lengths, no division), and per family slot L0 (the force pass) and
// 1 / L0^2 (the limiter's scan: the two kernels that read the slots).
#pragma once

#include "drape/topology.hpp"

#include <cstddef>
#include <memory>
#include <vector>

namespace drape::detail {

/// A run of springs that share the index offset b - a and whose first ends a are (nearly)
/// consecutive: slot j holds the spring from first + j to first + j + offset, or a hole. A
/// mesh generated row by row (a sheet) has most of its springs in a few families; the force
/// and strain kernels then read both ends from contiguous memory instead of through an index
/// list, and the compiler can vectorise them.
struct SpringFamily {
    Index offset;     ///< b - a of every spring in the family (> 0)
    Index first;      ///< first end a of slot 0
    Index count;      ///< slots; slot j has a = first + j
    std::size_t slot; ///< where the family's slots start in the per-slot arrays
};

/// SpringLayout::springSlot entry of a spring in no family.
inline constexpr std::size_t kNoSlot = static_cast<std::size_t>(-1);

/// Springs copied out in a fixed block order for the passes that read them front to back:
/// range r is springs[starts[r] .. starts[r + 1]), the inner blocks first (springs with both
/// ends in one contiguous range of particles), the springs crossing blocks last; index[j] is
/// the topology's index of springs[j]. Blocks never depend on the thread count, so the sums
/// are the same on one thread or many.
struct PackedSprings {
    std::vector<Spring> springs;
    std::vector<Index> index;
    std::vector<std::size_t> starts;
};

/// A fixed split of the springs for parallel accumulation. Particles are cut into `blocks`
/// contiguous index ranges; inner[b] lists (in index order) the springs with both ends in
/// block b, crossing the springs joining two blocks. Every particle then receives its inner
/// springs first, in index order, then its crossing springs, in index order: the same
/// floating-point sums whether the blocks run on one thread or many.
struct SpringBlocks {
    std::vector<std::vector<Index>> inner;
    std::vector<Index> crossing;
};
SpringBlocks makeSpringBlocks(const ClothTopology& topology, std::size_t blocks);
/// The same split of a subset of the springs (indices into topology.springs(), ascending).
SpringBlocks makeSpringBlocks(const ClothTopology& topology, const std::vector<Index>& subset,
                              std::size_t blocks);

/// Number of particle blocks of the packed spring layouts: one per 16384 particles, at most 64
/// (fixed by the particle count alone).
std::size_t springBlockCount(std::size_t particleCount);

/// Every spring of `topology` packed by block, each range ordered for the spring-damping sweep
/// (greedy edge colours: springs that share no particle run back to back). A cloth with spring
/// damping builds it once, at construction (ForceModel).
PackedSprings dampingSweepOrder(const ClothTopology& topology);

struct SpringLayout {
    /// 1 / L0^2 of each spring, in the topology's order: strain checks on squared lengths
    /// without a division (maxSpringStrain, the limiter's loose springs).
    std::vector<double> inverseSquaredRest;
    /// 1 / L0^2 of spring adjacentSprings()[k], next to the adjacency: the limiter's checks
    /// after a wave read a particle's springs from its adjacency.
    std::vector<double> adjacentInverseSquaredRest;

    /// The spring families (SpringFamily): every spring is in exactly one family slot or in
    /// looseSprings.
    std::vector<SpringFamily> families;
    /// Per family slot: its spring, or kNoParticle for a hole.
    std::vector<Index> slotSpring;
    /// Per family slot: the spring's rest length [m] (0 for a hole): the force pass.
    std::vector<double> slotRest;
    /// Per family slot: 1 / L0^2 (0 for a hole): the limiter's scan.
    std::vector<double> slotInverseSquaredRest;
    /// Per spring: its family slot, or kNoSlot for a loose spring.
    std::vector<std::size_t> springSlot;
    /// Springs in no family (irregular meshes), in index order.
    std::vector<Index> looseSprings;
    /// The loose springs packed by block: the force pass's layout for the springs in no
    /// family.
    PackedSprings packedLoose;
};

/// Builds the layout of `topology`'s springs (its springs and adjacency must be complete).
std::shared_ptr<const SpringLayout> optimise(const ClothTopology& topology);

} // namespace drape::detail
