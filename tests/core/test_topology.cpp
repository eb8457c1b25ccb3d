// Topology and mesh tests: springs are the unique triangle edges (Euler's formula on a grid,
// an irregular disc and a tube), welding of duplicate vertices, adjacency, and the sheet
// generator (plane, spacing, no favoured diagonal).
#include "helpers.hpp"

#include "drape/mesh.hpp"
#include "drape/topology.hpp"

#include <set>

using namespace drape;
using namespace drape_test;

namespace {

/// Checks every invariant of a topology against an independent count of the mesh's edges:
/// spring count and boundary count, Euler's formula V - E + F = chi, E = (3F + B)/2, rest
/// lengths, a < b, and the adjacency lists.
void checkTopology(const ClothTopology& topo, int expectedChi) {
    const auto uses = edgeUses(meshOf(topo));
    std::size_t boundary = 0;
    for (const auto& e : uses) {
        REQUIRE(e.second <= 2); // a cloth is a manifold surface
        if (e.second == 1) ++boundary;
    }
    const auto V = static_cast<long>(topo.particleCount());
    const auto E = static_cast<long>(topo.springCount());
    const auto F = static_cast<long>(topo.triangleCount());
    const auto B = static_cast<long>(topo.boundaryEdgeCount());
    CHECK(topo.springCount() == uses.size());
    CHECK(topo.boundaryEdgeCount() == boundary);
    CHECK(V - E + F == expectedChi);
    // Every triangle has 3 edge slots; interior edges fill 2 slots and boundary edges 1.
    CHECK(2 * E == 3 * F + B);

    std::set<std::pair<Index, Index>> seen;
    for (const Spring& s : topo.springs()) {
        CHECK(s.a < s.b);
        CHECK(uses.count({s.a, s.b}) == 1);
        CHECK(seen.insert({s.a, s.b}).second); // unique
        const double len = (topo.restPositions()[s.b] - topo.restPositions()[s.a]).norm();
        CHECK(s.restLength == Approx(len).epsilon(1e-14)); // the same subtraction, up to rounding
    }

    // Adjacency: symmetric, the joining spring really joins the pair, degrees sum to 2E.
    const auto& off = topo.adjacencyOffsets();
    REQUIRE(off.size() == topo.particleCount() + 1);
    CHECK(off.back() == 2 * topo.springCount());
    for (Index i = 0; i < topo.particleCount(); ++i) {
        for (Index k = off[i]; k < off[i + 1]; ++k) {
            const Index j = topo.adjacentParticles()[k];
            const Spring& s = topo.springs()[topo.adjacentSprings()[k]];
            CHECK(std::min(i, j) == s.a);
            CHECK(std::max(i, j) == s.b);
        }
    }
}

} // namespace

TEST_CASE("Topology of a grid sheet satisfies Euler's formula", "[topology]") {
    for (const auto& rc : std::vector<std::pair<Index, Index>>{{2, 2}, {3, 7}, {35, 35}, {6, 5}}) {
        SheetSpec spec;
        spec.rows = rc.first;
        spec.cols = rc.second;
        const auto topo = ClothTopology::build(makeSheet(spec));
        const long R = rc.first, C = rc.second;
        INFO("sheet " << R << " x " << C);
        // Closed forms for a grid with one diagonal per cell.
        CHECK(static_cast<long>(topo->particleCount()) == R * C);
        CHECK(static_cast<long>(topo->triangleCount()) == 2 * (R - 1) * (C - 1));
        CHECK(static_cast<long>(topo->springCount()) ==
              R * (C - 1) + C * (R - 1) + (R - 1) * (C - 1));
        CHECK(static_cast<long>(topo->boundaryEdgeCount()) == 2 * (R - 1) + 2 * (C - 1));
        checkTopology(*topo, 1);
        // Area of the rectangle (unit spacing).
        CHECK(topo->totalRestArea() ==
              Approx(static_cast<double>((R - 1) * (C - 1))).epsilon(1e-12));
    }
}

TEST_CASE("Topology of irregular meshes satisfies Euler's formula", "[topology]") {
    SECTION("irregular flat disc") {
        const TriangleMesh m = irregularMesh(7, 5, 42);
        const auto topo = ClothTopology::build(m);
        CHECK(topo->particleCount() == m.vertices.size());
        CHECK(topo->triangleCount() == m.triangles.size());
        checkTopology(*topo, 1);
        // Valences really vary (this is not a regular grid in disguise).
        std::set<Index> degrees;
        for (Index i = 0; i < topo->particleCount(); ++i)
            degrees.insert(topo->adjacencyOffsets()[i + 1] - topo->adjacencyOffsets()[i]);
        CHECK(degrees.size() >= 4);
        // The jitter keeps the outline a 7 x 5 rectangle, so the areas still add up to 35.
        CHECK(topo->totalRestArea() == Approx(35.0).epsilon(1e-12));
    }
    SECTION("irregular curved disc") {
        checkTopology(*ClothTopology::build(irregularMesh(6, 6, 7, true)), 1);
    }
    SECTION("tube (chi = 0)") {
        const auto topo = ClothTopology::build(tubeMesh(5, 12));
        checkTopology(*topo, 0);
        CHECK(topo->boundaryEdgeCount() == 2u * 12u); // two rims
    }
}

TEST_CASE("Duplicate vertices are welded into one particle", "[topology][weld]") {
    const TriangleMesh shared = irregularMesh(5, 4, 3);
    // A triangle soup: every triangle gets its own three copies of its corners, as exporters
    // write meshes with per-face attributes.
    TriangleMesh soup;
    std::vector<Index> original;
    for (const Triangle& t : shared.triangles) {
        Triangle nt{};
        for (int c = 0; c < 3; ++c) {
            nt[c] = static_cast<Index>(soup.vertices.size());
            soup.vertices.push_back(shared.vertices[t[c]]);
            original.push_back(t[c]);
        }
        soup.triangles.push_back(nt);
    }

    SECTION("exact duplicates") {
        const auto topo = ClothTopology::build(soup);
        const auto ref = ClothTopology::build(shared);
        CHECK(topo->particleCount() == shared.vertices.size());
        CHECK(topo->springCount() == ref->springCount());
        CHECK(topo->boundaryEdgeCount() == ref->boundaryEdgeCount());
        checkTopology(*topo, 1);
        // Copies of one vertex map to one particle sitting where the vertex was, and copies of
        // different vertices never share a particle.
        REQUIRE(topo->vertexToParticle().size() == soup.vertices.size());
        std::map<Index, Index> particleOf;
        for (std::size_t v = 0; v < soup.vertices.size(); ++v) {
            const Index p = topo->vertexToParticle()[v];
            REQUIRE(p < topo->particleCount());
            CHECK((topo->restPositions()[p] - soup.vertices[v]).norm() == 0.0);
            auto it = particleOf.emplace(original[v], p).first;
            CHECK(it->second == p);
        }
        std::set<Index> distinct;
        for (const auto& op : particleOf)
            distinct.insert(op.second);
        CHECK(distinct.size() == particleOf.size());
    }

    SECTION("near duplicates within the default tolerance") {
        // Offsets of 1e-12 m on a mesh whose diagonal is ~6.4 m: far below the default weld
        // tolerance (1e-9 x diagonal), far above zero.
        TriangleMesh noisy = soup;
        Rng rng(11);
        for (Vec3& p : noisy.vertices)
            p += Vec3(rng.uniform(-1, 1), rng.uniform(-1, 1), 0) * 1e-12;
        const auto topo = ClothTopology::build(noisy);
        CHECK(topo->particleCount() == shared.vertices.size());
        checkTopology(*topo, 1);
    }

    SECTION("weldVertices keeps first-occurrence order and real geometry") {
        const WeldResult w = weldVertices(soup, 0.0);
        CHECK(w.mesh.vertices.size() == shared.vertices.size());
        for (std::size_t v = 0; v < soup.vertices.size(); ++v)
            CHECK((w.mesh.vertices[w.remap[v]] - soup.vertices[v]).norm() == 0.0);
        // A mesh without duplicates is returned with its vertex order unchanged.
        const WeldResult same = weldVertices(shared, 0.0);
        for (std::size_t v = 0; v < shared.vertices.size(); ++v)
            CHECK(same.remap[v] == v);
        // Vertices 0.5 apart are not welded at tolerance 0.1, but are at 0.6.
        TriangleMesh two = equilateralTriangle(1.0);
        two.vertices.push_back(two.vertices[0] + Vec3(0.5, 0, 0));
        two.triangles.push_back({3, 1, 2});
        CHECK(weldVertices(two, 0.1).mesh.vertices.size() == 4);
        CHECK(weldVertices(two, 0.6).mesh.vertices.size() == 3);
    }
}

TEST_CASE("Sheet generator: plane, spacing and no favoured diagonal", "[topology][sheet]") {
    SheetSpec spec;
    spec.rows = 9;
    spec.cols = 12;
    spec.spacing = 0.25;
    spec.origin = Vec3(1.0, 2.0, -3.0);
    spec.uAxis = Vec3(0.0, 0.0, 2.0); // not unit length: normalised by makeSheet
    spec.vAxis = Vec3(-3.0, 0.0, 0.0);
    const TriangleMesh m = makeSheet(spec);
    REQUIRE(m.vertices.size() == 9u * 12u);
    const Vec3 u(0, 0, 1), v(-1, 0, 0);
    const Vec3 normal = u.cross(v);

    for (Index r = 0; r < spec.rows; ++r) {
        for (Index c = 0; c < spec.cols; ++c) {
            const Vec3 expected = spec.origin + c * spec.spacing * u + r * spec.spacing * v;
            // Positions are a few multiply-adds of numbers of order 1: 1e-14 is rounding.
            CHECK((m.vertices[sheetIndex(spec, r, c)] - expected).norm() < 1e-14);
            CHECK(std::abs((m.vertices[sheetIndex(spec, r, c)] - spec.origin).dot(normal)) < 1e-14);
        }
    }

    // Triangles are consistently oriented (all normals the same way).
    int positive = 0, negative = 0;
    for (const Triangle& t : m.triangles) {
        const double s = (m.vertices[t[1]] - m.vertices[t[0]])
                             .cross(m.vertices[t[2]] - m.vertices[t[0]])
                             .dot(normal);
        (s > 0 ? positive : negative) += 1;
    }
    CHECK((positive == 0 || negative == 0));

    // Classify springs: grid edges have length s, diagonals s sqrt(2) and come in two
    // directions, "\" (r+1, c+1) and "/" (r+1, c-1).
    const auto topo = ClothTopology::build(m);
    long grid = 0, down = 0, up = 0;
    std::vector<long> downPerRow(spec.rows - 1, 0), upPerRow(spec.rows - 1, 0);
    for (const Spring& s : topo->springs()) {
        const long ra = s.a / spec.cols, ca = s.a % spec.cols;
        const long rb = s.b / spec.cols, cb = s.b % spec.cols;
        const long dr = rb - ra, dc = cb - ca;
        if (std::abs(dr) + std::abs(dc) == 1) {
            ++grid;
            CHECK(s.restLength == Approx(spec.spacing).epsilon(1e-12));
        } else {
            REQUIRE(dr == 1);
            REQUIRE(std::abs(dc) == 1);
            CHECK(s.restLength == Approx(spec.spacing * std::sqrt(2.0)).epsilon(1e-12));
            if (dc == 1) {
                ++down;
                ++downPerRow[static_cast<std::size_t>(ra)];
            } else {
                ++up;
                ++upPerRow[static_cast<std::size_t>(ra)];
            }
        }
    }
    CHECK(grid == 9 * 11 + 12 * 8);
    CHECK(down + up == 8 * 11);
    // 88 cells: a checkerboard has exactly 44 of each; in every row of 11 cells they differ
    // by one at most.
    CHECK(down == up);
    for (std::size_t r = 0; r + 1 < spec.rows; ++r)
        CHECK(std::abs(downPerRow[r] - upPerRow[r]) <= 1);
}

TEST_CASE("Sheet generator with an odd number of cells", "[topology][sheet]") {
    SheetSpec spec;
    spec.rows = 4;
    spec.cols = 6; // 3 x 5 = 15 cells: the two directions differ by exactly one
    const auto topo = ClothTopology::build(makeSheet(spec));
    long down = 0, up = 0;
    for (const Spring& s : topo->springs()) {
        const long dc = static_cast<long>(s.b % spec.cols) - static_cast<long>(s.a % spec.cols);
        const long dr = static_cast<long>(s.b / spec.cols) - static_cast<long>(s.a / spec.cols);
        if (dr == 1 && dc == 1) ++down;
        if (dr == 1 && dc == -1) ++up;
    }
    CHECK(down + up == 15);
    CHECK(std::abs(down - up) == 1);
}

TEST_CASE("Vertices no triangle uses are not particles", "[topology]") {
    // A stray point (a file's leftover vertex) between used ones: dropped, mapped to
    // kNoParticle, and the other vertices keep their order.
    TriangleMesh m = irregularMesh(2, 2, 5);
    const std::size_t used = m.vertices.size();
    m.vertices.insert(m.vertices.begin() + 2, Vec3(50.0, 50.0, 50.0));
    for (Triangle& t : m.triangles)
        for (Index& v : t)
            if (v >= 2) ++v;
    const auto topo = ClothTopology::build(m);
    CHECK(topo->particleCount() == used);
    REQUIRE(topo->vertexToParticle().size() == used + 1);
    CHECK(topo->vertexToParticle()[2] == kNoParticle);
    CHECK(topo->vertexToParticle()[3] == 2u);
    checkTopology(*topo, 1);
}

TEST_CASE("dropUnusableTriangles removes degenerate and duplicate triangles, keeping the rest in "
          "order",
          "[topology][mesh]") {
    TriangleMesh m;
    m.vertices = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0),
                  Vec3(0, 1, 0), Vec3(2, 0, 0), Vec3(1e-6, 1e-6, 0)};
    m.triangles = {
        {0, 1, 2}, // 0 kept
        {0, 0, 3}, // 1 repeats a vertex
        {0, 2, 3}, // 2 kept
        {2, 1, 0}, // 3 triangle 0 with the other winding: a duplicate
        {0, 1, 4}, // 4 three corners on a line: no area
        {3, 0, 2}, // 5 triangle 2 rotated: a duplicate
        {1, 4, 2}, // 6 kept
        {0, 5, 2}, // 7 vertex 5 lies on the diagonal 0-2: no area
    };
    const double ratio = 1e-10;
    TriangleMesh copy = m;
    const UnusableTriangles u = dropUnusableTriangles(copy, ratio);
    CHECK(u.degenerate == std::vector<std::size_t>{1, 4, 7});
    CHECK(u.duplicate == std::vector<std::size_t>{3, 5});
    CHECK_FALSE(u.empty());
    REQUIRE(copy.triangles.size() == 3);
    CHECK(copy.triangles[0] == Triangle{0, 1, 2});
    CHECK(copy.triangles[1] == Triangle{0, 2, 3});
    CHECK(copy.triangles[2] == Triangle{1, 4, 2});
    CHECK(copy.vertices.size() == m.vertices.size()); // vertices are left alone
    CHECK_NOTHROW(validateMesh(copy, ratio));
    CHECK_NOTHROW(ClothTopology::build(copy));
    // A clean mesh is untouched.
    const UnusableTriangles none = dropUnusableTriangles(copy, ratio);
    CHECK(none.empty());
    CHECK(copy.triangles.size() == 3);
    // validateMesh and ClothTopology::build still refuse what it would drop.
    CHECK_THROWS_AS(validateMesh(m, ratio), Error);
    CHECK_THROWS_AS(ClothTopology::build(m), Error);
}
