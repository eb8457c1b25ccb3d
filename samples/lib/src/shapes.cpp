// shapes.cpp: triangle meshes for drawing rigid bodies and cloth (no OpenGL needed here).
#include "drape_samples/render.hpp"

#include <cmath>

namespace drape::samples {

namespace {

constexpr double kPi = 3.14159265358979323846;

void pushVertex(DrawMesh& m, double x, double y, double z) {
    m.positions.push_back(static_cast<float>(x));
    m.positions.push_back(static_cast<float>(y));
    m.positions.push_back(static_cast<float>(z));
}

void pushTriangle(DrawMesh& m, std::uint32_t a, std::uint32_t b, std::uint32_t c) {
    m.indices.push_back(a);
    m.indices.push_back(b);
    m.indices.push_back(c);
}

} // namespace

std::vector<float> computeNormals(const std::vector<float>& p,
                                  const std::vector<std::uint32_t>& idx) {
    std::vector<float> n(p.size(), 0.0f);
    for (std::size_t t = 0; t + 2 < idx.size(); t += 3) {
        const std::uint32_t a = idx[t], b = idx[t + 1], c = idx[t + 2];
        const Eigen::Vector3f pa(p[3 * a], p[3 * a + 1], p[3 * a + 2]);
        const Eigen::Vector3f pb(p[3 * b], p[3 * b + 1], p[3 * b + 2]);
        const Eigen::Vector3f pc(p[3 * c], p[3 * c + 1], p[3 * c + 2]);
        const Eigen::Vector3f fn = (pb - pa).cross(pc - pa); // length = twice the area
        for (std::uint32_t v : {a, b, c})
            for (int k = 0; k < 3; ++k)
                n[3 * v + static_cast<std::uint32_t>(k)] += fn[k];
    }
    for (std::size_t v = 0; v + 2 < n.size(); v += 3) {
        const float len = std::sqrt(n[v] * n[v] + n[v + 1] * n[v + 1] + n[v + 2] * n[v + 2]);
        if (len > 0.0f) {
            n[v] /= len;
            n[v + 1] /= len;
            n[v + 2] /= len;
        } else {
            n[v + 1] = 1.0f;
        }
    }
    return n;
}

std::size_t keepNormalsFacingViewer(std::vector<float>& p, std::vector<float>& n,
                                    std::vector<std::uint32_t>& idx, const Eigen::Vector3f& eye) {
    auto vec = [](const std::vector<float>& a, std::uint32_t v) {
        return Eigen::Vector3f(a[3 * v], a[3 * v + 1], a[3 * v + 2]);
    };
    std::size_t changed = 0;
    for (std::size_t t = 0; t + 2 < idx.size(); t += 3) {
        const Eigen::Vector3f pa = vec(p, idx[t]), pb = vec(p, idx[t + 1]), pc = vec(p, idx[t + 2]);
        const Eigen::Vector3f face = (pb - pa).cross(pc - pa);
        const float facing = face.dot(eye - pa); // > 0: the front is seen
        const float area2 = face.norm();
        if (!(area2 > 0.0f) || !std::isfinite(area2) || !(facing != 0.0f) || !std::isfinite(facing))
            continue;
        const float side = facing > 0.0f ? 1.0f : -1.0f;
        const Eigen::Vector3f flat = side * face / area2; // the seen side's normal
        for (std::size_t k = 0; k < 3; ++k) {
            const std::uint32_t v = idx[t + k];
            const Eigen::Vector3f x = vec(p, v);
            const Eigen::Vector3f toEye = (eye - x).normalized();
            Eigen::Vector3f s = side * vec(n, v); // the normal the lighting would use
            const float len = s.norm();
            float c = 0.0f; // a zero or non-finite normal counts as facing away
            if (len > 0.0f && std::isfinite(len)) {
                s /= len;
                c = s.dot(toEye);
            } else {
                s = flat;
            }
            if (c >= kNormalViewCosine) continue;
            const float w = c <= 0.0f ? 1.0f : 1.0f - c / kNormalViewCosine; // weight of flat
            Eigen::Vector3f b = (1.0f - w) * s + w * flat;
            // Both terms face the camera (c > 0 and flat), so b is never zero.
            b.normalize();
            const auto nv = static_cast<std::uint32_t>(p.size() / 3);
            for (int d = 0; d < 3; ++d) {
                p.push_back(x[d]);
                n.push_back(side * b[d]);
            }
            idx[t + k] = nv;
            ++changed;
        }
    }
    return changed;
}

DrawMesh toDrawMesh(const std::vector<Vec3>& vertices, const std::vector<Triangle>& triangles,
                    const Color& front, const Color& back) {
    DrawMesh m;
    m.positions.reserve(vertices.size() * 3);
    for (const Vec3& v : vertices)
        pushVertex(m, v.x(), v.y(), v.z());
    m.indices.reserve(triangles.size() * 3);
    for (const Triangle& t : triangles)
        pushTriangle(m, t[0], t[1], t[2]);
    m.normals = computeNormals(m.positions, m.indices);
    m.front = front;
    m.back = back;
    return m;
}

DrawMesh makeBoxMesh(const Vec3& h) {
    // Four vertices per face so that each face gets its own flat normal.
    DrawMesh m;
    const int axes[6][3] = {{0, 1, 2}, {0, 1, 2}, {1, 2, 0}, {1, 2, 0}, {2, 0, 1}, {2, 0, 1}};
    for (int f = 0; f < 6; ++f) {
        const int n = axes[f][2], u = axes[f][0], v = axes[f][1];
        const double s = (f % 2 == 0) ? 1.0 : -1.0;
        const std::uint32_t base = static_cast<std::uint32_t>(m.positions.size() / 3);
        const double corners[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
        for (const auto& c : corners) {
            double p[3];
            p[n] = s * h[n];
            p[u] = c[0] * h[u];
            p[v] = c[1] * s * h[v]; // mirrored on the negative face keeps the winding outward
            pushVertex(m, p[0], p[1], p[2]);
            for (int k = 0; k < 3; ++k)
                m.normals.push_back(k == n ? static_cast<float>(s) : 0.0f);
        }
        pushTriangle(m, base, base + 1, base + 2);
        pushTriangle(m, base, base + 2, base + 3);
    }
    return m;
}

namespace {

// A UV sphere with `stacks` rings from pole to pole (even, so the equator is a row).
/// Two triangles per cell of a grid of `bands` x `slices` cells whose vertex rows hold
/// slices + 1 vertices each (a sphere's or capsule's latitude bands).
void pushBands(DrawMesh& m, int bands, int slices) {
    const auto row = static_cast<std::uint32_t>(slices + 1);
    for (int i = 0; i < bands; ++i)
        for (int j = 0; j < slices; ++j) {
            const std::uint32_t a =
                static_cast<std::uint32_t>(i) * row + static_cast<std::uint32_t>(j);
            const std::uint32_t b = a + row;
            pushTriangle(m, a, b, a + 1);
            pushTriangle(m, a + 1, b, b + 1);
        }
}

DrawMesh makeRoundMesh(double r, int slices, int stacks) {
    DrawMesh m;
    if (stacks % 2) ++stacks;
    for (int i = 0; i <= stacks; ++i) {
        const double phi = kPi * i / stacks; // 0 at the top
        const double y = r * std::cos(phi);
        const double ring = r * std::sin(phi);
        for (int j = 0; j <= slices; ++j) {
            const double th = 2.0 * kPi * j / slices;
            pushVertex(m, ring * std::cos(th), y, -ring * std::sin(th));
            m.normals.push_back(static_cast<float>(std::sin(phi) * std::cos(th)));
            m.normals.push_back(static_cast<float>(std::cos(phi)));
            m.normals.push_back(static_cast<float>(-std::sin(phi) * std::sin(th)));
        }
    }
    pushBands(m, stacks, slices);
    return m;
}

} // namespace

DrawMesh makeSphereMesh(double radius, int slices, int stacks) {
    return makeRoundMesh(radius, slices, stacks);
}

DrawMesh makeCapsuleMesh(double radius, double height, int slices, int stacks) {
    // Duplicate the equator so that the upper rows are shifted up and the lower rows down;
    // the band between the two copies is the cylinder.
    if (stacks % 2) ++stacks;
    DrawMesh top = makeRoundMesh(radius, slices, stacks);
    DrawMesh m;
    const int row = slices + 1;
    for (int i = 0; i <= stacks + 1; ++i) {
        const int src = i <= stacks / 2 ? i : i - 1;
        const double dy = i <= stacks / 2 ? 0.5 * height : -0.5 * height;
        for (int j = 0; j < row; ++j) {
            const std::size_t s = static_cast<std::size_t>(src * row + j) * 3;
            pushVertex(m, top.positions[s], top.positions[s + 1] + dy, top.positions[s + 2]);
            for (int k = 0; k < 3; ++k)
                m.normals.push_back(top.normals[s + static_cast<std::size_t>(k)]);
        }
    }
    pushBands(m, stacks + 1, slices);
    return m;
}

std::vector<DrawMesh> makePlaneMeshes(const Vec3& normal, double offset, const Vec3& around,
                                      double size, const Color& color, int cells) {
    const Vec3 n = normal.normalized();
    const Vec3 centre = around - (n.dot(around) - offset) * n;
    const Vec3 u = (std::abs(n.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY()).cross(n).normalized();
    const Vec3 v = n.cross(u);
    std::vector<DrawMesh> out(2);
    const Color dark = {color[0] * 0.85f, color[1] * 0.85f, color[2] * 0.85f};
    out[0].front = out[0].back = color;
    out[1].front = out[1].back = dark;
    const double cell = size / cells;
    for (int i = 0; i < cells; ++i)
        for (int j = 0; j < cells; ++j) {
            DrawMesh& m = out[static_cast<std::size_t>((i + j) % 2)];
            const auto base = static_cast<std::uint32_t>(m.positions.size() / 3);
            const Vec3 o = centre + (i * cell - 0.5 * size) * u + (j * cell - 0.5 * size) * v;
            for (const Vec3& p :
                 {o, Vec3(o + cell * u), Vec3(o + cell * u + cell * v), Vec3(o + cell * v)}) {
                pushVertex(m, p.x(), p.y(), p.z());
                for (int k = 0; k < 3; ++k)
                    m.normals.push_back(static_cast<float>(n[k]));
            }
            pushTriangle(m, base, base + 1, base + 2);
            pushTriangle(m, base, base + 2, base + 3);
        }
    return out;
}

} // namespace drape::samples
