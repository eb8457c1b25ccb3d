// The offscreen renderer: the cloth shows up in its own colours (front and back), rigid bodies
// are drawn, normals never face away from the camera (no black triangles at folds), and the PNG on
// disk holds the same pixels.
#include "drape_samples/render.hpp"
#include "drape_samples/simulation.hpp"

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
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

TEST_CASE("a triangle whose normals point to its far side is lit on the side the camera sees",
          "[render]") {
    if (!renderingAvailable()) {
        WARN("skipped: built without OSMesa");
        return;
    }
    // Where cloth folds onto itself a smooth vertex normal can point to the far side of a
    // triangle that turns the fold; two-sided lighting then lit that triangle from behind
    // (ambient only) and it came out near black. The same fault, made on purpose: the sheet's
    // normals all reversed. It must look as the sheet with its own normals does.
    const DrawMesh good = sheetFacingPlusZ();
    DrawMesh reversed = good;
    for (float& n : reversed.normals)
        n = -n;
    OffscreenRenderer r(160, 120);
    for (const double z : {3.0, -3.0}) { // front, then back
        INFO("camera at z = " << z);
        const Image want = r.render(cameraAt(z), {good}, kBackground);
        const Image got = r.render(cameraAt(z), {reversed}, kBackground);
        const auto c = got.pixel(80, 60);
        CHECK(std::max({c[0], c[1], c[2]}) > 120); // lit, not ambient-only (about 19)
        std::size_t differing = 0;
        for (std::size_t i = 0; i < got.rgb.size(); ++i)
            differing += got.rgb[i] != want.rgb[i] ? 1u : 0u;
        CHECK(differing == 0);
    }
}

TEST_CASE("keepNormalsFacingViewer turns only the normals that face away from the camera",
          "[render]") {
    // One triangle in the z = 0 plane, counter-clockwise seen from +z (its normal is +z).
    const std::vector<float> positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    const std::vector<std::uint32_t> indices = {0, 1, 2};
    // Corner 0 points to the far side, corner 1 has no normal (a smooth normal that cancelled
    // out), corner 2 is the triangle's own normal.
    const std::vector<float> normals = {0, 0, -1, 0, 0, 0, 0, 0, 1};
    auto normalAt = [](const std::vector<float>& n, std::uint32_t v) {
        return Eigen::Vector3f(n[3 * v], n[3 * v + 1], n[3 * v + 2]);
    };
    for (const float side : {1.0f, -1.0f}) { // the camera in front, then behind
        INFO("camera at z = " << 5.0f * side);
        std::vector<float> p = positions, n = normals;
        std::vector<std::uint32_t> idx = indices;
        const std::size_t changed =
            keepNormalsFacingViewer(p, n, idx, Eigen::Vector3f(0.2f, 0.2f, 5.0f * side));
        REQUIRE(changed == 2);
        REQUIRE(p.size() == 15); // two vertices added
        REQUIRE(n.size() == 15);
        CHECK(idx[0] == 3);
        CHECK(idx[1] == 4);
        CHECK(idx[2] == 2); // left alone
        // The new vertices sit where the old ones did and carry the triangle's normal (which
        // OpenGL negates when the triangle is seen from behind: then it faces the camera too).
        for (std::uint32_t k = 0; k < 2; ++k) {
            CHECK(Eigen::Vector3f(p[3 * idx[k]], p[3 * idx[k] + 1], p[3 * idx[k] + 2]) ==
                  Eigen::Vector3f(positions[3 * k], positions[3 * k + 1], positions[3 * k + 2]));
            CHECK((normalAt(n, idx[k]) - Eigen::Vector3f(0, 0, 1)).norm() < 1e-6f);
        }
    }
    SECTION("a normal leaning almost edge-on is blended towards the triangle's, not replaced") {
        std::vector<float> p = positions, n = normals;
        std::vector<std::uint32_t> idx = indices;
        // Corner 2 leans 84 degrees from the direction to the camera: cos = 0.1, below 0.2.
        const float s = std::sqrt(1.0f - 0.01f);
        n = {0, 0, 1, 0, 0, 1, s, 0, 0.1f};
        const Eigen::Vector3f eye(0.0f, 1.0f, 1.0e4f); // far away: the direction is +z
        CHECK(keepNormalsFacingViewer(p, n, idx, eye) == 1);
        const Eigen::Vector3f b = normalAt(n, idx[2]);
        CHECK(b.norm() == Approx(1.0f));
        CHECK(b.z() > 0.1f); // turned towards the camera
        CHECK(b.z() < 0.99f);
        CHECK(b.x() > 0.1f); // but still leaning the way it did
    }
    SECTION("a flat sheet seen from either side is left as it is") {
        DrawMesh sheet = sheetFacingPlusZ();
        for (const float z : {3.0f, -3.0f}) {
            DrawMesh m = sheet;
            CHECK(keepNormalsFacingViewer(m.positions, m.normals, m.indices,
                                          Eigen::Vector3f(0.3f, -0.2f, z)) == 0);
            CHECK(m.positions == sheet.positions);
            CHECK(m.indices == sheet.indices);
        }
    }
}
