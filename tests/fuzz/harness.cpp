// tests/fuzz/harness.cpp: the fuzzing entry points (see harness.hpp).
#include "harness.hpp"

#include <drape/error.hpp>
#include <drape/topology.hpp>
#include <drape_samples/mesh_io.hpp>
#include <drape_samples/scene.hpp>
#include <drape_samples/simulation.hpp>

#include <cstdlib>
#include <fstream>
#include <stdexcept>
#include <system_error>

namespace drape::fuzz {

namespace {

/// True when `file` lies inside `dir` (after resolving "..", symlinks and the like).
bool isInside(const std::filesystem::path& file, const std::filesystem::path& dir) {
    std::error_code ec;
    const auto f = std::filesystem::weakly_canonical(file, ec);
    if (ec) return false;
    const auto d = std::filesystem::weakly_canonical(dir, ec);
    if (ec) return false;
    const auto rel = f.lexically_relative(d);
    return !rel.empty() && *rel.begin() != "..";
}

bool meshesAllowed(const samples::SceneDesc& scene, const ScenePaths& paths) {
    if (scene.mesh && !isInside(scene.mesh->file, paths.meshDir)) return false;
    for (const auto& body : scene.rigidBodies)
        if (body.shape.kind == samples::ShapeKind::Mesh &&
            !isInside(body.shape.mesh.file, paths.meshDir))
            return false;
    return true;
}

std::size_t particleEstimate(const samples::SceneDesc& scene) {
    if (scene.sheet)
        return static_cast<std::size_t>(scene.sheet->spec.rows) * scene.sheet->spec.cols;
    return 0; // the shipped meshes are all small
}

} // namespace

Outcome runSceneInput(const std::uint8_t* data, std::size_t size, const ScenePaths& paths) {
    const std::string text(reinterpret_cast<const char*>(data), size);
    Outcome out;
    try {
        const samples::SceneDesc scene = samples::parseScene(text, "fuzz.json", paths.sceneDir);
        (void)scene.stepCount();
        (void)scene.needsBullet();
        if (particleEstimate(scene) > kMaxBuiltParticles || !meshesAllowed(scene, paths)) {
            out.accepted = true;
            return out;
        }
        samples::Simulation sim(scene);
        if (sim.cloth().particleCount() <= kMaxSteppedParticles &&
            sim.substeps() <= kMaxSteppedSubsteps) {
            for (int i = 0; i < kStepsTaken; ++i)
                sim.step();
            (void)sim.stats();
        }
        out.accepted = true;
    } catch (const samples::SceneError& e) {
        out.message = e.what();
    } catch (const drape::Error& e) {
        out.message = e.what();
    }
    return out;
}

Outcome runMeshInput(const std::uint8_t* data, std::size_t size,
                     const std::filesystem::path& workDir) {
    Outcome out;
    if (size == 0) {
        out.message = "empty input";
        return out;
    }
    const auto file =
        workDir / (std::string("input") + kMeshExtensions[data[0] % kMeshFormatCount]);
    {
        std::ofstream f(file, std::ios::binary | std::ios::trunc);
        f.write(reinterpret_cast<const char*>(data + 1), static_cast<std::streamsize>(size - 1));
        if (!f) throw std::runtime_error("fuzz harness: cannot write " + file.string());
    }
    try {
        const samples::ImportedMesh imported = io::importMesh(file);
        const TopologyPtr topology = ClothTopology::build(imported.mesh);
        (void)topology->springCount();
        out.accepted = true;
    } catch (const samples::SceneError& e) {
        out.message = e.what();
    } catch (const drape::Error& e) {
        out.message = e.what();
    }
    std::error_code ec;
    std::filesystem::remove(file, ec);
    return out;
}

std::filesystem::path makeWorkDir() {
    std::string pattern = (std::filesystem::temp_directory_path() / "drape-fuzz-XXXXXX").string();
    if (!mkdtemp(pattern.data())) throw std::runtime_error("fuzz harness: mkdtemp failed");
    return pattern;
}

} // namespace drape::fuzz
