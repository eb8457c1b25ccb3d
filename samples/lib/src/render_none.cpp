// render_none.cpp: builds without OSMesa (DRAPE_WITH_RENDERING=OFF) refuse to render.
#include "drape_samples/render.hpp"

namespace drape::samples {

namespace {
[[noreturn]] void noRenderer() {
    throw SceneError("this build has no renderer (configure with -DDRAPE_WITH_RENDERING=ON)");
}
} // namespace

bool renderingAvailable() {
    return false;
}

struct OffscreenRenderer::Impl {};
OffscreenRenderer::OffscreenRenderer(int, int, int) {
    noRenderer();
}
OffscreenRenderer::~OffscreenRenderer() = default;
Image OffscreenRenderer::render(const CameraDesc&, const std::vector<DrawMesh>&, const Color&) {
    noRenderer();
}
void writePng(const std::filesystem::path&, const Image&) {
    noRenderer();
}
Image readPng(const std::filesystem::path&) {
    noRenderer();
}

} // namespace drape::samples
