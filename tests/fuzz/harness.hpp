// tests/fuzz/harness.hpp: the two fuzzing entry points, shared by the libFuzzer targets
// (fuzz_scene.cpp, fuzz_mesh.cpp) and by the regression tests (regressions/), so a saved
// crashing input replays through exactly the code the fuzzer ran.
//
// Each entry point returns normally when drape accepted the input or rejected it with one of
// its own errors (drape::Error, drape::samples::SceneError). Anything else escapes: another
// exception propagates, and a crash, a sanitizer report, a hang or a leak is the fuzzer's to
// catch.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>

namespace drape::fuzz {

/// What drape made of an input.
struct Outcome {
    bool accepted = false; ///< true: parsed and built; false: rejected with a drape error
    std::string message;   ///< the error's message when rejected
};

/// Folders the scene target needs.
struct ScenePaths {
    /// Relative mesh paths in a fuzzed scene resolve against this folder (samples/scenes, so
    /// that "../meshes/curtain.obj" of the shipped scenes still finds its file).
    std::filesystem::path sceneDir;
    /// Only mesh files inside this folder are loaded (samples/meshes). A scene naming any other
    /// file is parsed but not built: the fuzzer must not read arbitrary files of the machine,
    /// and mesh parsing has its own target.
    std::filesystem::path meshDir;
};

/// Above this many particles a parsed scene is not built: large sheets are legal (the limit is
/// kMaxSceneParticles) but would spend the fuzzer's time in allocation, not in new code.
inline constexpr std::size_t kMaxBuiltParticles = 1u << 14;
/// Only cloths up to this size are stepped, and only kStepsTaken times, and only while a scene
/// step is at most kMaxSteppedSubsteps cloth steps ("auto", the default, sub-steps a long
/// time step as far as 10,000 times: valid, bounded, and a long run, not input handling).
inline constexpr std::size_t kMaxSteppedParticles = 1024;
inline constexpr int kMaxSteppedSubsteps = 64;
inline constexpr int kStepsTaken = 2;

/// The bytes as a scene file: drape::samples::parseScene, then (within the limits above) the
/// Simulation that drape-run would build (cloth topology, masses, stability check, pins,
/// attachments, rigid bodies, mesh colliders) and a couple of steps.
Outcome runSceneInput(const std::uint8_t* data, std::size_t size, const ScenePaths& paths);

/// Mesh formats of the mesh target, chosen by the first byte of an input modulo the count.
inline constexpr const char* kMeshExtensions[] = {".obj", ".ply", ".stl", ".3ds", ".gltf",
                                                  ".glb", ".off", ".fbx", ".dae"};
inline constexpr std::size_t kMeshFormatCount =
    sizeof(kMeshExtensions) / sizeof(kMeshExtensions[0]);

/// The first byte picks a file extension (kMeshExtensions[data[0] % kMeshFormatCount]); the
/// rest is written to a file with that extension in `workDir`, read with
/// drape::io::importMesh and turned into a cloth with drape::ClothTopology::build.
Outcome runMeshInput(const std::uint8_t* data, std::size_t size,
                     const std::filesystem::path& workDir);

/// A fresh private folder under the system's temporary folder (mkdtemp), for runMeshInput.
std::filesystem::path makeWorkDir();

} // namespace drape::fuzz
