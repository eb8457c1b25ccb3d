// tests/core/helpers.hpp: meshes and small utilities shared by the core tests (irregular
// meshes, a tube, an equilateral triangle, edge counting, error checks, slope fitting).
#pragma once

#include <catch2/catch.hpp>

#include "drape/cloth.hpp"
#include "drape/error.hpp"
#include "drape/mesh.hpp"
#include "drape/topology.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace drape_test {

using drape::Index;
using drape::Triangle;
using drape::TriangleMesh;
using drape::Vec3;

constexpr double kPi = 3.14159265358979323846;

/// A tiny deterministic generator (SplitMix64), so meshes are identical on every platform.
class Rng {
  public:
    explicit Rng(std::uint64_t seed) : state_(seed) {}
    std::uint64_t next() {
        std::uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
        z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
        z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
        return z ^ (z >> 31);
    }
    /// Uniform in [lo, hi).
    double uniform(double lo, double hi) {
        return lo + (hi - lo) * static_cast<double>(next() >> 11) * (1.0 / 9007199254740992.0);
    }
    int below(int n) { return static_cast<int>(next() % static_cast<std::uint64_t>(n)); }

  private:
    std::uint64_t state_;
};

/// An irregular disc-like mesh (Euler characteristic 1): an nx x ny grid of unit cells with
/// interior vertices jittered by up to +-0.25 (cells stay convex), each cell split along a
/// random diagonal or into four triangles around an extra centre vertex. Vertex valences
/// and triangle shapes vary. With `curved` the sheet is bent out of its plane.
inline TriangleMesh irregularMesh(int nx, int ny, std::uint64_t seed, bool curved = false) {
    Rng rng(seed);
    TriangleMesh m;
    auto id = [&](int i, int j) { return static_cast<Index>(j * (nx + 1) + i); };
    for (int j = 0; j <= ny; ++j) {
        for (int i = 0; i <= nx; ++i) {
            double x = i, y = j;
            if (i > 0 && i < nx && j > 0 && j < ny) {
                x += rng.uniform(-0.25, 0.25);
                y += rng.uniform(-0.25, 0.25);
            }
            const double z = curved ? 0.3 * std::sin(0.8 * x) * std::cos(0.5 * y) : 0.0;
            m.vertices.emplace_back(x, y, z);
        }
    }
    for (int j = 0; j < ny; ++j) {
        for (int i = 0; i < nx; ++i) {
            const Index a = id(i, j), b = id(i + 1, j), c = id(i + 1, j + 1), d = id(i, j + 1);
            switch (rng.below(3)) {
            case 0:
                m.triangles.push_back({a, b, c});
                m.triangles.push_back({a, c, d});
                break;
            case 1:
                m.triangles.push_back({a, b, d});
                m.triangles.push_back({b, c, d});
                break;
            default: {
                const Index e = static_cast<Index>(m.vertices.size());
                Vec3 centre =
                    0.25 * (m.vertices[a] + m.vertices[b] + m.vertices[c] + m.vertices[d]);
                m.vertices.push_back(centre);
                m.triangles.push_back({a, b, e});
                m.triangles.push_back({b, c, e});
                m.triangles.push_back({c, d, e});
                m.triangles.push_back({d, a, e});
            }
            }
        }
    }
    return m;
}

/// A tube (Euler characteristic 0): rows rings of cols vertices around the z axis, each quad
/// split along one diagonal.
inline TriangleMesh tubeMesh(int rows, int cols, double radius = 1.0, double height = 0.5) {
    TriangleMesh m;
    for (int r = 0; r < rows; ++r) {
        for (int c = 0; c < cols; ++c) {
            const double a = 2.0 * kPi * c / cols;
            m.vertices.emplace_back(radius * std::cos(a), radius * std::sin(a), height * r);
        }
    }
    auto id = [&](int r, int c) { return static_cast<Index>(r * cols + (c % cols)); };
    for (int r = 0; r + 1 < rows; ++r) {
        for (int c = 0; c < cols; ++c) {
            m.triangles.push_back({id(r, c), id(r, c + 1), id(r + 1, c + 1)});
            m.triangles.push_back({id(r, c), id(r + 1, c + 1), id(r + 1, c)});
        }
    }
    return m;
}

/// Unit directions from the centroid to the corners of the equilateral test triangle.
inline std::vector<Vec3> equilateralDirections() {
    std::vector<Vec3> d;
    for (int i = 0; i < 3; ++i) {
        const double a = kPi / 2.0 + 2.0 * kPi * i / 3.0;
        d.emplace_back(std::cos(a), std::sin(a), 0.0);
    }
    return d;
}

/// One equilateral triangle with corners at distance r0 from the origin (side sqrt(3) r0).
inline TriangleMesh equilateralTriangle(double r0) {
    TriangleMesh m;
    for (const Vec3& d : equilateralDirections())
        m.vertices.push_back(r0 * d);
    m.triangles.push_back({0, 1, 2});
    return m;
}

/// Each undirected edge (min, max) of a mesh with the number of triangles using it.
inline std::map<std::pair<Index, Index>, int> edgeUses(const TriangleMesh& m) {
    std::map<std::pair<Index, Index>, int> uses;
    for (const Triangle& t : m.triangles) {
        for (int c = 0; c < 3; ++c) {
            Index a = t[c], b = t[(c + 1) % 3];
            if (a > b) std::swap(a, b);
            ++uses[{a, b}];
        }
    }
    return uses;
}

/// The topology's particles and triangles as a mesh (for edgeUses on welded meshes).
inline TriangleMesh meshOf(const drape::ClothTopology& topo) {
    return TriangleMesh{topo.restPositions(), topo.triangles()};
}

inline std::string lower(std::string s) {
    std::transform(s.begin(), s.end(), s.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    return s;
}

/// Least-squares slope of log(y) against log(x).
inline double logLogSlope(const std::vector<double>& x, const std::vector<double>& y) {
    const double n = static_cast<double>(x.size());
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    for (std::size_t i = 0; i < x.size(); ++i) {
        const double lx = std::log(x[i]), ly = std::log(y[i]);
        sx += lx;
        sy += ly;
        sxx += lx * lx;
        sxy += lx * ly;
    }
    return (n * sxy - sx * sy) / (n * sxx - sx * sx);
}

} // namespace drape_test

/// Runs `expr`, requires it to throw drape::Error with `errcode` and a message containing
/// `substring` (case-insensitive).
#define REQUIRE_DRAPE_ERROR(expr, errcode, substring)                                              \
    do {                                                                                           \
        bool drapeThrew_ = false;                                                                  \
        try {                                                                                      \
            (void)(expr);                                                                          \
        } catch (const drape::Error& drapeError_) {                                                \
            drapeThrew_ = true;                                                                    \
            INFO("message: " << drapeError_.what());                                               \
            CHECK(std::string(drape::toString(drapeError_.code())) ==                              \
                  std::string(drape::toString(errcode)));                                          \
            CHECK_THAT(drape_test::lower(drapeError_.what()),                                      \
                       Catch::Matchers::Contains(drape_test::lower(substring)));                   \
        }                                                                                          \
        CHECK(drapeThrew_);                                                                        \
    } while (false)
