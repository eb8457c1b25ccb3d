// Mesh welding, validation and the sheet generator.
#include "drape/mesh.hpp"

#include "drape/error.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <unordered_map>

namespace drape {
namespace {

std::string vecStr(const Vec3& v) {
    return "(" + std::to_string(v.x()) + ", " + std::to_string(v.y()) + ", " +
           std::to_string(v.z()) + ")";
}

void checkSizesAndIndices(const TriangleMesh& mesh) {
    if (mesh.vertices.size() > kMaxParticles) {
        throw Error(ErrorCode::InvalidMesh, "mesh has " + std::to_string(mesh.vertices.size()) +
                                                " vertices, more than the limit of " +
                                                std::to_string(kMaxParticles));
    }
    if (mesh.triangles.size() > kMaxTriangles) {
        throw Error(ErrorCode::InvalidMesh, "mesh has " + std::to_string(mesh.triangles.size()) +
                                                " triangles, more than the limit of " +
                                                std::to_string(kMaxTriangles));
    }
    if (mesh.triangles.empty()) throw Error(ErrorCode::InvalidMesh, "mesh has no triangles");
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
        if (!mesh.vertices[i].allFinite()) {
            throw Error(ErrorCode::NonFinite, "vertex " + std::to_string(i) +
                                                  " has a non-finite coordinate " +
                                                  vecStr(mesh.vertices[i]));
        }
    }
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
        for (int c = 0; c < 3; ++c) {
            if (mesh.triangles[t][c] >= mesh.vertices.size()) {
                throw Error(ErrorCode::IndexOutOfRange,
                            "triangle " + std::to_string(t) + " refers to vertex " +
                                std::to_string(mesh.triangles[t][c]) + " but the mesh has only " +
                                std::to_string(mesh.vertices.size()) + " vertices");
            }
        }
    }
}

/// validateMesh's test: a repeated vertex, or an area below minAreaRatio times the longest
/// edge squared. Returns an empty string for a usable triangle, else why it is not.
std::string degeneracy(const TriangleMesh& mesh, std::size_t t, double minAreaRatio) {
    const auto& tri = mesh.triangles[t];
    if (tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2]) {
        return "triangle " + std::to_string(t) + " repeats a vertex (" + std::to_string(tri[0]) +
               ", " + std::to_string(tri[1]) + ", " + std::to_string(tri[2]) + ")";
    }
    const Vec3& a = mesh.vertices[tri[0]];
    const Vec3& b = mesh.vertices[tri[1]];
    const Vec3& c = mesh.vertices[tri[2]];
    const double longest2 =
        std::max({(b - a).squaredNorm(), (c - b).squaredNorm(), (a - c).squaredNorm()});
    const double area = 0.5 * (b - a).cross(c - a).norm();
    if (!(area > minAreaRatio * longest2)) {
        return "triangle " + std::to_string(t) + " (vertices " + std::to_string(tri[0]) + ", " +
               std::to_string(tri[1]) + ", " + std::to_string(tri[2]) +
               ") has zero or near-zero area " + std::to_string(area);
    }
    return {};
}

struct CellKey {
    std::int64_t x, y, z;
    bool operator==(const CellKey& o) const { return x == o.x && y == o.y && z == o.z; }
};
struct CellHash {
    std::size_t operator()(const CellKey& k) const {
        auto h = static_cast<std::uint64_t>(k.x) * 0x9E3779B97F4A7C15ull;
        h ^= static_cast<std::uint64_t>(k.y) * 0xC2B2AE3D27D4EB4Full + (h << 6) + (h >> 2);
        h ^= static_cast<std::uint64_t>(k.z) * 0x165667B19E3779F9ull + (h << 6) + (h >> 2);
        return static_cast<std::size_t>(h);
    }
};

} // namespace

double triangleArea(const TriangleMesh& mesh, std::size_t t) {
    const auto& tri = mesh.triangles[t];
    const Vec3& a = mesh.vertices[tri[0]];
    return 0.5 * (mesh.vertices[tri[1]] - a).cross(mesh.vertices[tri[2]] - a).norm();
}

WeldResult weldVertices(const TriangleMesh& mesh, double tolerance) {
    checkSizesAndIndices(mesh);
    if (!(tolerance >= 0.0) || !std::isfinite(tolerance)) {
        throw Error(ErrorCode::InvalidArgument,
                    "weld tolerance must be finite and >= 0, got " + std::to_string(tolerance));
    }
    WeldResult out;
    out.remap.resize(mesh.vertices.size());
    std::unordered_map<CellKey, std::vector<Index>, CellHash> cells;
    cells.reserve(mesh.vertices.size());
    const double cell = tolerance > 0.0 ? tolerance : 1.0;
    const double tol2 = tolerance * tolerance;
    auto keyOf = [&](const Vec3& p) {
        if (tolerance == 0.0) {
            // Exact welding: the key is the bit pattern (with -0 folded into +0).
            CellKey k{};
            const double c[3] = {p.x() + 0.0, p.y() + 0.0, p.z() + 0.0};
            std::memcpy(&k.x, &c[0], 8);
            std::memcpy(&k.y, &c[1], 8);
            std::memcpy(&k.z, &c[2], 8);
            return k;
        }
        return CellKey{static_cast<std::int64_t>(std::floor(p.x() / cell)),
                       static_cast<std::int64_t>(std::floor(p.y() / cell)),
                       static_cast<std::int64_t>(std::floor(p.z() / cell))};
    };
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
        const Vec3& p = mesh.vertices[i];
        const CellKey k = keyOf(p);
        Index found = static_cast<Index>(-1);
        if (tolerance == 0.0) {
            auto it = cells.find(k);
            if (it != cells.end()) found = it->second.front();
        } else {
            for (std::int64_t dx = -1; dx <= 1 && found == Index(-1); ++dx)
                for (std::int64_t dy = -1; dy <= 1 && found == Index(-1); ++dy)
                    for (std::int64_t dz = -1; dz <= 1 && found == Index(-1); ++dz) {
                        auto it = cells.find(CellKey{k.x + dx, k.y + dy, k.z + dz});
                        if (it == cells.end()) continue;
                        for (Index j : it->second) {
                            if ((out.mesh.vertices[j] - p).squaredNorm() <= tol2) {
                                found = j;
                                break;
                            }
                        }
                    }
        }
        if (found == Index(-1)) {
            found = static_cast<Index>(out.mesh.vertices.size());
            out.mesh.vertices.push_back(p);
            cells[k].push_back(found);
        }
        out.remap[i] = found;
    }
    out.mesh.triangles.reserve(mesh.triangles.size());
    for (const auto& t : mesh.triangles) {
        out.mesh.triangles.push_back({out.remap[t[0]], out.remap[t[1]], out.remap[t[2]]});
    }
    return out;
}

namespace {
void requireMinAreaRatio(double minAreaRatio, const char* name) {
    if (!(minAreaRatio >= 0.0 && std::isfinite(minAreaRatio)))
        throw Error(ErrorCode::InvalidArgument,
                    std::string(name) + " must be >= 0 and finite, got " +
                        std::to_string(minAreaRatio) +
                        " (a negative ratio lets zero-area triangles through); the default is "
                        "1e-10");
}
} // namespace

void validateMesh(const TriangleMesh& mesh, double minAreaRatio) {
    requireMinAreaRatio(minAreaRatio, "validateMesh: minAreaRatio");
    checkSizesAndIndices(mesh);
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
        const std::string why = degeneracy(mesh, t, minAreaRatio);
        if (!why.empty()) throw Error(ErrorCode::DegenerateTriangle, why);
    }
}

UnusableTriangles dropUnusableTriangles(TriangleMesh& mesh, double minAreaRatio) {
    requireMinAreaRatio(minAreaRatio, "dropUnusableTriangles: minAreaRatio");
    checkSizesAndIndices(mesh);
    UnusableTriangles out;
    const std::size_t n = mesh.triangles.size();
    std::vector<unsigned char> drop(n, 0);
    for (std::size_t t = 0; t < n; ++t) {
        if (!degeneracy(mesh, t, minAreaRatio).empty()) {
            drop[t] = 1;
            out.degenerate.push_back(t);
        }
    }
    // Duplicates among the rest: equal sorted vertex triples; the lowest index is kept.
    std::vector<Triangle> sorted(n);
    std::vector<std::size_t> order;
    order.reserve(n);
    for (std::size_t t = 0; t < n; ++t) {
        sorted[t] = mesh.triangles[t];
        std::sort(sorted[t].begin(), sorted[t].end());
        if (!drop[t]) order.push_back(t);
    }
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t a, std::size_t b) { return sorted[a] < sorted[b]; });
    for (std::size_t i = 1; i < order.size(); ++i) {
        if (sorted[order[i]] == sorted[order[i - 1]]) {
            drop[order[i]] = 1;
            out.duplicate.push_back(order[i]);
        }
    }
    std::sort(out.duplicate.begin(), out.duplicate.end());
    if (out.empty()) return out;
    std::size_t kept = 0;
    for (std::size_t t = 0; t < n; ++t)
        if (!drop[t]) mesh.triangles[kept++] = mesh.triangles[t];
    mesh.triangles.resize(kept);
    return out;
}

TriangleMesh makeSheet(const SheetSpec& spec) {
    if (spec.rows < 2 || spec.cols < 2) {
        throw Error(ErrorCode::InvalidArgument, "sheet needs at least 2 x 2 particles, got " +
                                                    std::to_string(spec.rows) + " x " +
                                                    std::to_string(spec.cols));
    }
    if (static_cast<std::size_t>(spec.rows) * spec.cols > kMaxParticles) {
        throw Error(ErrorCode::InvalidArgument,
                    "sheet of " + std::to_string(spec.rows) + " x " + std::to_string(spec.cols) +
                        " particles exceeds the limit of " + std::to_string(kMaxParticles));
    }
    if (!(spec.spacing > 0.0) || !std::isfinite(spec.spacing)) {
        throw Error(ErrorCode::InvalidArgument, "sheet spacing must be positive and finite, got " +
                                                    std::to_string(spec.spacing));
    }
    if (!spec.origin.allFinite() || !spec.uAxis.allFinite() || !spec.vAxis.allFinite()) {
        throw Error(ErrorCode::NonFinite, "sheet origin or axes are not finite");
    }
    const double un = spec.uAxis.norm(), vn = spec.vAxis.norm();
    if (un == 0.0 || vn == 0.0)
        throw Error(ErrorCode::InvalidArgument, "sheet axis has zero length");
    const Vec3 u = spec.uAxis / un, v = spec.vAxis / vn;
    if (u.cross(v).norm() < 1e-6) {
        throw Error(ErrorCode::InvalidArgument, "sheet axes uAxis and vAxis are parallel");
    }
    TriangleMesh mesh;
    mesh.vertices.reserve(static_cast<std::size_t>(spec.rows) * spec.cols);
    for (Index r = 0; r < spec.rows; ++r) {
        for (Index c = 0; c < spec.cols; ++c) {
            mesh.vertices.push_back(spec.origin + (c * spec.spacing) * u + (r * spec.spacing) * v);
        }
    }
    mesh.triangles.reserve(2 * static_cast<std::size_t>(spec.rows - 1) * (spec.cols - 1));
    for (Index r = 0; r + 1 < spec.rows; ++r) {
        for (Index c = 0; c + 1 < spec.cols; ++c) {
            const Index i00 = r * spec.cols + c, i01 = i00 + 1;
            const Index i10 = i00 + spec.cols, i11 = i10 + 1;
            if ((r + c) % 2 == 0) { // diagonal i00-i11
                mesh.triangles.push_back({i00, i10, i11});
                mesh.triangles.push_back({i00, i11, i01});
            } else { // diagonal i01-i10
                mesh.triangles.push_back({i00, i10, i01});
                mesh.triangles.push_back({i01, i10, i11});
            }
        }
    }
    return mesh;
}

} // namespace drape
