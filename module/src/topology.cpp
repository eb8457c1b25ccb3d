// Topology: welding, validation, unique edges as linked springs, adjacency.
#include "drape/topology.hpp"

#include "drape/error.hpp"

#include "spring_layout.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>

namespace drape {

namespace {
constexpr double kWeldShareOfMedianEdge = 1e-3;
} // namespace

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

double automaticWeldTolerance(const TriangleMesh& mesh) {
    const double least = automaticWeldTolerance(mesh.vertices);
    std::vector<double> lengths;
    lengths.reserve(3 * mesh.triangles.size());
    const auto n = static_cast<Index>(mesh.vertices.size());
    for (const Triangle& t : mesh.triangles) {
        if (t[0] >= n || t[1] >= n || t[2] >= n) continue; // validateMesh names it
        for (int k = 0; k < 3; ++k) {
            const double l = (mesh.vertices[t[(k + 1) % 3]] - mesh.vertices[t[k]]).norm();
            if (std::isfinite(l)) lengths.push_back(l);
        }
    }
    if (lengths.empty()) return least;
    auto middle = lengths.begin() + static_cast<std::ptrdiff_t>(lengths.size() / 2);
    std::nth_element(lengths.begin(), middle, lengths.end());
    return std::max(least, kWeldShareOfMedianEdge * *middle);
}

std::shared_ptr<const ClothTopology> ClothTopology::build(const TriangleMesh& input,
                                                          const TopologyOptions& options) {
    if (input.vertices.empty()) throw Error(ErrorCode::InvalidMesh, "mesh has no vertices");
    if (options.weldTolerance &&
        !(*options.weldTolerance >= 0.0 && std::isfinite(*options.weldTolerance))) {
        throw Error(ErrorCode::InvalidArgument, "weldTolerance must be >= 0 and finite, got " +
                                                    std::to_string(*options.weldTolerance));
    }
    if (!(options.minAreaRatio >= 0.0 && std::isfinite(options.minAreaRatio))) {
        throw Error(ErrorCode::InvalidArgument,
                    "TopologyOptions::minAreaRatio must be >= 0 and finite, got " +
                        std::to_string(options.minAreaRatio) +
                        " (a negative ratio lets zero-area triangles through); the default is "
                        "1e-10");
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
    topo->triangleAreas_.resize(topo->triangles_.size());
    for (std::size_t t = 0; t < topo->triangles_.size(); ++t) {
        const auto& tri = topo->triangles_[t];
        const Vec3& a = topo->restPositions_[tri[0]];
        topo->triangleAreas_[t] =
            0.5 * (topo->restPositions_[tri[1]] - a).cross(topo->restPositions_[tri[2]] - a).norm();
        topo->totalArea_ += topo->triangleAreas_[t];
    }
    topo->layout_ = detail::optimise(*topo);
    return topo;
}

} // namespace drape
