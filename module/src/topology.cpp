// Topology: welding, validation, unique edges as linked springs, adjacency.
#include "drape/topology.hpp"

#include "drape/error.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>

namespace drape {

double automaticWeldTolerance(const std::vector<Vec3>& vertices) {
    bool any = false;
    Vec3 lo = Vec3::Zero(), hi = Vec3::Zero();
    for (const Vec3& p : vertices) {
        if (!p.allFinite()) continue; // weldVertices reports it with the vertex number
        lo = any ? lo.cwiseMin(p) : p;
        hi = any ? hi.cwiseMax(p) : p;
        any = true;
    }
    return 1e-9 * (hi - lo).norm();
}

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

std::size_t ClothTopology::springBlockCount() const {
    return std::min<std::size_t>(64, 1 + particleCount() / 16384);
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
            pack(topology, makeSpringBlocks(topology, topology.springBlockCount()));
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

std::shared_ptr<const ClothTopology> ClothTopology::build(const TriangleMesh& input,
                                                          const TopologyOptions& options) {
    if (input.vertices.empty()) throw Error(ErrorCode::InvalidMesh, "mesh has no vertices");
    if (options.weldTolerance &&
        !(*options.weldTolerance >= 0.0 && std::isfinite(*options.weldTolerance))) {
        throw Error(ErrorCode::InvalidArgument, "weldTolerance must be >= 0 and finite, got " +
                                                    std::to_string(*options.weldTolerance));
    }
    const double tolerance =
        options.weldTolerance ? *options.weldTolerance : automaticWeldTolerance(input.vertices);
    WeldResult welded = weldVertices(input, tolerance);
    validateMesh(welded.mesh, options.minAreaRatio);

    // Vertices no triangle uses (stray points in a file) are not particles: drop them and
    // map them to kNoParticle.
    {
        std::vector<Index> compact(welded.mesh.vertices.size(), kNoParticle);
        for (const auto& t : welded.mesh.triangles)
            for (Index v : t)
                compact[v] = 0;
        Index next = 0;
        std::vector<Vec3> used;
        used.reserve(welded.mesh.vertices.size());
        for (std::size_t v = 0; v < compact.size(); ++v) {
            if (compact[v] == kNoParticle) continue;
            compact[v] = next++;
            used.push_back(welded.mesh.vertices[v]);
        }
        if (used.size() != welded.mesh.vertices.size()) {
            welded.mesh.vertices = std::move(used);
            for (auto& t : welded.mesh.triangles)
                for (Index& v : t)
                    v = compact[v];
            for (Index& r : welded.remap)
                r = compact[r];
        }
    }

    std::shared_ptr<ClothTopology> topo(new ClothTopology());
    topo->restPositions_ = std::move(welded.mesh.vertices);
    topo->triangles_ = std::move(welded.mesh.triangles);
    topo->vertexToParticle_ = std::move(welded.remap);

    // Two copies of a triangle (same three particles) after welding would double its springs'
    // stiffness and mass silently: refuse them.
    {
        std::vector<std::array<Index, 3>> sorted(topo->triangles_.size());
        for (std::size_t t = 0; t < sorted.size(); ++t) {
            sorted[t] = topo->triangles_[t];
            std::sort(sorted[t].begin(), sorted[t].end());
        }
        std::vector<std::size_t> idx(sorted.size());
        for (std::size_t i = 0; i < idx.size(); ++i)
            idx[i] = i;
        std::sort(idx.begin(), idx.end(),
                  [&](std::size_t a, std::size_t b) { return sorted[a] < sorted[b]; });
        for (std::size_t i = 1; i < idx.size(); ++i) {
            if (sorted[idx[i]] == sorted[idx[i - 1]]) {
                throw Error(ErrorCode::InvalidMesh,
                            "triangles " + std::to_string(std::min(idx[i], idx[i - 1])) + " and " +
                                std::to_string(std::max(idx[i], idx[i - 1])) +
                                " join the same three particles");
            }
        }
    }

    // Unique edges: sort (min, max) pairs, count multiplicity for the boundary.
    struct Edge {
        Index a, b;
    };
    std::vector<Edge> edges;
    edges.reserve(topo->triangles_.size() * 3);
    for (const auto& t : topo->triangles_) {
        for (int c = 0; c < 3; ++c) {
            Index a = t[c], b = t[(c + 1) % 3];
            if (a > b) std::swap(a, b);
            edges.push_back({a, b});
        }
    }
    std::sort(edges.begin(), edges.end(),
              [](const Edge& l, const Edge& r) { return l.a != r.a ? l.a < r.a : l.b < r.b; });
    for (std::size_t i = 0; i < edges.size();) {
        std::size_t j = i;
        while (j < edges.size() && edges[j].a == edges[i].a && edges[j].b == edges[i].b)
            ++j;
        if (j - i == 1) ++topo->boundaryEdges_;
        const double len =
            (topo->restPositions_[edges[i].b] - topo->restPositions_[edges[i].a]).norm();
        topo->springs_.push_back({edges[i].a, edges[i].b, len});
        i = j;
    }

    const std::size_t n = topo->restPositions_.size();
    topo->adjOffsets_.assign(n + 1, 0);
    for (const auto& s : topo->springs_) {
        ++topo->adjOffsets_[s.a + 1];
        ++topo->adjOffsets_[s.b + 1];
    }
    for (std::size_t i = 0; i < n; ++i)
        topo->adjOffsets_[i + 1] += topo->adjOffsets_[i];
    topo->adjParticles_.resize(topo->adjOffsets_[n]);
    topo->adjSprings_.resize(topo->adjOffsets_[n]);
    std::vector<Index> fill(topo->adjOffsets_.begin(), topo->adjOffsets_.end() - 1);
    for (std::size_t s = 0; s < topo->springs_.size(); ++s) {
        const auto& sp = topo->springs_[s];
        topo->adjParticles_[fill[sp.a]] = sp.b;
        topo->adjSprings_[fill[sp.a]++] = static_cast<Index>(s);
        topo->adjParticles_[fill[sp.b]] = sp.a;
        topo->adjSprings_[fill[sp.b]++] = static_cast<Index>(s);
    }
    topo->invRest2_.resize(topo->springs_.size());
    for (std::size_t s = 0; s < topo->springs_.size(); ++s) {
        topo->invRest2_[s] = 1.0 / (topo->springs_[s].restLength * topo->springs_[s].restLength);
    }
    topo->adjRest_.resize(topo->adjSprings_.size());
    for (std::size_t k = 0; k < topo->adjSprings_.size(); ++k) {
        topo->adjRest_[k] = topo->springs_[topo->adjSprings_[k]].restLength;
    }
    topo->adjInvRest2_.resize(topo->adjSprings_.size());
    for (std::size_t k = 0; k < topo->adjSprings_.size(); ++k)
        topo->adjInvRest2_[k] = topo->invRest2_[topo->adjSprings_[k]];

    topo->bakeFamilies();
    topo->packedLoose_ =
        pack(*topo, makeSpringBlocks(*topo, topo->looseSprings(), topo->springBlockCount()));

    topo->triangleAreas_.resize(topo->triangles_.size());
    for (std::size_t t = 0; t < topo->triangles_.size(); ++t) {
        const auto& tri = topo->triangles_[t];
        const Vec3& a = topo->restPositions_[tri[0]];
        topo->triangleAreas_[t] =
            0.5 * (topo->restPositions_[tri[1]] - a).cross(topo->restPositions_[tri[2]] - a).norm();
        topo->totalArea_ += topo->triangleAreas_[t];
    }
    return topo;
}

// Families: the springs grouped by offset b - a, each group split into runs wherever more
// than kMaxGap consecutive slots would be empty. A run becomes a family when it has at least
// kMinSprings springs and fills at least 40 % of its slots (a sheet's alternating diagonals
// fill about half); its springs are then evaluated in contiguous memory. The rest stay loose.
void ClothTopology::bakeFamilies() {
    constexpr Index kMaxGap = 4;
    constexpr std::size_t kMinSprings = 8;
    families_.clear();
    slotSpring_.clear();
    slotRest_.clear();
    slotInvRest2_.clear();
    looseSprings_.clear();
    springSlot_.assign(springs_.size(), kNoSlot);
    std::vector<Index> order(springs_.size());
    for (std::size_t s = 0; s < order.size(); ++s)
        order[s] = static_cast<Index>(s);
    auto offsetOf = [&](Index s) { return springs_[s].b - springs_[s].a; };
    std::sort(order.begin(), order.end(), [&](Index p, Index q) {
        const Index op = offsetOf(p), oq = offsetOf(q);
        return op != oq ? op < oq : springs_[p].a < springs_[q].a;
    });
    std::vector<unsigned char> inFamily(springs_.size(), 0);
    for (std::size_t i = 0; i < order.size();) {
        // One run: same offset, gaps of at most kMaxGap empty slots.
        std::size_t j = i + 1;
        while (j < order.size() && offsetOf(order[j]) == offsetOf(order[i]) &&
               springs_[order[j]].a - springs_[order[j - 1]].a <= kMaxGap + 1) {
            ++j;
        }
        const Index first = springs_[order[i]].a;
        const Index span = springs_[order[j - 1]].a - first + 1;
        const std::size_t count = j - i;
        if (count >= kMinSprings && 5 * count >= 2 * std::size_t(span)) {
            SpringFamily f{offsetOf(order[i]), first, span, slotSpring_.size()};
            slotSpring_.resize(f.slot + span, kNoParticle);
            slotRest_.resize(f.slot + span, 0.0);
            slotInvRest2_.resize(f.slot + span, 0.0);
            for (std::size_t k = i; k < j; ++k) {
                const Index s = order[k];
                const std::size_t slot = f.slot + (springs_[s].a - first);
                slotSpring_[slot] = s;
                slotRest_[slot] = springs_[s].restLength;
                slotInvRest2_[slot] = invRest2_[s];
                springSlot_[s] = slot;
                inFamily[s] = 1;
            }
            families_.push_back(f);
        }
        i = j;
    }
    for (std::size_t s = 0; s < springs_.size(); ++s)
        if (!inFamily[s]) looseSprings_.push_back(static_cast<Index>(s));
}

} // namespace drape
