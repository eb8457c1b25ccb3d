// The offscreen renderer: the cloth shows up in its own colours (front and back), rigid bodies
// are drawn, and the PNG on disk holds the same pixels.
#include "drape_samples/render.hpp"
#include "drape_samples/simulation.hpp"

#include <catch2/catch.hpp>

#include <filesystem>

using namespace drape;
using namespace drape::samples;
namespace fs = std::filesystem;

namespace {

const Color kBackground = {0.90f, 0.90f, 0.90f};
const Color kFront = {0.85f, 0.10f, 0.10f}; // red
const Color kBack = {0.10f, 0.15f, 0.85f};  // blue

/// A 2 m x 2 m sheet in the z = 0 plane, front (counter-clockwise side) facing +z.
DrawMesh sheetFacingPlusZ() {
    SheetSpec spec;
    spec.rows = 11;
    spec.cols = 11;
    spec.spacing = 0.2;
    spec.origin = Vec3(-1.0, 1.0, 0.0);
    spec.uAxis = Vec3::UnitX();
    spec.vAxis = -Vec3::UnitY();
    TriangleMesh m = makeSheet(spec);
    // Make sure the counter-clockwise side faces +z whatever makeSheet's convention.
    const Vec3 n = (m.vertices[m.triangles[0][1]] - m.vertices[m.triangles[0][0]])
                       .cross(m.vertices[m.triangles[0][2]] - m.vertices[m.triangles[0][0]]);
    if (n.z() < 0.0)
        for (Triangle& t : m.triangles)
            std::swap(t[1], t[2]);
    return toDrawMesh(m.vertices, m.triangles, kFront, kBack);
}

CameraDesc cameraAt(double z) {
    CameraDesc c;
    c.position = Vec3(0.0, 0.0, z);
    c.target = Vec3::Zero();
    c.fovDeg = 60.0;
    return c;
}

bool reddish(const std::array<std::uint8_t, 3>& p) {
    return p[0] > 60 && p[0] > 2 * p[1] && p[0] > 2 * p[2];
}
bool bluish(const std::array<std::uint8_t, 3>& p) {
    return p[2] > 60 && p[2] > 2 * p[0] && p[2] > 2 * p[1];
}
bool isBackground(const std::array<std::uint8_t, 3>& p) {
    for (int c = 0; c < 3; ++c)
        if (std::abs(int(p[static_cast<std::size_t>(c)]) -
                     int(kBackground[static_cast<std::size_t>(c)] * 255.0f + 0.5f)) > 2)
            return false;
    return true;
}

double fraction(const Image& img, bool (*pred)(const std::array<std::uint8_t, 3>&)) {
    std::size_t n = 0;
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x)
            n += pred(img.pixel(x, y)) ? 1u : 0u;
    return static_cast<double>(n) / (img.width * img.height);
}

} // namespace

TEST_CASE("the cloth is drawn in its front colour where it is, background elsewhere", "[render]") {
    if (!renderingAvailable()) {
        WARN("skipped: built without OSMesa");
        return;
    }
    OffscreenRenderer r(160, 120);
    // At distance 3 with a 60 degree field of view the 2 m sheet spans the middle ~58 % of
    // the image height: (2 / 2) / (3 tan 30 deg) = 0.577.
    const Image img = r.render(cameraAt(3.0), {sheetFacingPlusZ()}, kBackground);
    REQUIRE(img.width == 160);
    REQUIRE(img.height == 120);
    CHECK(reddish(img.pixel(80, 60))); // centre: cloth
    CHECK(reddish(img.pixel(60, 45)));
    CHECK(isBackground(img.pixel(2, 2))); // corners: background
    CHECK(isBackground(img.pixel(157, 117)));
    CHECK(isBackground(img.pixel(80, 5))); // above the sheet
    // Expected cloth area: a square 0.577 of the height on a side: 0.577^2 * 120 / 160 = 0.25.
    const double f = fraction(img, reddish);
    CHECK(f == Approx(0.25).margin(0.04));
    CHECK(fraction(img, isBackground) == Approx(1.0 - f).margin(0.03)); // nothing else drawn
    // Lit and shaded, not flat black: the cloth's red is well above its ambient-only value.
    CHECK(img.pixel(80, 60)[0] > 120);
}

TEST_CASE("the back of the cloth is drawn in the back colour", "[render]") {
    if (!renderingAvailable()) {
        WARN("skipped: built without OSMesa");
        return;
    }
    OffscreenRenderer r(160, 120);
    const Image img = r.render(cameraAt(-3.0), {sheetFacingPlusZ()}, kBackground);
    CHECK(bluish(img.pixel(80, 60)));
    CHECK(fraction(img, reddish) == 0.0);
    CHECK(fraction(img, bluish) == Approx(0.25).margin(0.04));
}

TEST_CASE("rigid bodies are drawn with their transform and hide what is behind them", "[render]") {
    if (!renderingAvailable()) {
        WARN("skipped: built without OSMesa");
        return;
    }
    OffscreenRenderer r(160, 120);
    DrawMesh box = makeBoxMesh(Vec3(0.3, 0.3, 0.3));
    box.front = box.back = {0.1f, 0.8f, 0.1f};
    box.model(0, 3) = 0.0f;
    box.model(2, 3) = 1.0f; // between the camera and the sheet
    const Image img = r.render(cameraAt(3.0), {sheetFacingPlusZ(), box}, kBackground);
    const auto c = img.pixel(80, 60);
    CHECK((c[1] > 2 * c[0] && c[1] > 2 * c[2])); // green box in front of the red cloth
    CHECK(reddish(img.pixel(80, 30)));           // cloth around it
    DrawMesh sphere = makeSphereMesh(0.4);
    sphere.front = sphere.back = {0.1f, 0.8f, 0.1f};
    const Image img2 = r.render(cameraAt(3.0), {sphere}, kBackground);
    const auto s = img2.pixel(80, 60);
    CHECK((s[1] > 2 * s[0] && s[1] > 2 * s[2]));
    CHECK(isBackground(img2.pixel(80, 10)));
}

TEST_CASE("a PNG written to disk reads back with the same pixels", "[render]") {
    if (!renderingAvailable()) {
        WARN("skipped: built without OSMesa");
        return;
    }
    OffscreenRenderer r(96, 64);
    const Image img = r.render(cameraAt(3.0), {sheetFacingPlusZ()}, kBackground);
    const fs::path dir = fs::path(DRAPE_TEST_OUT_DIR) / "render";
    fs::create_directories(dir);
    writePng(dir / "sheet.png", img);
    const Image back = readPng(dir / "sheet.png");
    CHECK(back.width == img.width);
    CHECK(back.height == img.height);
    CHECK(back.rgb == img.rgb);
    CHECK_THROWS_AS(writePng("/nonexistent-folder/x.png", img), SceneError);
    CHECK_THROWS_AS(readPng(dir / "missing.png"), SceneError);
}

TEST_CASE("a rendered shipped scene shows its cloth", "[render]") {
    if (!renderingAvailable()) {
        WARN("skipped: built without OSMesa");
        return;
    }
    SceneDesc scene =
        loadScene(fs::path(DRAPE_SAMPLES_DIR) / "scenes" / "experiment1_suspended_sheet.json");
    scene.frontColor = kFront;
    scene.backColor = kFront;
    Simulation sim(scene);
    OffscreenRenderer r(128, 96);
    const Image img = r.render(scene.camera, sim.drawMeshes(), kBackground);
    // The 340 x 340 sheet seen from about 900 away fills a good part of the view.
    const double f = fraction(img, reddish);
    CHECK(f > 0.10);
    CHECK(f < 0.80);
}
