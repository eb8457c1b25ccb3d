// sheet_scene.cpp: what the reports and benchmarks take from a sheet scene file without
// running it through Simulation: resizedSheet, the one way a scene is run at another size (the
// reduced and scaling sizes), and fixedPins.
#include "drape_samples/scene.hpp"

#include <algorithm>
#include <cmath>

namespace drape::samples {

namespace {

[[noreturn]] void refuse(const SceneDesc& s, const std::string& what) {
    const std::string origin = s.sourceFile.empty() ? s.name : s.sourceFile.string();
    throw SceneError(origin + ": " + what);
}

[[noreturn]] void cannotResize(const SceneDesc& s, const std::string& what) {
    refuse(s, "cannot be resized: " + what);
}

/// Which coordinate axis a direction lies along, or -1.
int coordinateAxis(const Vec3& d) {
    for (int a = 0; a < 3; ++a)
        if (d[a] != 0.0 && d[(a + 1) % 3] == 0.0 && d[(a + 2) % 3] == 0.0) return a;
    return -1;
}

} // namespace

SceneDesc resizedSheet(const SceneDesc& scene, Index rows, Index cols) {
    if (!scene.sheet) cannotResize(scene, "the cloth is not a generated sheet");
    const SheetSpec& old = scene.sheet->spec;
    if (rows < 2 || cols < 2) cannotResize(scene, "a sheet needs at least 2 x 2 particles");
    const int ua = coordinateAxis(old.uAxis), va = coordinateAxis(old.vAxis);
    if (ua < 0 || va < 0 || ua == va)
        cannotResize(scene, "the sheet's axes are not two different coordinate axes");
    // Scale factor num[a] / den[a] per world axis. x * num / den is exact whenever the product
    // is, so Experiment I keeps its exact origin -side / 2 at every size.
    Vec3 num, den;
    num[ua] = old.spacing * static_cast<double>(cols - 1);
    den[ua] = old.spacing * static_cast<double>(old.cols - 1);
    num[va] = old.spacing * static_cast<double>(rows - 1);
    den[va] = old.spacing * static_cast<double>(old.rows - 1);
    const int na = 3 - ua - va;
    num[na] = std::sqrt(num[ua] * num[va]);
    den[na] = std::sqrt(den[ua] * den[va]);
    const auto map = [&num, &den](const Vec3& x) {
        return Vec3(x.array() * num.array() / den.array());
    };
    const double mean = num[na] / den[na];
    const auto place = [](Index i, Index from, Index to) {
        return static_cast<Index>(std::lround(static_cast<double>(i) * static_cast<double>(to - 1) /
                                              static_cast<double>(from - 1)));
    };

    SceneDesc s = scene;
    SheetSpec& spec = s.sheet->spec;
    spec.rows = rows;
    spec.cols = cols;
    spec.origin = map(old.origin);
    auto resizeSelector = [&](ParticleSelector& sel) {
        if (!sel.groups.empty()) cannotResize(scene, sel.path + ": groups of a sheet");
        for (Index& i : sel.indices) {
            if (i >= old.rows * old.cols) cannotResize(scene, sel.path + ": index out of range");
            i = sheetIndex(spec, place(i / old.cols, old.rows, rows),
                           place(i % old.cols, old.cols, cols));
        }
        for (auto& cell : sel.gridCells)
            cell = {place(cell[0], old.rows, rows), place(cell[1], old.cols, cols)};
        if (sel.box) {
            const Vec3 a = map((*sel.box)[0]), b = map((*sel.box)[1]);
            sel.box = {{a.cwiseMin(b), a.cwiseMax(b)}};
        }
    };
    for (PinDesc& p : s.pins)
        resizeSelector(p.select);
    for (AttachmentDesc& a : s.attachments)
        resizeSelector(a.select);
    for (RigidBodyDesc& b : s.rigidBodies) {
        if (b.rotationDeg != Vec3::Zero()) cannotResize(scene, b.path + ": a rotated body");
        b.position = map(b.position);
        for (KeyframeDesc& k : b.keyframes) {
            if (k.rotationDeg != Vec3::Zero())
                cannotResize(scene, b.path + ": a rotating keyframe");
            k.position = map(k.position);
        }
        ShapeDesc& shape = b.shape;
        switch (shape.kind) {
        case ShapeKind::Box:
            shape.halfExtents = map(shape.halfExtents);
            break;
        case ShapeKind::Sphere:
            shape.radius *= mean;
            break;
        case ShapeKind::Capsule:
            shape.radius *= mean;
            shape.height *= num[1] / den[1];
            break;
        case ShapeKind::Plane: {
            const int a = coordinateAxis(shape.normal);
            if (a < 0)
                cannotResize(scene, b.path + ": a plane whose normal is not a coordinate axis");
            shape.offset = shape.offset * num[a] / den[a];
            break;
        }
        case ShapeKind::Mesh:
            cannotResize(scene, b.path + ": a mesh body");
        }
    }
    const double zoom = std::max(num[ua] / den[ua], num[va] / den[va]);
    const Vec3 target = map(scene.camera.target);
    s.camera.position = target + zoom * (scene.camera.position - scene.camera.target);
    s.camera.target = target;
    return s;
}

std::vector<Index> fixedPins(const SceneDesc& scene) {
    if (!scene.sheet) refuse(scene, "the cloth is not a generated sheet");
    const SheetSpec& spec = scene.sheet->spec;
    std::vector<Index> out;
    for (const PinDesc& pin : scene.pins) {
        if (!pin.velocity.isZero() || pin.select.box || !pin.select.groups.empty())
            refuse(scene, pin.select.path + ": only fixed pins chosen by index or grid cell");
        for (Index i : pin.select.indices) {
            if (i >= spec.rows * spec.cols) refuse(scene, pin.select.path + ": index out of range");
            out.push_back(i);
        }
        for (const auto& [r, c] : pin.select.gridCells)
            out.push_back(sheetIndex(spec, r, c));
    }
    return out;
}

} // namespace drape::samples
