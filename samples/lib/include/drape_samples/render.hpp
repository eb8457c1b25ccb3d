// drape_samples/render.hpp: headless rendering of cloth and rigid bodies to images.
//
// OffscreenRenderer draws through OSMesa (software OpenGL, fixed-function pipeline) into
// memory: smooth-shaded, two-sided lighting (front and back of the cloth in their own
// colours, every shading normal kept facing the camera: keepNormalsFacingViewer), two lights
// fixed to the camera, 2x2 supersampling. No window or display needed.
// The shape builders below make triangle meshes for rigid bodies and need no OpenGL.
#pragma once

#include "drape_samples/scene.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <filesystem>
#include <vector>

namespace drape::samples {

/// An 8-bit RGB image, rows top to bottom.
struct Image {
    int width = 0;
    int height = 0;
    std::vector<std::uint8_t> rgb; ///< width * height * 3 bytes
    std::array<std::uint8_t, 3> pixel(int x, int y) const {
        const std::size_t o = (static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
                               static_cast<std::size_t>(x)) *
                              3u;
        return {rgb[o], rgb[o + 1], rgb[o + 2]};
    }
};

/// A triangle mesh to draw, in world coordinates after `model`.
struct DrawMesh {
    std::vector<float> positions;       ///< x y z per vertex
    std::vector<float> normals;         ///< x y z per vertex; computed when empty
    std::vector<std::uint32_t> indices; ///< three per triangle, counter-clockwise = front
    Color front = {0.8f, 0.8f, 0.8f};
    Color back = {0.6f, 0.6f, 0.6f};
    Eigen::Matrix4f model = Eigen::Matrix4f::Identity();
};

/// Area-weighted smooth vertex normals of a mesh given as float arrays.
std::vector<float> computeNormals(const std::vector<float>& positions,
                                  const std::vector<std::uint32_t>& indices);

/// Keeps every shading normal facing the camera on the side its triangle is seen from.
///
/// Why: OpenGL's two-sided lighting lights the side of a triangle that faces the camera and,
/// for a triangle seen from behind, negates its normals. A smooth vertex normal averages the
/// triangles around the vertex; where the cloth folds back onto itself it follows the layer
/// on one side and can lean far from a triangle that turns the fold (or cancel out, when the
/// fallback +y is used), so that on the seen side it points away from the camera. Such a
/// triangle was lit as if from behind: ambient only, near black.
///
/// What: for each triangle corner, c is the cosine between its normal (negated if the
/// triangle is seen from behind) and the direction from the corner to `eye`. Where c is
/// below kNormalViewCosine the normal is blended towards the triangle's own (flat) normal on
/// the seen side, which always faces the camera: all the way at c <= 0, not at all at
/// c = kNormalViewCosine, so the shading changes continuously as the cloth moves. A blended
/// corner gets a vertex of its own (its position is appended to `positions`, its index
/// rewritten); other corners and flat meshes are left as they are. `eye` is the camera
/// position in the mesh's coordinates, which must be the world's up to a rigid motion.
/// Triangles with no area or seen edge-on are left alone. Returns how many corners changed.
std::size_t keepNormalsFacingViewer(std::vector<float>& positions, std::vector<float>& normals,
                                    std::vector<std::uint32_t>& indices,
                                    const Eigen::Vector3f& eye);
/// See keepNormalsFacingViewer (a cosine of 0.2: about 78 degrees from the view direction).
constexpr float kNormalViewCosine = 0.2f;

/// Converts a drape mesh (double) into a DrawMesh with normals.
DrawMesh toDrawMesh(const std::vector<Vec3>& vertices, const std::vector<Triangle>& triangles,
                    const Color& front, const Color& back);

/// Shape meshes in the body's local frame (centred at the origin; capsules along y).
DrawMesh makeBoxMesh(const Vec3& halfExtents);
DrawMesh makeSphereMesh(double radius, int slices = 32, int stacks = 16);
DrawMesh makeCapsuleMesh(double radius, double height, int slices = 32, int stacks = 16);
/// A checkered square of side `size` on the plane n . x = offset, centred near `around`.
std::vector<DrawMesh> makePlaneMeshes(const Vec3& normal, double offset, const Vec3& around,
                                      double size, const Color& color, int cells = 16);

/// Whether this build renders (DRAPE_WITH_RENDERING).
bool renderingAvailable();

/// A software OpenGL context and its framebuffer. One per thread; not copyable.
class OffscreenRenderer {
  public:
    /// Throws SceneError if OSMesa cannot create a context of this size.
    OffscreenRenderer(int width, int height, int supersample = 2);
    ~OffscreenRenderer();
    OffscreenRenderer(const OffscreenRenderer&) = delete;
    OffscreenRenderer& operator=(const OffscreenRenderer&) = delete;

    /// Draws the meshes as seen by the camera (the camera's width and height are ignored:
    /// the renderer's size is used) and returns the image.
    Image render(const CameraDesc& camera, const std::vector<DrawMesh>& meshes,
                 const Color& background);

    int width() const { return width_; }
    int height() const { return height_; }

  private:
    struct Impl;
    Impl* impl_ = nullptr;
    int width_ = 0;
    int height_ = 0;
    int ss_ = 1;
};

/// Writes an RGB PNG through libpng; throws SceneError naming the file on failure.
void writePng(const std::filesystem::path& file, const Image& image);
/// Reads a PNG as 8-bit RGB; throws SceneError on failure.
Image readPng(const std::filesystem::path& file);

} // namespace drape::samples
