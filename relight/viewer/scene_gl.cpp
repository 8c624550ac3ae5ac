// The viewer's scene on the GPU: see scene_gl.h.
//
// In detail: the geometry pass draws the mesh indexed and writes gl_PrimitiveID + 1
// (0 = nothing). The shading pass fetches, for a pixel with a triangle, its vertex
// indices and positions from textures, intersects the pixel's ray with it
// (Moller-Trumbore: the barycentrics Embree reports), interpolates the vertex normals
// and the relit radiance of the three vertices with them and applies F_t, the view-map
// terms and the optional specular layer, term for term as TranslucentShader::shade.
// Each pixel is shaded exactly once, whatever the depth complexity; when only the light
// changes (relighting, exposure, toggles) the frame is this one pass. It tone-maps into
// output 0 and writes the linear radiance (alpha 1 on the object, 0 behind) to output
// 1, which is dropped when drawing straight into the window. All float textures are
// RGBA32F (the fast texel-fetch path of software rasterisers such as llvmpipe).
//
// The shaders are in relight/viewer/shaders/, embedded at build time
// (shaders/embed.cmake) as prt::shaders::k<Name>: fullscreen.vert draws the full-screen
// triangle, visibility.vert/.frag the geometry pass, shade_common.glsl + shade.frag the
// shading pass. Every function of the last two ports one of common/ exactly (float
// instead of double): rayDirection = cameraRayDirection at the pixel centre,
// latLongRadiance = environmentRadiance, fresnelReflectance / refractDirection =
// bssrdf.cpp, faceUV = directionToFaceUV, viewMap = Cubemap::sampleBilinear, encodeSrgb
// = writePng's clamp + linearToSrgb.

#include "relight/viewer/scene_gl.h"

#include <glm/gtc/matrix_transform.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <iterator>
#include <utility>

#include "common/envmap.h"
#include "common/error.h"
#include "common/util.h"
#include "relight/render/specular.h"
#include "relight/viewer/gl_util.h"
#include "relight/viewer/shaders/shaders.h"

namespace prt {

namespace fs = std::filesystem;

namespace {

bool sameCamera(const Camera& a, const Camera& b) {
    return a.eye == b.eye && a.target == b.target && a.up == b.up && a.fovY == b.fovY && a.width == b.width &&
           a.height == b.height;
}

}  // namespace

SceneGl::SceneGl(const RelightObject& object, const std::vector<Image>& environments, int specularBlur, int width,
                 int height, int subpixels)
    : object_(object),
      environments_(environments),
      prefiltered_(environments.size()),
      specularBlur_(specularBlur),
      fileTerms_(object.transport.viewMaps ? object.transport.viewMaps->terms : 0),
      subpixels_(subpixels) {
    if (subpixels_ < 1) throw Error("--spp", "the sub-pixel grid must be at least 1 x 1");
    {
        const TriangleMesh& object = object_.mesh;
        vertexAreas_.assign(object.vertexCount(), 0.0f);
        for (size_t f = 0; f < object.triangleCount(); ++f)
            for (int k = 0; k < 3; ++k) vertexAreas_[object.triangles[f][k]] += faceArea(object, f) / 3.0f;
    }
    // What is drawn: the object, then the ground's vertices and triangles (withGround).
    const TriangleMesh mesh = object_.ground ? withGround(object_.mesh, object_.ground->mesh) : object_.mesh;
    const size_t V = mesh.vertexCount(), T = mesh.triangleCount();
    drawnVertices_ = V;
    drawnTriangles_ = T;
    drawnCentre_ = object_.sphereCentre;
    drawnRadius_ = object_.sphereRadius;
    if (object_.ground) {  // a sphere around the plane's box too: the half diagonal of the whole box
        const Bounds box = bounds(mesh);
        drawnCentre_ = glm::dvec3(box.centre());
        drawnRadius_ = 0.5 * double(box.diagonal());
    }
    GLint maxSize = 0;
    glGetIntegerv(GL_MAX_TEXTURE_SIZE, &maxSize);
    rowWidth_ = std::min(4096, int(maxSize));
    const auto rowsFor = [&](size_t n) { return int((n + size_t(rowWidth_) - 1) / size_t(rowWidth_)); };
    const int vertexRows = std::max(1, rowsFor(V));
    const int triangleRows = std::max(1, rowsFor(T));
    slotRows_ = vertexRows;
    const int slots = 1 + fileTerms_;
    if (triangleRows > maxSize || vertexRows * slots > maxSize)
        throw Error("OpenGL", "mesh too large for this OpenGL's textures (" + std::to_string(V) + " vertices, " +
                                  std::to_string(T) + " triangles, maximum texture size " +
                                  std::to_string(maxSize) + ")");
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);

    // Indexed draw of the geometry pass: positions only.
    glGenVertexArrays(1, &meshVao_);
    glBindVertexArray(meshVao_);
    glGenBuffers(2, meshBuffers_);
    glBindBuffer(GL_ARRAY_BUFFER, meshBuffers_[0]);
    glBufferData(GL_ARRAY_BUFFER, GLsizeiptr(V * sizeof(glm::vec3)), mesh.positions.data(), GL_STATIC_DRAW);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, sizeof(glm::vec3), nullptr);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, meshBuffers_[1]);
    glBufferData(GL_ELEMENT_ARRAY_BUFFER, GLsizeiptr(T * sizeof(glm::uvec3)), mesh.triangles.data(), GL_STATIC_DRAW);
    glBindVertexArray(0);
    glBindBuffer(GL_ARRAY_BUFFER, 0);

    // The same data as textures for the fragment shader (RGBA: the fast fetch path).
    std::vector<glm::vec4> positions(V);
    for (size_t v = 0; v < V; ++v) positions[v] = glm::vec4(mesh.positions[v], 1.0f);
    positions_ = makeTexture(GL_RGBA32F, rowWidth_, vertexRows, GL_RGBA, GL_FLOAT, nullptr);
    uploadRows(positions_, rowWidth_, 0, V, GL_RGBA, GL_FLOAT, &positions[0].x, 4);
    for (size_t v = 0; v < V; ++v)
        positions[v] = glm::vec4(v < mesh.normals.size() ? mesh.normals[v] : glm::vec3(0.0f, 1.0f, 0.0f), 0.0f);
    normals_ = makeTexture(GL_RGBA32F, rowWidth_, vertexRows, GL_RGBA, GL_FLOAT, nullptr);
    uploadRows(normals_, rowWidth_, 0, V, GL_RGBA, GL_FLOAT, &positions[0].x, 4);
    std::vector<glm::uvec4> triangles(T);
    for (size_t t = 0; t < T; ++t) triangles[t] = glm::uvec4(mesh.triangles[t], 0u);
    triangles_ = makeTexture(GL_RGBA32UI, rowWidth_, triangleRows, GL_RGBA_INTEGER, GL_UNSIGNED_INT, nullptr);
    uploadRows(triangles_, rowWidth_, 0, T, GL_RGBA_INTEGER, GL_UNSIGNED_INT, &triangles[0].x, 4);
    const std::vector<float> zeros(size_t(rowWidth_) * size_t(vertexRows * slots) * 4, 0.0f);
    for (GLuint& t : radiance_)
        t = makeTexture(GL_RGBA32F, rowWidth_, vertexRows * slots, GL_RGBA, GL_FLOAT, zeros.data());
    if (fileTerms_ > 0) {
        const ViewMaps& maps = *object_.transport.viewMaps;
        viewMapSize_ = maps.size;
        if (size_t(6) * maps.size * fileTerms_ > size_t(maxSize))
            throw Error("OpenGL", "view maps too large for this OpenGL's textures");
        viewMaps_ = makeTexture(GL_R32F, maps.size, 6 * maps.size * fileTerms_, GL_RED, GL_FLOAT, maps.data.data());
    }
    if (object_.baseColour.enabled()) uploadBaseColour(maxSize);
    const float zero[4] = {0, 0, 0, 0};
    dummy_ = makeTexture(GL_RGBA32F, 1, 1, GL_RGBA, GL_FLOAT, zero);
    envTextures_.assign(environments_.size(), 0);
    prefilteredTextures_.assign(environments_.size(), 0);

    glGenVertexArrays(1, &vao_);
    visibilityProgram_ = linkProgram({shaders::kVisibilityVert}, {shaders::kVisibilityFrag}, "visibility");
    shadeProgram_ = linkProgram({shaders::kFullscreenVert}, {shaders::kShadeCommon, shaders::kShadeFrag}, "shading");
    if (subpixels_ > 1)
        resolveProgram_ =
            linkProgram({shaders::kFullscreenVert}, {shaders::kShadeCommon, shaders::kResolveFrag}, "resolve");
    checkGl("creating the mesh buffers, textures and shaders");
    createTargets(width, height);
}

SceneGl::~SceneGl() {
    destroyTargets();
    GLuint textures[] = {positions_,       normals_,   triangles_,   radiance_[0], radiance_[1],   viewMaps_, dummy_,
                         triangleColours_, cornerUvs_, baseTexture_, pointLights_, pointIrradiance_};
    glDeleteTextures(GLsizei(std::size(textures)), textures);
    if (!envTextures_.empty()) glDeleteTextures(GLsizei(envTextures_.size()), envTextures_.data());
    if (!prefilteredTextures_.empty())
        glDeleteTextures(GLsizei(prefilteredTextures_.size()), prefilteredTextures_.data());
    glDeleteProgram(visibilityProgram_);
    glDeleteProgram(shadeProgram_);
    if (resolveProgram_) glDeleteProgram(resolveProgram_);
    glDeleteVertexArrays(1, &vao_);
    glDeleteVertexArrays(1, &meshVao_);
    glDeleteBuffers(2, meshBuffers_);
}

void SceneGl::resize(int width, int height) { createTargets(width, height); }

void SceneGl::createTargets(int width, int height) {
    destroyTargets();
    targetWidth_ = width;
    targetHeight_ = height;
    // Visibility (and, with sub-pixels, shading) at the sub-pixel grid's size.
    const int n = subpixels_;
    GLint maxSize = 0;
    glGetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &maxSize);
    if (width * n > maxSize || height * n > maxSize)
        throw Error("OpenGL", std::to_string(width * n) + " x " + std::to_string(height * n) +
                                  " sub-pixels exceed this OpenGL's largest framebuffer (" + std::to_string(maxSize) +
                                  "): use a smaller --spp or window");
    visibility_ = makeTexture(GL_R32UI, width * n, height * n, GL_RED_INTEGER, GL_UNSIGNED_INT, nullptr);
    glGenRenderbuffers(1, &depth_);
    glBindRenderbuffer(GL_RENDERBUFFER, depth_);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT32F, width * n, height * n);
    glGenFramebuffers(1, &visibilityFbo_);
    glBindFramebuffer(GL_FRAMEBUFFER, visibilityFbo_);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, visibility_, 0);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth_);
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
        throw Error("OpenGL", "the visibility framebuffer (R32UI + DEPTH32F) is not supported");
    visibilityValid_ = false;

    displayColor_ = makeTexture(GL_RGBA8, width, height, GL_RGBA, GL_UNSIGNED_BYTE, nullptr);
    linearColor_ = makeTexture(GL_RGBA32F, width, height, GL_RGBA, GL_FLOAT, nullptr);
    glGenFramebuffers(1, &offscreenFbo_);
    glBindFramebuffer(GL_FRAMEBUFFER, offscreenFbo_);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, displayColor_, 0);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT1, GL_TEXTURE_2D, linearColor_, 0);
    const GLenum buffers[2] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1};
    glDrawBuffers(2, buffers);
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
        throw Error("OpenGL", "the offscreen framebuffer (RGBA8 + RGBA32F) is not supported");
    if (n > 1) {  // the shading pass writes only its linear output (location 1) here
        subpixelLinear_ = makeTexture(GL_RGBA32F, width * n, height * n, GL_RGBA, GL_FLOAT, nullptr);
        glGenFramebuffers(1, &subpixelFbo_);
        glBindFramebuffer(GL_FRAMEBUFFER, subpixelFbo_);
        glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT1, GL_TEXTURE_2D, subpixelLinear_, 0);
        const GLenum linearOnly[2] = {GL_NONE, GL_COLOR_ATTACHMENT1};
        glDrawBuffers(2, linearOnly);
        if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
            throw Error("OpenGL", "the sub-pixel framebuffer (RGBA32F) is not supported");
    }
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    checkGl("creating the framebuffers");
}

void SceneGl::destroyTargets() {
    if (offscreenFbo_) glDeleteFramebuffers(1, &offscreenFbo_);
    if (subpixelFbo_) glDeleteFramebuffers(1, &subpixelFbo_);
    if (subpixelLinear_) glDeleteTextures(1, &subpixelLinear_);
    subpixelFbo_ = subpixelLinear_ = 0;
    if (visibilityFbo_) glDeleteFramebuffers(1, &visibilityFbo_);
    if (depth_) glDeleteRenderbuffers(1, &depth_);
    GLuint t[] = {displayColor_, linearColor_, visibility_};
    glDeleteTextures(3, t);
    offscreenFbo_ = visibilityFbo_ = depth_ = displayColor_ = linearColor_ = visibility_ = 0;
    visibilityValid_ = false;
}

GLuint SceneGl::environmentTexture(int index, bool prefiltered) {
    std::vector<GLuint>& cache = prefiltered ? prefilteredTextures_ : envTextures_;
    GLuint& t = cache[size_t(index)];
    if (t) return t;
    const Image* image = &environments_[size_t(index)];
    if (prefiltered) {
        Image& p = prefiltered_[size_t(index)];
        if (p.empty()) p = prefilterEnvironment(*image, specularBlurFactor(specularBlur_, *image));
        image = &p;
    }
    // loadEnvironment gives RGB; rows top first, as texel rows 0, 1, ...
    std::vector<float> rgba(size_t(image->width) * size_t(image->height) * 4, 0.0f);
    for (size_t i = 0; i < size_t(image->width) * size_t(image->height); ++i)
        for (int c = 0; c < 3; ++c) rgba[i * 4 + size_t(c)] = image->pixels[i * size_t(image->channels) + size_t(c)];
    t = makeTexture(GL_RGBA32F, image->width, image->height, GL_RGBA, GL_FLOAT, rgba.data());
    // For the background's filtered lookups (texelFetch ignores these).
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_REPEAT);
    checkGl("uploading an environment");
    return t;
}

void SceneGl::uploadBaseColour(int maxSize) {
    const Asset& asset = *object_.baseColour.asset();
    const size_t T = object_.mesh.triangleCount();
    // One texture at most: the shader samples a single image.
    const AssetMaterial* textured = nullptr;
    for (const AssetMaterial& m : asset.materials) {
        if (!m.hasTexture() || asset.uvs.empty()) continue;
        if (textured && !(m.baseColorTexture.pixels == textured->baseColorTexture.pixels &&
                          m.wrapU == textured->wrapU && m.wrapV == textured->wrapV))
            throw Error("--base-colour", "the viewer draws one base-colour texture; this asset has several (use render)");
        textured = &m;
    }
    // Per triangle: the material's factor, and in A whether its texture applies.
    std::vector<glm::vec4> colours(T);
    for (size_t t = 0; t < T; ++t) {
        const AssetMaterial& m = asset.materials[asset.triangleMaterials.empty() ? 0 : asset.triangleMaterials[t]];
        colours[t] = glm::vec4(glm::vec3(m.baseColorFactor), m.hasTexture() && !asset.uvs.empty() ? 1.0f : 0.0f);
    }
    const auto rowsFor = [&](size_t n) { return std::max(1, int((n + size_t(rowWidth_) - 1) / size_t(rowWidth_))); };
    if (rowsFor(3 * T) > maxSize) throw Error("OpenGL", "mesh too large for this OpenGL's texture coordinates");
    triangleColours_ = makeTexture(GL_RGBA32F, rowWidth_, rowsFor(T), GL_RGBA, GL_FLOAT, nullptr);
    uploadRows(triangleColours_, rowWidth_, 0, T, GL_RGBA, GL_FLOAT, &colours[0].x, 4);
    if (!textured) return;
    std::vector<glm::vec4> uvs(3 * T);
    for (size_t i = 0; i < uvs.size(); ++i) uvs[i] = glm::vec4(asset.uvs[i], 0.0f, 0.0f);
    cornerUvs_ = makeTexture(GL_RGBA32F, rowWidth_, rowsFor(3 * T), GL_RGBA, GL_FLOAT, nullptr);
    uploadRows(cornerUvs_, rowWidth_, 0, uvs.size(), GL_RGBA, GL_FLOAT, &uvs[0].x, 4);
    const Image& image = textured->baseColorTexture;
    if (image.width > maxSize || image.height > maxSize)
        throw Error("OpenGL", "base-colour texture too large for this OpenGL's textures");
    std::vector<glm::vec4> texels(size_t(image.width) * size_t(image.height));
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x) {
            const float* p = image.pixel(x, y);
            const int c = image.channels;
            texels[size_t(y) * size_t(image.width) + size_t(x)] =
                c >= 3 ? glm::vec4(p[0], p[1], p[2], 1.0f) : glm::vec4(p[0], p[0], p[0], 1.0f);
        }
    baseTexture_ = makeTexture(GL_RGBA32F, image.width, image.height, GL_RGBA, GL_FLOAT, texels.data());
    baseTextureSize_ = glm::ivec2(image.width, image.height);
    baseWrap_ = glm::ivec2(int(textured->wrapU), int(textured->wrapV));
}

void SceneGl::uploadRadiance(const std::vector<glm::vec4>& packed, int slots, const std::vector<glm::vec3>& ground) {
    const int back = 1 - radianceFront_;
    const size_t V = object_.mesh.vertexCount();
    for (int k = 0; k < slots; ++k) {
        if (k == 0 && drawnVertices_ > V) {
            // Slot 0 holds the ground's vertices after the object's.
            slot0_.assign(drawnVertices_, glm::vec4(0.0f));
            std::copy(packed.begin(), packed.begin() + ptrdiff_t(V), slot0_.begin());
            if (ground.size() == drawnVertices_ - V)
                for (size_t g = 0; g < ground.size(); ++g) slot0_[V + g] = glm::vec4(ground[g], 0.0f);
            uploadRows(radiance_[back], rowWidth_, 0, drawnVertices_, GL_RGBA, GL_FLOAT, &slot0_[0].x, 4);
            continue;
        }
        uploadRows(radiance_[back], rowWidth_, k * slotRows_, V, GL_RGBA, GL_FLOAT, &packed[size_t(k) * V].x, 4);
    }
    radianceFront_ = back;
    // Chang's Radiance_avg without reading the frame back: the area-weighted mean
    // luminance of the view-independent radiance (slot 0) over the surface.
    double sum = 0.0, area = 0.0;
    for (size_t v = 0; v < V && slots > 0; ++v) {
        const glm::vec4& L = packed[v];
        const float y = luminance(glm::vec3(std::max(L.r, 0.0f), std::max(L.g, 0.0f), std::max(L.b, 0.0f)));
        if (std::isfinite(y)) sum += double(vertexAreas_[v]) * double(y);
        area += double(vertexAreas_[v]);
    }
    radianceAverage_ = area > 0.0 ? sum / area : 0.0;
}

void SceneGl::uploadPointSpecular(const std::vector<Light>& lights, const std::vector<glm::vec3>& irradiance) {
    const size_t V = object_.mesh.vertexCount();
    const int L = int(lights.size());
    if (irradiance.size() != lights.size() * V)
        throw Error("point lights", "the lights' vertex irradiance is of another mesh or light count");
    pointLightCount_ = 0;
    if (L == 0) return;
    if (L > pointTextureLights_) {
        GLint maxSize = 0;
        glGetIntegerv(GL_MAX_TEXTURE_SIZE, &maxSize);
        if (L > maxSize || int64_t(L) * slotRows_ > maxSize)
            throw Error("OpenGL", std::to_string(L) + " point lights' specular exceeds this OpenGL's textures");
        const GLuint old[2] = {pointLights_, pointIrradiance_};
        glDeleteTextures(2, old);
        pointLights_ = makeTexture(GL_RGBA32F, L, 1, GL_RGBA, GL_FLOAT, nullptr);
        pointIrradiance_ = makeTexture(GL_RGBA32F, rowWidth_, L * slotRows_, GL_RGBA, GL_FLOAT, nullptr);
        pointTextureLights_ = L;
    }
    std::vector<glm::vec4> texels(static_cast<size_t>(L));
    for (int l = 0; l < L; ++l) {
        const Light& light = lights[size_t(l)];
        texels[size_t(l)] = hasPosition(light) ? glm::vec4(glm::vec3(light.position), 0.0f)
                                               : glm::vec4(glm::vec3(light.direction), 1.0f);
    }
    uploadRows(pointLights_, L, 0, size_t(L), GL_RGBA, GL_FLOAT, &texels[0].x, 4);
    std::vector<glm::vec4> rows(V);
    for (int l = 0; l < L; ++l) {
        for (size_t v = 0; v < V; ++v) rows[v] = glm::vec4(irradiance[size_t(l) * V + v], 0.0f);
        uploadRows(pointIrradiance_, rowWidth_, l * slotRows_, V, GL_RGBA, GL_FLOAT, &rows[0].x, 4);
    }
    pointLightCount_ = L;
}

void SceneGl::draw(const SceneFrame& frame, bool offscreen) {
    const Camera& c = frame.camera;
    const glm::dvec3 forward = glm::normalize(c.target - c.eye);
    const glm::dvec3 right = glm::normalize(glm::cross(forward, c.up));
    const glm::dvec3 up = glm::cross(right, forward);
    const double tanHalf = std::tan(glm::radians(c.fovY) * 0.5);
    const glm::dmat3 rotation = rotationY(frame.rotation);
    const glm::mat3 rotationT(glm::transpose(rotation));
    const int env = frame.environment;

    glBindVertexArray(vao_);
    glDisable(GL_BLEND);
    glDisable(GL_CULL_FACE);
    glDisable(GL_SCISSOR_TEST);
    glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    const int n = subpixels_;
    glViewport(0, 0, c.width * n, c.height * n);

    // 1. Visibility, when the camera changed. No back-face culling: the offline
    // renderer's rays hit back faces (through holes; black there, n . w_o <= 0), and a
    // front face seen at a grazing angle can come out back-facing in float.
    if (!visibilityValid_ || !sameCamera(c, visibilityCamera_)) {
        // Depth range around the bounding sphere (the planes must not clip the object).
        const double r = std::max(drawnRadius_, 1e-6);
        const double d = glm::length(drawnCentre_ - c.eye);
        const double zFar = d + 1.01 * r;
        const double zNear = std::max(d - 1.01 * r, 1e-4 * zFar);
        const glm::dmat4 view = glm::lookAt(c.eye, c.target, c.up);
        const glm::dmat4 projection =
            glm::perspective(glm::radians(c.fovY), double(c.width) / c.height, zNear, zFar);
        const glm::mat4 viewProjection(projection * view);
        glBindFramebuffer(GL_FRAMEBUFFER, visibilityFbo_);
        const GLuint zero[4] = {0, 0, 0, 0};
        glClearBufferuiv(GL_COLOR, 0, zero);
        glClearDepth(1.0);
        glDepthMask(GL_TRUE);
        glClear(GL_DEPTH_BUFFER_BIT);
        glEnable(GL_DEPTH_TEST);
        glDepthFunc(GL_LESS);
        glUseProgram(visibilityProgram_);
        glUniformMatrix4fv(glGetUniformLocation(visibilityProgram_, "uViewProjection"), 1, GL_FALSE,
                           &viewProjection[0][0]);
        glBindVertexArray(meshVao_);
        glDrawElements(GL_TRIANGLES, GLsizei(3 * drawnTriangles_), GL_UNSIGNED_INT, nullptr);
        glBindVertexArray(vao_);
        glDisable(GL_DEPTH_TEST);
        visibilityCamera_ = c;
        visibilityValid_ = true;
    }

    // 2. Shading, one full-screen triangle (of sub-pixels when n > 1).
    glBindFramebuffer(GL_FRAMEBUFFER, n > 1 ? subpixelFbo_ : offscreen ? offscreenFbo_ : 0);
    const GLuint p = shadeProgram_;
    glUseProgram(p);
    glUniform3f(glGetUniformLocation(p, "uEye"), float(c.eye.x), float(c.eye.y), float(c.eye.z));
    glUniform3f(glGetUniformLocation(p, "uForward"), float(forward.x), float(forward.y), float(forward.z));
    glUniform3f(glGetUniformLocation(p, "uRight"), float(right.x), float(right.y), float(right.z));
    glUniform3f(glGetUniformLocation(p, "uUp"), float(up.x), float(up.y), float(up.z));
    glUniform1f(glGetUniformLocation(p, "uTanHalf"), float(tanHalf));
    glUniform2f(glGetUniformLocation(p, "uViewSize"), float(c.width * n), float(c.height * n));
    glUniformMatrix3fv(glGetUniformLocation(p, "uEnvRotationT"), 1, GL_FALSE, &rotationT[0][0]);
    const DisplayMapping mapping = displayMapping(frame.display, radianceAverage_);
    glUniform1f(glGetUniformLocation(p, "uScale"), mapping.scale);
    glUniform1i(glGetUniformLocation(p, "uToneMap"), int(mapping.op));
    glUniform1i(glGetUniformLocation(p, "uRowWidth"), rowWidth_);
    glUniform1i(glGetUniformLocation(p, "uSlotRows"), slotRows_);
    glUniform1i(glGetUniformLocation(p, "uTermCount"), frame.viewTerms);
    glUniform1i(glGetUniformLocation(p, "uViewMapSize"), std::max(viewMapSize_, 1));
    glUniform1f(glGetUniformLocation(p, "uEta"), float(object_.eta));
    glUniform1fv(glGetUniformLocation(p, "uEyePath"), EyePathTable::kSize, frame.eyePath.values().data());
    glUniform1i(glGetUniformLocation(p, "uObjectTriangles"), int(object_.mesh.triangleCount()));
    glUniform1i(glGetUniformLocation(p, "uSpecular"), frame.specular && frame.environmentLight ? 1 : 0);
    glUniform1i(glGetUniformLocation(p, "uBackground"), frame.environmentLight ? 1 : 0);
    glUniform1i(glGetUniformLocation(p, "uHasBaseColour"), triangleColours_ ? 1 : 0);
    glUniform2i(glGetUniformLocation(p, "uBaseSize"), baseTextureSize_.x, baseTextureSize_.y);
    glUniform2i(glGetUniformLocation(p, "uBaseWrap"), baseWrap_.x, baseWrap_.y);
    glUniform1i(glGetUniformLocation(p, "uPointLightCount"), frame.pointSpecular ? pointLightCount_ : 0);
    glUniform1f(glGetUniformLocation(p, "uPointRoughness"), float(frame.pointSpecularRoughness));
    glUniform1f(glGetUniformLocation(p, "uPointEta"), float(frame.pointEta));
    const std::pair<const char*, GLuint> textures[] = {
        {"uVisibility", visibility_},
        {"uEnvironment", environmentTexture(env, false)},
        {"uPositions", positions_},
        {"uNormals", normals_},
        {"uTriangles", triangles_},
        {"uRadiance", radiance_[radianceFront_]},
        {"uViewMaps", viewMaps_ ? viewMaps_ : dummy_},
        {"uPrefiltered", frame.specular ? environmentTexture(env, true) : dummy_},
        {"uTriangleColours", triangleColours_ ? triangleColours_ : dummy_},
        {"uCornerUvs", cornerUvs_ ? cornerUvs_ : dummy_},
        {"uBaseTexture", baseTexture_ ? baseTexture_ : dummy_},
        {"uPointLights", pointLights_ ? pointLights_ : dummy_},
        {"uPointIrradiance", pointIrradiance_ ? pointIrradiance_ : dummy_},
    };
    for (int unit = 0; unit < int(std::size(textures)); ++unit) {
        glActiveTexture(GLenum(GL_TEXTURE0 + unit));
        glBindTexture(GL_TEXTURE_2D, textures[unit].second);
        glUniform1i(glGetUniformLocation(p, textures[unit].first), unit);
    }
    glDrawArrays(GL_TRIANGLES, 0, 3);

    // 3. With sub-pixels: their box filter, then the display transform, per pixel.
    if (n > 1) {
        glBindFramebuffer(GL_FRAMEBUFFER, offscreen ? offscreenFbo_ : 0);
        glViewport(0, 0, c.width, c.height);
        const GLuint q = resolveProgram_;
        glUseProgram(q);
        glUniform1f(glGetUniformLocation(q, "uScale"), mapping.scale);
        glUniform1i(glGetUniformLocation(q, "uToneMap"), int(mapping.op));
        glUniform1i(glGetUniformLocation(q, "uSubpixelGrid"), n);
        glActiveTexture(GL_TEXTURE0);
        glBindTexture(GL_TEXTURE_2D, subpixelLinear_);
        glUniform1i(glGetUniformLocation(q, "uSubpixels"), 0);
        glDrawArrays(GL_TRIANGLES, 0, 3);
    }

    glActiveTexture(GL_TEXTURE0);
    glBindVertexArray(0);
    glUseProgram(0);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
}

void SceneGl::blitToWindow(int width, int height) {
    const bool direct = width == targetWidth_ && height == targetHeight_;
    glBindFramebuffer(GL_READ_FRAMEBUFFER, offscreenFbo_);
    glReadBuffer(GL_COLOR_ATTACHMENT0);
    glBindFramebuffer(GL_DRAW_FRAMEBUFFER, 0);
    glViewport(0, 0, width, height);
    if (!direct) {
        glClearColor(0.0f, 0.0f, 0.0f, 1.0f);
        glClear(GL_COLOR_BUFFER_BIT);
    }
    glBlitFramebuffer(0, 0, targetWidth_, targetHeight_, 0, 0, width, height, GL_COLOR_BUFFER_BIT,
                      direct ? GL_NEAREST : GL_LINEAR);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
}

void SceneGl::writeScreenshot(const std::string& path) {
    const fs::path parent = fs::path(path).parent_path();
    if (!parent.empty()) fs::create_directories(parent);
    if (toLower(fs::path(path).extension().string()) == ".exr") {
        // The linear scene framebuffer: RGB radiance, A = 1 on the object.
        Image image(targetWidth_, targetHeight_, 4);
        std::vector<float> rows(image.pixels.size());
        glBindFramebuffer(GL_READ_FRAMEBUFFER, offscreenFbo_);
        glReadBuffer(GL_COLOR_ATTACHMENT1);
        glReadPixels(0, 0, targetWidth_, targetHeight_, GL_RGBA, GL_FLOAT, rows.data());
        glBindFramebuffer(GL_READ_FRAMEBUFFER, 0);
        const size_t row = size_t(targetWidth_) * 4;
        for (int y = 0; y < targetHeight_; ++y)  // OpenGL rows count from the bottom
            std::memcpy(&image.pixels[size_t(y) * row], &rows[size_t(targetHeight_ - 1 - y) * row],
                        row * sizeof(float));
        writeExr(path, image);
        return;
    }
    glBindFramebuffer(GL_READ_FRAMEBUFFER, offscreenFbo_);
    glReadBuffer(GL_COLOR_ATTACHMENT0);
    writeDisplayPng(path, targetWidth_, targetHeight_);
}

void SceneGl::writeWindowScreenshot(const std::string& path, int width, int height) {
    const fs::path parent = fs::path(path).parent_path();
    if (!parent.empty()) fs::create_directories(parent);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, 0);
    glReadBuffer(GL_BACK);
    writeDisplayPng(path, width, height);
}

void SceneGl::writeDisplayPng(const std::string& path, int width, int height) {
    std::vector<unsigned char> bytes(size_t(width) * size_t(height) * 4);
    glReadPixels(0, 0, width, height, GL_RGBA, GL_UNSIGNED_BYTE, bytes.data());
    glBindFramebuffer(GL_READ_FRAMEBUFFER, 0);
    checkGl("reading the framebuffer");
    // The bytes are sRGB-encoded already; writePng encodes linear values, and
    // linearToSrgb(srgbToLinear(q / 255)) rounds back to q exactly.
    float decode[256];
    for (int q = 0; q < 256; ++q) decode[q] = srgbToLinear(float(q) / 255.0f);
    Image image(width, height, 3);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            const unsigned char* src = &bytes[(size_t(height - 1 - y) * size_t(width) + size_t(x)) * 4];
            float* dst = image.pixel(x, y);
            for (int c = 0; c < 3; ++c) dst[c] = decode[src[c]];
        }
    writePng(path, image, 0.0);
}

}  // namespace prt
