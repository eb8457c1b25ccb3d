// mesh_io.cpp: a scene's MeshDesc read through drape::io.
#include "drape_samples/mesh_io.hpp"

#include <drape/error.hpp>

#include <cstdio>

namespace drape::samples {

bool meshIoAvailable() {
    return io::available();
}

std::string meshDescKey(const MeshDesc& d) {
    std::string key = d.file.string();
    auto add = [&key](double v) {
        char buf[32];
        std::snprintf(buf, sizeof buf, "|%.17g", v);
        key += buf;
    };
    for (const Vec3* v : {&d.scale, &d.rotationDeg, &d.translation})
        for (int k = 0; k < 3; ++k)
            add((*v)[k]);
    add(d.weldTolerance.value_or(-1.0));
    add(d.refuseDegenerate ? 1.0 : 0.0);
    add(d.unitsPerMetre);
    return key;
}

ImportedMesh importMesh(const MeshDesc& desc, bool cloth) {
    MeshImportOptions o;
    o.cloth = cloth;
    o.weldTolerance = desc.weldTolerance;
    o.refuseDegenerate = desc.refuseDegenerate;
    o.unitsPerMetre = desc.unitsPerMetre;
    o.transform = true;
    o.scale = desc.scale;
    o.rotationDeg = desc.rotationDeg;
    o.translation = desc.translation;
    try {
        return io::importMesh(desc.file, o);
    } catch (const Error& e) {
        throw SceneError(e.what()); // the message starts with the file's path
    }
}

} // namespace drape::samples
