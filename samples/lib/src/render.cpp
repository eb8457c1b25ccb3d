// render.cpp: OSMesa offscreen rendering (fixed-function OpenGL) and PNG I/O through libpng.
#include "drape_samples/render.hpp"

#include <GL/gl.h>
#include <GL/osmesa.h>
#include <png.h>

#include <Eigen/Geometry>
#include <Eigen/LU>

#include <cmath>
#include <cstring>

namespace drape::samples {

bool renderingAvailable() {
    return true;
}

struct OffscreenRenderer::Impl {
    OSMesaContext context = nullptr;
    std::vector<std::uint8_t> buffer; // RGBA, bottom row first
    int w = 0, h = 0;
};

OffscreenRenderer::OffscreenRenderer(int width, int height, int supersample)
    : width_(width), height_(height), ss_(supersample < 1 ? 1 : supersample) {
    if (width < 1 || height < 1 || width > kMaxImageSide || height > kMaxImageSide)
        throw SceneError("renderer: image size " + std::to_string(width) + "x" +
                         std::to_string(height) + " is outside 1.." +
                         std::to_string(kMaxImageSide));
    // Keep the supersampled buffer within OSMesa's maximum viewport.
    while (ss_ > 1 && (width * ss_ > 4096 || height * ss_ > 4096))
        --ss_;
    impl_ = new Impl;
    impl_->w = width * ss_;
    impl_->h = height * ss_;
    impl_->context = OSMesaCreateContextExt(OSMESA_RGBA, 24, 0, 0, nullptr);
    if (!impl_->context) {
        delete impl_;
        throw SceneError("renderer: OSMesa could not create an OpenGL context");
    }
    impl_->buffer.assign(
        static_cast<std::size_t>(impl_->w) * static_cast<std::size_t>(impl_->h) * 4u, 0);
}

OffscreenRenderer::~OffscreenRenderer() {
    if (impl_) {
        OSMesaDestroyContext(impl_->context);
        delete impl_;
    }
}

namespace {

Eigen::Matrix4f lookAt(const Vec3& eye, const Vec3& target, const Vec3& upHint) {
    const Eigen::Vector3f e = eye.cast<float>();
    const Eigen::Vector3f f = (target - eye).normalized().cast<float>();
    const Eigen::Vector3f s = f.cross(upHint.normalized().cast<float>()).normalized();
    const Eigen::Vector3f u = s.cross(f);
    Eigen::Matrix4f m = Eigen::Matrix4f::Identity();
    m.block<1, 3>(0, 0) = s.transpose();
    m.block<1, 3>(1, 0) = u.transpose();
    m.block<1, 3>(2, 0) = -f.transpose();
    m(0, 3) = -s.dot(e);
    m(1, 3) = -u.dot(e);
    m(2, 3) = f.dot(e);
    return m;
}

Eigen::Matrix4f perspective(double fovYDeg, double aspect, double zNear, double zFar) {
    const double f = 1.0 / std::tan(0.5 * fovYDeg * 3.14159265358979323846 / 180.0);
    Eigen::Matrix4f p = Eigen::Matrix4f::Zero();
    p(0, 0) = static_cast<float>(f / aspect);
    p(1, 1) = static_cast<float>(f);
    p(2, 2) = static_cast<float>((zFar + zNear) / (zNear - zFar));
    p(2, 3) = static_cast<float>(2.0 * zFar * zNear / (zNear - zFar));
    p(3, 2) = -1.0f;
    return p;
}

void setMaterial(GLenum face, const Color& c) {
    const GLfloat ambient[4] = {0.35f * c[0], 0.35f * c[1], 0.35f * c[2], 1.0f};
    const GLfloat diffuse[4] = {c[0], c[1], c[2], 1.0f};
    const GLfloat specular[4] = {0.08f, 0.08f, 0.08f, 1.0f};
    glMaterialfv(face, GL_AMBIENT, ambient);
    glMaterialfv(face, GL_DIFFUSE, diffuse);
    glMaterialfv(face, GL_SPECULAR, specular);
    glMaterialf(face, GL_SHININESS, 16.0f);
}

} // namespace

Image OffscreenRenderer::render(const CameraDesc& camera, const std::vector<DrawMesh>& meshes,
                                const Color& background) {
    if (!OSMesaMakeCurrent(impl_->context, impl_->buffer.data(), GL_UNSIGNED_BYTE, impl_->w,
                           impl_->h))
        throw SceneError("renderer: OSMesa could not bind the framebuffer");
    glViewport(0, 0, impl_->w, impl_->h);
    glClearColor(background[0], background[1], background[2], 1.0f);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    glEnable(GL_DEPTH_TEST);
    glDisable(GL_CULL_FACE);
    glEnable(GL_NORMALIZE);
    glShadeModel(GL_SMOOTH);

    // Clip planes from the distance to the target: scenes range from metres to the paper's
    // hundreds of units.
    const double dist = (camera.target - camera.position).norm();
    glMatrixMode(GL_PROJECTION);
    const Eigen::Matrix4f proj =
        perspective(camera.fovDeg, static_cast<double>(width_) / height_, dist * 0.01, dist * 50.0);
    glLoadMatrixf(proj.data());

    // Lights are placed in eye space (identity modelview), so they follow the camera.
    glMatrixMode(GL_MODELVIEW);
    glLoadIdentity();
    glEnable(GL_LIGHTING);
    glLightModeli(GL_LIGHT_MODEL_TWO_SIDE, GL_TRUE);
    const GLfloat globalAmbient[4] = {0.25f, 0.25f, 0.27f, 1.0f};
    glLightModelfv(GL_LIGHT_MODEL_AMBIENT, globalAmbient);
    // The key light is a point above and to the right of the camera, so that even a flat
    // sheet shows a gradient; the fill light is directional from the left.
    const float d = static_cast<float>(dist);
    const GLfloat keyDir[4] = {0.7f * d, 1.0f * d, 0.2f * d, 1.0f};
    const GLfloat keyCol[4] = {0.75f, 0.74f, 0.70f, 1.0f};
    const GLfloat fillDir[4] = {-0.6f, 0.1f, 0.8f, 0.0f};
    const GLfloat fillCol[4] = {0.30f, 0.32f, 0.36f, 1.0f};
    const GLfloat black[4] = {0.0f, 0.0f, 0.0f, 1.0f};
    glEnable(GL_LIGHT0);
    glLightfv(GL_LIGHT0, GL_POSITION, keyDir);
    glLightfv(GL_LIGHT0, GL_DIFFUSE, keyCol);
    glLightfv(GL_LIGHT0, GL_SPECULAR, keyCol);
    glLightfv(GL_LIGHT0, GL_AMBIENT, black);
    glEnable(GL_LIGHT1);
    glLightfv(GL_LIGHT1, GL_POSITION, fillDir);
    glLightfv(GL_LIGHT1, GL_DIFFUSE, fillCol);
    glLightfv(GL_LIGHT1, GL_SPECULAR, black);
    glLightfv(GL_LIGHT1, GL_AMBIENT, black);

    const Eigen::Matrix4f view = lookAt(camera.position, camera.target, camera.up);
    glEnableClientState(GL_VERTEX_ARRAY);
    glEnableClientState(GL_NORMAL_ARRAY);
    for (const DrawMesh& m : meshes) {
        if (m.indices.empty() || m.positions.empty()) continue;
        const Eigen::Matrix4f mv = view * m.model;
        // Normals facing the camera on each triangle's seen side (keepNormalsFacingViewer:
        // without it the triangles that turn a fold in the cloth came out near black), on
        // copies of the mesh's arrays.
        std::vector<float> positions = m.positions;
        std::vector<float> normals = m.normals.size() == m.positions.size()
                                         ? m.normals
                                         : computeNormals(m.positions, m.indices);
        std::vector<std::uint32_t> indices = m.indices;
        const Eigen::Vector4f eye = mv.inverse() * Eigen::Vector4f(0.0f, 0.0f, 0.0f, 1.0f);
        keepNormalsFacingViewer(positions, normals, indices, eye.head<3>() / eye.w());
        glLoadMatrixf(mv.data());
        setMaterial(GL_FRONT, m.front);
        setMaterial(GL_BACK, m.back);
        glVertexPointer(3, GL_FLOAT, 0, positions.data());
        glNormalPointer(GL_FLOAT, 0, normals.data());
        glDrawElements(GL_TRIANGLES, static_cast<GLsizei>(indices.size()), GL_UNSIGNED_INT,
                       indices.data());
    }
    glDisableClientState(GL_NORMAL_ARRAY);
    glDisableClientState(GL_VERTEX_ARRAY);
    glFinish();
    if (glGetError() != GL_NO_ERROR) throw SceneError("renderer: OpenGL reported an error");

    // Box-filter the supersampled buffer down and flip it to top-first rows.
    Image img;
    img.width = width_;
    img.height = height_;
    img.rgb.resize(static_cast<std::size_t>(width_) * static_cast<std::size_t>(height_) * 3u);
    const int s = ss_;
    for (int y = 0; y < height_; ++y)
        for (int x = 0; x < width_; ++x) {
            unsigned sum[3] = {0, 0, 0};
            for (int dy = 0; dy < s; ++dy)
                for (int dx = 0; dx < s; ++dx) {
                    const int by = (height_ - 1 - y) * s + dy; // OSMesa rows start at the bottom
                    const std::size_t o =
                        (static_cast<std::size_t>(by) * static_cast<std::size_t>(impl_->w) +
                         static_cast<std::size_t>(x * s + dx)) *
                        4u;
                    for (int c = 0; c < 3; ++c)
                        sum[c] += impl_->buffer[o + static_cast<std::size_t>(c)];
                }
            const std::size_t o = (static_cast<std::size_t>(y) * static_cast<std::size_t>(width_) +
                                   static_cast<std::size_t>(x)) *
                                  3u;
            for (int c = 0; c < 3; ++c)
                img.rgb[o + static_cast<std::size_t>(c)] = static_cast<std::uint8_t>(
                    (sum[c] + static_cast<unsigned>(s * s / 2)) / static_cast<unsigned>(s * s));
        }
    return img;
}

void writePng(const std::filesystem::path& file, const Image& image) {
    png_image pi;
    std::memset(&pi, 0, sizeof pi);
    pi.version = PNG_IMAGE_VERSION;
    pi.width = static_cast<png_uint_32>(image.width);
    pi.height = static_cast<png_uint_32>(image.height);
    pi.format = PNG_FORMAT_RGB;
    if (!png_image_write_to_file(&pi, file.string().c_str(), 0, image.rgb.data(), 0, nullptr)) {
        const std::string msg = pi.message;
        png_image_free(&pi);
        throw SceneError(file.string() + ": cannot write PNG: " + msg);
    }
}

Image readPng(const std::filesystem::path& file) {
    png_image pi;
    std::memset(&pi, 0, sizeof pi);
    pi.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&pi, file.string().c_str()))
        throw SceneError(file.string() + ": cannot read PNG: " + pi.message);
    pi.format = PNG_FORMAT_RGB;
    Image img;
    img.width = static_cast<int>(pi.width);
    img.height = static_cast<int>(pi.height);
    img.rgb.resize(PNG_IMAGE_SIZE(pi));
    if (!png_image_finish_read(&pi, nullptr, img.rgb.data(), 0, nullptr)) {
        const std::string msg = pi.message;
        png_image_free(&pi);
        throw SceneError(file.string() + ": cannot read PNG: " + msg);
    }
    return img;
}

} // namespace drape::samples
