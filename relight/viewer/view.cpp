// prt-relight view: see view.h and docs/viewer.md.
//
// Frame structure (a visibility buffer, then one shading pass), at the camera's width
// x height so the image is the offline renderer's pixel for pixel:
//   1. geometry pass, only when the camera moved: the mesh, drawn indexed, writes
//      gl_PrimitiveID + 1 (0 = nothing) into an R32UI target with a float depth buffer,
//      i.e. the triangle the pixel's ray hits first, as Embree's primary ray does;
//   2. shading pass, one full-screen triangle, every frame: a pixel with a triangle
//      fetches the triangle's vertex indices and positions from textures, intersects
//      the pixel's ray with it (Moller-Trumbore: the barycentrics Embree reports),
//      interpolates the vertex normals and the relit radiance of the three vertices with
//      them and applies F_t, the view-map terms and the optional specular layer:
//      TranslucentShader::shade's formula term for term, for any number of terms K. A
//      pixel without one shows the lat-long environment along its ray. Each pixel is
//      shaded exactly once, whatever the depth complexity; when only the light changes
//      (relighting, exposure, toggles) the frame is this one pass.
// The shading pass tone-maps (writePng's 2^exposure, clamp and exact sRGB encoding)
// into output 0 and writes the linear radiance (alpha 1 on the object, 0 behind) to
// output 1. Normally it draws straight into the window (output 1 is dropped) and the
// ImGui panel goes on top. For screenshots, or when the window's framebuffer is not
// the camera's size, it draws into an offscreen framebuffer (RGBA8 + RGBA32F) that is
// read back (PNG from the RGBA8 target, EXR from the float one) and blitted to the
// window. All float textures are RGBA32F (the fast texel-fetch path of software
// rasterisers such as llvmpipe).
//
// The shaders are in relight/viewer/shaders/, embedded at build time (shaders/embed.cmake) as
// prt::shaders::k<Name>: fullscreen.vert draws the full-screen triangle,
// visibility.vert/.frag the geometry pass, shade_common.glsl + shade.frag the shading
// pass. Every function of the last two ports one of common/ exactly (float instead of
// double): rayDirection = cameraRayDirection at the pixel centre, latLongRadiance =
// environmentRadiance, fresnelReflectance / refractDirection = bssrdf.cpp, faceUV =
// directionToFaceUV, viewMap = Cubemap::sampleBilinear, encodeSrgb = writePng's clamp
// + linearToSrgb. The GL helpers are in relight/viewer/gl_util.h, the relight worker (light
// vector + relight kernel off the UI thread) in relight/viewer/relight_worker.h.

#include "relight/viewer/view.h"

#define GLFW_INCLUDE_NONE
#include <GL/glew.h>
#include <GLFW/glfw3.h>
#include <glm/gtc/matrix_transform.hpp>
#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>
#include <imgui.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <iterator>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "common/envmap.h"
#include "common/error.h"
#include "relight/viewer/gl_util.h"
#include "relight/prt/light_vector.h"
#include "relight/viewer/point_light_worker.h"
#include "relight/viewer/relight_worker.h"
#include "relight/viewer/shaders/shaders.h"
#include "common/progress.h"
#include "common/util.h"

#ifndef PRT_SOURCE_DIR
#define PRT_SOURCE_DIR "."
#endif

namespace prt {

namespace fs = std::filesystem;

namespace {

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

double wrapDegrees(double d) {
    d = std::fmod(d, 360.0);
    if (d > 180.0) d -= 360.0;
    if (d <= -180.0) d += 360.0;
    return d;
}

std::string lowerExtension(const fs::path& p) {
    return toLower(p.extension().string());
}

// ---------------------------------------------------------------------------
// GLFW errors: the last message, for clear exceptions
// ---------------------------------------------------------------------------

std::mutex glfwErrorMutex;
std::string glfwLastError;

void glfwErrorCallback(int code, const char* description) {
    std::lock_guard<std::mutex> lock(glfwErrorMutex);
    glfwLastError = description ? description : ("GLFW error " + std::to_string(code));
}

std::string takeGlfwError() {
    std::lock_guard<std::mutex> lock(glfwErrorMutex);
    std::string e = glfwLastError.empty() ? "no reason given" : glfwLastError;
    glfwLastError.clear();
    return e;
}

// ---------------------------------------------------------------------------
// Statistics
// ---------------------------------------------------------------------------

struct RunningStats {
    size_t count = 0;
    double sum = 0.0, min = 0.0, max = 0.0;
    void add(double v) {
        min = count ? std::min(min, v) : v;
        max = count ? std::max(max, v) : v;
        sum += v;
        ++count;
    }
    double mean() const { return count ? sum / double(count) : 0.0; }
};

// ---------------------------------------------------------------------------
// The viewer
// ---------------------------------------------------------------------------

struct GlfwSession {
    GlfwSession() {
        glfwSetErrorCallback(glfwErrorCallback);
        if (!glfwInit())
            throw Error("display", "cannot open a window: " + takeGlfwError() +
                                       " (no X11/Wayland display? Set DISPLAY, or run under xvfb-run -a)");
    }
    ~GlfwSession() { glfwTerminate(); }
};

class Viewer {
public:
    explicit Viewer(ViewerSetup setup) : s_(std::move(setup)) {}
    ~Viewer();
    int run();

private:
    void loadEnvironments();
    void createWindow();
    void createResources();
    void createTargets(int width, int height);
    void destroyTargets();
    GLuint environmentTexture(int index, bool prefiltered);
    // Uploads the environment's per-vertex radiance (if on) plus the point lights' (if
    // on) to the back radiance texture and swaps it in.
    void uploadCombined();
    PointLightRequest currentPointRequest() const;
    void drawPointLightPanel();
    void drawLightMarkers();
    void handleInput();
    void handleKey(int key, int mods);
    void renderScene(bool offscreen);
    void drawPanel();
    // Reads the offscreen targets (the frame must have been rendered offscreen) or,
    // withPanel, the window's back buffer.
    void writeScreenshot(const std::string& path, bool withPanel);
    void screenshotKey() { screenshotRequested_ = true; }
    void writeKeyScreenshot();
    std::string renderCommand() const;
    LightRequest currentRequest() const;
    void printSummary(double seconds) const;

    static void keyCallback(GLFWwindow* w, int key, int scancode, int action, int mods);
    static void scrollCallback(GLFWwindow* w, double dx, double dy);
    static void framebufferSizeCallback(GLFWwindow* w, int width, int height);

    ViewerSetup s_;
    std::vector<Image> environments_;
    std::vector<std::string> environmentNames_;
    std::vector<Image> prefiltered_;  // per environment, made on first use
    bool hasMs_ = false, hasSs_ = false;
    int fileTerms_ = 0;  // K of the file's view maps

    // UI state (what the user asks for).
    Camera camera_;
    int environment_ = 0;
    double rotation_ = 0.0;
    float exposure_ = 0.0f;
    int lightTerms_ = 0;
    bool ms_ = true, ss_ = true, specular_ = false, showPanel_ = true;

    // Lighting on screen (the last result uploaded) and requests.
    std::unique_ptr<RelightWorker> worker_;
    LightResult front_;
    bool haveLight_ = false;
    LightRequest displayed_, submitted_;
    uint64_t nextId_ = 1;
    int displayedTerms_ = 0;
    double lastUploadMs_ = 0.0;
    RunningStats relightStats_, lightStats_, kernelStats_, uploadStats_;

    // Point lights (texture-space importance sampling).
    std::unique_ptr<PointLightWorker> pointWorker_;
    PointLightResult pointFront_;
    bool havePoint_ = false, envOn_ = true, pointOn_ = true;
    PointLightRequest pointSubmitted_, pointDisplayed_;
    uint64_t nextPointId_ = 1;
    std::vector<Light> lights_;
    int splitMode_ = int(TextureSpaceMode::Hybrid), pointSamples_ = 900;
    bool comparing_ = false;
    std::string comparison_, pointStatus_;
    RunningStats pointStats_;
    bool uploadDirty_ = false, uploadedEnvOn_ = true, uploadedPointOn_ = true;
    std::vector<glm::vec4> combined_;

    // GLFW / GL.
    std::unique_ptr<GlfwSession> glfw_;
    GLFWwindow* window_ = nullptr;
    bool imgui_ = false;
    GLuint vao_ = 0, visibilityProgram_ = 0, shadeProgram_ = 0;
    GLuint meshVao_ = 0, meshBuffers_[2] = {0, 0};
    GLuint positions_ = 0, normals_ = 0, triangles_ = 0, radiance_[2] = {0, 0}, viewMaps_ = 0, dummy_ = 0;
    int radianceFront_ = 0;
    std::vector<GLuint> envTextures_, prefilteredTextures_;
    GLuint offscreenFbo_ = 0, displayColor_ = 0, linearColor_ = 0;
    GLuint visibilityFbo_ = 0, visibility_ = 0, depth_ = 0;
    bool visibilityValid_ = false;
    Camera visibilityCamera_;  // the camera the visibility buffer was drawn with
    int targetWidth_ = 0, targetHeight_ = 0;
    int rowWidth_ = 4096, slotRows_ = 0, viewMapSize_ = 0;
    std::string glVersion_, glRenderer_;

    // Input.
    enum class Drag { None, Orbit, Pan, Environment } drag_ = Drag::None;
    double lastX_ = 0.0, lastY_ = 0.0, scroll_ = 0.0;
    std::vector<std::pair<int, int>> keys_;  // key, mods
    bool pendingResize_ = false;
    int resizeWidth_ = 0, resizeHeight_ = 0;
    int screenshotCounter_ = 0;
    bool screenshotRequested_ = false;
    std::string status_;

    // Frame timing.
    double fps_ = 0.0, frameMs_ = 0.0;
    double relightRate_ = 0.0;  // completed relights per second over the last window
    RunningStats stillFrames_, busyFrames_;
};

Viewer::~Viewer() {
    worker_.reset();
    pointWorker_.reset();
    if (window_) {
        glfwMakeContextCurrent(window_);
        if (imgui_) {
            ImGui_ImplOpenGL3_Shutdown();
            ImGui_ImplGlfw_Shutdown();
            ImGui::DestroyContext();
        }
        destroyTargets();
        GLuint textures[] = {positions_, normals_, triangles_, radiance_[0], radiance_[1], viewMaps_, dummy_};
        glDeleteTextures(GLsizei(std::size(textures)), textures);
        if (!envTextures_.empty()) glDeleteTextures(GLsizei(envTextures_.size()), envTextures_.data());
        if (!prefilteredTextures_.empty())
            glDeleteTextures(GLsizei(prefilteredTextures_.size()), prefilteredTextures_.data());
        glDeleteProgram(visibilityProgram_);
        glDeleteProgram(shadeProgram_);
        glDeleteVertexArrays(1, &vao_);
        glDeleteVertexArrays(1, &meshVao_);
        glDeleteBuffers(2, meshBuffers_);
        glfwDestroyWindow(window_);
    }
}

void Viewer::loadEnvironments() {
    const auto t0 = Clock::now();
    environments_.resize(s_.environments.size());
    // OpenImageIO reads are thread-safe; the maps are independent.
    tbb::parallel_for(size_t(0), s_.environments.size(), [&](size_t i) {
        environments_[i] = loadEnvironment(s_.environments[i], NonFinitePolicy::ClampNegative);
    });
    for (const std::string& p : s_.environments) environmentNames_.push_back(fs::path(p).stem().string());
    prefiltered_.resize(environments_.size());
    std::printf("environments: %zu loaded in %.0f ms (", environments_.size(), msSince(t0));
    for (size_t i = 0; i < environments_.size(); ++i)
        std::printf("%s%s %dx%d", i ? ", " : "", environmentNames_[i].c_str(), environments_[i].width,
                    environments_[i].height);
    std::printf(")\n");
    std::fflush(stdout);
}

void Viewer::createWindow() {
    glfw_ = std::make_unique<GlfwSession>();
    glfwDefaultWindowHints();
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
    glfwWindowHint(GLFW_DEPTH_BITS, 0);  // depth only in the visibility pass (offscreen)
    glfwWindowHint(GLFW_SRGB_CAPABLE, GLFW_FALSE);
    const std::string title = "prt-relight view - " + fs::path(s_.meshPath).filename().string();
    window_ = glfwCreateWindow(s_.camera.width, s_.camera.height, title.c_str(), nullptr, nullptr);
    if (!window_)
        throw Error("OpenGL", "cannot create a window with an OpenGL 3.3 core context: " + takeGlfwError() +
                                  " (the viewer needs OpenGL 3.3 core or newer; under Xvfb Mesa's llvmpipe "
                                  "provides 4.5)");
    glfwMakeContextCurrent(window_);
    glewExperimental = GL_TRUE;
    const GLenum glewStatus = glewInit();
    // GLEW_ERROR_NO_GLX_DISPLAY: GLEW could not query GLX (EGL or Wayland contexts); the
    // core GL entry points are loaded before that check, so carry on.
#ifdef GLEW_ERROR_NO_GLX_DISPLAY
    const bool glewOk = glewStatus == GLEW_OK || glewStatus == GLEW_ERROR_NO_GLX_DISPLAY;
#else
    const bool glewOk = glewStatus == GLEW_OK;
#endif
    if (!glewOk)
        throw Error("OpenGL", std::string("GLEW cannot load the OpenGL functions: ") +
                                  reinterpret_cast<const char*>(glewGetErrorString(glewStatus)));
    while (glGetError() != GL_NO_ERROR) {
    }  // glewInit may leave GL_INVALID_ENUM in core profiles
    GLint major = 0, minor = 0;
    glGetIntegerv(GL_MAJOR_VERSION, &major);
    glGetIntegerv(GL_MINOR_VERSION, &minor);
    const char* version = reinterpret_cast<const char*>(glGetString(GL_VERSION));
    const char* renderer = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
    glVersion_ = version ? version : "?";
    glRenderer_ = renderer ? renderer : "?";
    if (major < 3 || (major == 3 && minor < 3))
        throw Error("OpenGL", "version " + glVersion_ + " is too old: the viewer needs 3.3 core or newer");
    std::printf("OpenGL %s, %s\n", glVersion_.c_str(), glRenderer_.c_str());
    std::fflush(stdout);
    glfwSwapInterval(s_.vsync ? 1 : 0);
    glfwSetWindowUserPointer(window_, this);
    // Installed before ImGui's, which chains to them.
    glfwSetKeyCallback(window_, keyCallback);
    glfwSetScrollCallback(window_, scrollCallback);
    glfwSetFramebufferSizeCallback(window_, framebufferSizeCallback);

    IMGUI_CHECKVERSION();
    ImGui::CreateContext();
    ImGui::GetIO().IniFilename = nullptr;  // no imgui.ini in the working directory
    ImGui::StyleColorsDark();
    if (!ImGui_ImplGlfw_InitForOpenGL(window_, true) || !ImGui_ImplOpenGL3_Init("#version 330 core"))
        throw Error("OpenGL", "cannot initialise the ImGui backends");
    imgui_ = true;
}

void Viewer::createResources() {
    const TriangleMesh& mesh = s_.object.mesh;
    const size_t V = mesh.vertexCount(), T = mesh.triangleCount();
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
        const ViewMaps& maps = *s_.object.transport.viewMaps;
        viewMapSize_ = maps.size;
        if (size_t(6) * maps.size * fileTerms_ > size_t(maxSize))
            throw Error("OpenGL", "view maps too large for this OpenGL's textures");
        viewMaps_ = makeTexture(GL_R32F, maps.size, 6 * maps.size * fileTerms_, GL_RED, GL_FLOAT, maps.data.data());
    }
    const float zero[4] = {0, 0, 0, 0};
    dummy_ = makeTexture(GL_RGBA32F, 1, 1, GL_RGBA, GL_FLOAT, zero);
    envTextures_.assign(environments_.size(), 0);
    prefilteredTextures_.assign(environments_.size(), 0);

    glGenVertexArrays(1, &vao_);
    visibilityProgram_ = linkProgram({shaders::kVisibilityVert}, {shaders::kVisibilityFrag}, "visibility");
    shadeProgram_ = linkProgram({shaders::kFullscreenVert}, {shaders::kShadeCommon, shaders::kShadeFrag}, "shading");
    checkGl("creating the mesh buffers, textures and shaders");
    createTargets(s_.camera.width, s_.camera.height);
}

void Viewer::createTargets(int width, int height) {
    destroyTargets();
    targetWidth_ = width;
    targetHeight_ = height;
    visibility_ = makeTexture(GL_R32UI, width, height, GL_RED_INTEGER, GL_UNSIGNED_INT, nullptr);
    glGenRenderbuffers(1, &depth_);
    glBindRenderbuffer(GL_RENDERBUFFER, depth_);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT32F, width, height);
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
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    checkGl("creating the framebuffers");
}

void Viewer::destroyTargets() {
    if (offscreenFbo_) glDeleteFramebuffers(1, &offscreenFbo_);
    if (visibilityFbo_) glDeleteFramebuffers(1, &visibilityFbo_);
    if (depth_) glDeleteRenderbuffers(1, &depth_);
    GLuint t[] = {displayColor_, linearColor_, visibility_};
    glDeleteTextures(3, t);
    offscreenFbo_ = visibilityFbo_ = depth_ = displayColor_ = linearColor_ = visibility_ = 0;
    visibilityValid_ = false;
}

GLuint Viewer::environmentTexture(int index, bool prefiltered) {
    std::vector<GLuint>& cache = prefiltered ? prefilteredTextures_ : envTextures_;
    GLuint& t = cache[size_t(index)];
    if (t) return t;
    const Image* image = &environments_[size_t(index)];
    if (prefiltered) {
        Image& p = prefiltered_[size_t(index)];
        if (p.empty()) p = prefilterEnvironment(*image, specularBlurFactor(s_.specularBlur, *image));
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

void Viewer::uploadCombined() {
    const auto t0 = Clock::now();
    const int back = 1 - radianceFront_;
    const size_t V = s_.object.mesh.vertexCount();
    const bool env = envOn_ && haveLight_;
    const bool point = pointOn_ && havePoint_ && pointFront_.radiance.size() == V;
    const int envSlots = haveLight_ ? std::min(1 + fileTerms_, int(front_.packed.size() / std::max<size_t>(V, 1))) : 1;
    const int slots = std::max(envSlots, 1);
    combined_.assign(size_t(slots) * V, glm::vec4(0.0f));
    if (env) std::copy(front_.packed.begin(), front_.packed.begin() + ptrdiff_t(size_t(slots) * V), combined_.begin());
    if (point)
        for (size_t v = 0; v < V; ++v) combined_[v] += glm::vec4(pointFront_.radiance[v], 0.0f);
    for (int k = 0; k < slots; ++k)
        uploadRows(radiance_[back], rowWidth_, k * slotRows_, V, GL_RGBA, GL_FLOAT, &combined_[size_t(k) * V].x, 4);
    radianceFront_ = back;
    displayedTerms_ = env ? std::max(slots - 1, 0) : 0;
    lastUploadMs_ = msSince(t0);
    checkGl("uploading relit radiance");
}

PointLightRequest Viewer::currentPointRequest() const {
    PointLightRequest r;
    if (pointOn_) r.lights = lights_;
    r.mode = TextureSpaceMode(splitMode_);
    r.samples = pointSamples_;
    r.seed = s_.tsis.seed;
    return r;
}

LightRequest Viewer::currentRequest() const {
    LightRequest r;
    r.environment = environment_;
    r.rotation = rotation_;
    r.lightTerms = size_t(std::max(lightTerms_, 0));
    r.multipleScattering = ms_ && hasMs_;
    r.singleScattering = ss_ && hasSs_;
    return r;
}

// ---------------------------------------------------------------------------
// Input
// ---------------------------------------------------------------------------

void Viewer::keyCallback(GLFWwindow* w, int key, int, int action, int mods) {
    auto* v = static_cast<Viewer*>(glfwGetWindowUserPointer(w));
    if (v && (action == GLFW_PRESS || action == GLFW_REPEAT)) v->keys_.emplace_back(key, mods);
}

void Viewer::scrollCallback(GLFWwindow* w, double, double dy) {
    auto* v = static_cast<Viewer*>(glfwGetWindowUserPointer(w));
    if (v) v->scroll_ += dy;
}

void Viewer::framebufferSizeCallback(GLFWwindow* w, int width, int height) {
    auto* v = static_cast<Viewer*>(glfwGetWindowUserPointer(w));
    if (!v) return;
    v->pendingResize_ = true;
    v->resizeWidth_ = width;
    v->resizeHeight_ = height;
}

void Viewer::handleKey(int key, int mods) {
    const bool shift = (mods & GLFW_MOD_SHIFT) != 0;
    const int count = int(environments_.size());
    switch (key) {
        case GLFW_KEY_ESCAPE:
        case GLFW_KEY_Q: glfwSetWindowShouldClose(window_, GLFW_TRUE); break;
        case GLFW_KEY_R: {
            const int w = camera_.width, h = camera_.height;
            camera_ = s_.camera;
            camera_.width = w;
            camera_.height = h;
            break;
        }
        case GLFW_KEY_LEFT: rotation_ = wrapDegrees(rotation_ - (shift ? 1.0 : 5.0)); break;
        case GLFW_KEY_RIGHT: rotation_ = wrapDegrees(rotation_ + (shift ? 1.0 : 5.0)); break;
        case GLFW_KEY_N:
        case GLFW_KEY_PAGE_DOWN: environment_ = (environment_ + 1) % count; break;
        case GLFW_KEY_B:
        case GLFW_KEY_PAGE_UP: environment_ = (environment_ + count - 1) % count; break;
        case GLFW_KEY_M: ms_ = !ms_; break;
        case GLFW_KEY_S: ss_ = !ss_; break;
        case GLFW_KEY_G: specular_ = !specular_; break;
        case GLFW_KEY_E: envOn_ = !envOn_; break;
        case GLFW_KEY_L: pointOn_ = !pointOn_; break;
        case GLFW_KEY_EQUAL:
        case GLFW_KEY_KP_ADD: exposure_ += 0.5f; break;
        case GLFW_KEY_MINUS:
        case GLFW_KEY_KP_SUBTRACT: exposure_ -= 0.5f; break;
        case GLFW_KEY_0: exposure_ = 0.0f; break;
        case GLFW_KEY_RIGHT_BRACKET:
            lightTerms_ = lightTerms_ == 0 ? 0 : std::min(lightTerms_ * 2, 6 * int(s_.object.transport.cubemapSize *
                                                                                   s_.object.transport.cubemapSize));
            break;
        case GLFW_KEY_LEFT_BRACKET:
            lightTerms_ = lightTerms_ == 0 ? 6 * int(s_.object.transport.cubemapSize * s_.object.transport.cubemapSize) / 2
                                           : std::max(1, lightTerms_ / 2);
            break;
        case GLFW_KEY_H:
        case GLFW_KEY_F1: showPanel_ = !showPanel_; break;
        case GLFW_KEY_P:
        case GLFW_KEY_F12: screenshotKey(); break;
        default: break;
    }
}

void Viewer::handleInput() {
    const ImGuiIO& io = ImGui::GetIO();
    std::vector<std::pair<int, int>> keys;
    keys.swap(keys_);
    if (!io.WantCaptureKeyboard)
        for (const auto& [key, mods] : keys) handleKey(key, mods);

    double x = 0.0, y = 0.0;
    glfwGetCursorPos(window_, &x, &y);
    double dx = x - lastX_, dy = y - lastY_;
    lastX_ = x;
    lastY_ = y;
    const bool left = glfwGetMouseButton(window_, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS;
    const bool right = glfwGetMouseButton(window_, GLFW_MOUSE_BUTTON_RIGHT) == GLFW_PRESS;
    const bool middle = glfwGetMouseButton(window_, GLFW_MOUSE_BUTTON_MIDDLE) == GLFW_PRESS;
    if (!left && !right && !middle) {
        drag_ = Drag::None;
    } else if (drag_ == Drag::None && !io.WantCaptureMouse) {
        const bool modifier = glfwGetKey(window_, GLFW_KEY_LEFT_SHIFT) == GLFW_PRESS ||
                              glfwGetKey(window_, GLFW_KEY_RIGHT_SHIFT) == GLFW_PRESS ||
                              glfwGetKey(window_, GLFW_KEY_LEFT_CONTROL) == GLFW_PRESS ||
                              glfwGetKey(window_, GLFW_KEY_RIGHT_CONTROL) == GLFW_PRESS;
        drag_ = left ? (modifier ? Drag::Environment : Drag::Orbit) : Drag::Pan;
        dx = dy = 0.0;  // motion before the press (since the last frame) is not part of the drag
    }

    const glm::dvec3 up = glm::normalize(camera_.up);
    glm::dvec3 offset = camera_.eye - camera_.target;
    double distance = glm::length(offset);
    if (drag_ == Drag::Orbit && (dx != 0.0 || dy != 0.0) && distance > 0) {
        // Azimuth about the up vector, polar angle from it kept in [1, 179] degrees.
        const double c = std::clamp(glm::dot(offset / distance, up), -1.0, 1.0);
        glm::dvec3 h = offset - glm::dot(offset, up) * up;
        if (glm::length(h) > 1e-12 * distance) {
            h = glm::normalize(h);
            const double theta = std::clamp(std::acos(c) - glm::radians(0.3 * dy), glm::radians(1.0),
                                            glm::radians(179.0));
            h = rotationAxisAngle(up, -0.3 * dx) * h;
            offset = distance * (std::cos(theta) * up + std::sin(theta) * h);
            camera_.eye = camera_.target + offset;
        }
    } else if (drag_ == Drag::Pan && (dx != 0.0 || dy != 0.0)) {
        const glm::dvec3 forward = glm::normalize(camera_.target - camera_.eye);
        const glm::dvec3 rightAxis = glm::normalize(glm::cross(forward, camera_.up));
        const glm::dvec3 upAxis = glm::cross(rightAxis, forward);
        const double perPixel = 2.0 * distance * std::tan(glm::radians(camera_.fovY) * 0.5) / camera_.height;
        const glm::dvec3 move = (-dx * rightAxis + dy * upAxis) * perPixel;
        camera_.eye += move;
        camera_.target += move;
    } else if (drag_ == Drag::Environment && dx != 0.0) {
        rotation_ = wrapDegrees(rotation_ + 0.5 * dx);
    }
    if (scroll_ != 0.0 && !io.WantCaptureMouse && distance > 0) {
        distance = std::max(distance * std::pow(0.9, scroll_), 1e-3 * std::max(s_.object.sphereRadius, 1e-6));
        camera_.eye = camera_.target + distance * glm::normalize(offset);
    }
    scroll_ = 0.0;
}

// ---------------------------------------------------------------------------
// Drawing
// ---------------------------------------------------------------------------

bool sameCamera(const Camera& a, const Camera& b) {
    return a.eye == b.eye && a.target == b.target && a.up == b.up && a.fovY == b.fovY && a.width == b.width &&
           a.height == b.height;
}

void Viewer::renderScene(bool offscreen) {
    const Camera& c = camera_;
    const glm::dvec3 forward = glm::normalize(c.target - c.eye);
    const glm::dvec3 right = glm::normalize(glm::cross(forward, c.up));
    const glm::dvec3 up = glm::cross(right, forward);
    const double tanHalf = std::tan(glm::radians(c.fovY) * 0.5);
    const glm::dmat3 rotation = rotationY(haveLight_ ? displayed_.rotation : rotation_);
    const glm::mat3 rotationT(glm::transpose(rotation));
    const int env = haveLight_ ? displayed_.environment : environment_;

    glBindVertexArray(vao_);
    glDisable(GL_BLEND);
    glDisable(GL_CULL_FACE);
    glDisable(GL_SCISSOR_TEST);
    glColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    glViewport(0, 0, c.width, c.height);

    // 1. Visibility, when the camera changed. No back-face culling: the offline
    // renderer's rays hit back faces (through holes; black there, n . w_o <= 0), and a
    // front face seen at a grazing angle can come out back-facing in float.
    if (!visibilityValid_ || !sameCamera(c, visibilityCamera_)) {
        // Depth range around the bounding sphere (the planes must not clip the object).
        const double r = std::max(s_.object.sphereRadius, 1e-6);
        const double d = glm::length(s_.object.sphereCentre - c.eye);
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
        glDrawElements(GL_TRIANGLES, GLsizei(3 * s_.object.mesh.triangleCount()), GL_UNSIGNED_INT, nullptr);
        glBindVertexArray(vao_);
        glDisable(GL_DEPTH_TEST);
        visibilityCamera_ = c;
        visibilityValid_ = true;
    }

    // 2. Shading, one full-screen triangle.
    glBindFramebuffer(GL_FRAMEBUFFER, offscreen ? offscreenFbo_ : 0);
    const GLuint p = shadeProgram_;
    glUseProgram(p);
    glUniform3f(glGetUniformLocation(p, "uEye"), float(c.eye.x), float(c.eye.y), float(c.eye.z));
    glUniform3f(glGetUniformLocation(p, "uForward"), float(forward.x), float(forward.y), float(forward.z));
    glUniform3f(glGetUniformLocation(p, "uRight"), float(right.x), float(right.y), float(right.z));
    glUniform3f(glGetUniformLocation(p, "uUp"), float(up.x), float(up.y), float(up.z));
    glUniform1f(glGetUniformLocation(p, "uTanHalf"), float(tanHalf));
    glUniform2f(glGetUniformLocation(p, "uViewSize"), float(c.width), float(c.height));
    glUniformMatrix3fv(glGetUniformLocation(p, "uEnvRotationT"), 1, GL_FALSE, &rotationT[0][0]);
    glUniform1f(glGetUniformLocation(p, "uScale"), float(std::exp2(double(exposure_))));
    glUniform1i(glGetUniformLocation(p, "uRowWidth"), rowWidth_);
    glUniform1i(glGetUniformLocation(p, "uSlotRows"), slotRows_);
    glUniform1i(glGetUniformLocation(p, "uTermCount"), haveLight_ ? displayedTerms_ : 0);
    glUniform1i(glGetUniformLocation(p, "uViewMapSize"), std::max(viewMapSize_, 1));
    glUniform1f(glGetUniformLocation(p, "uEta"), float(s_.object.eta));
    glUniform1i(glGetUniformLocation(p, "uSpecular"), specular_ && envOn_ ? 1 : 0);
    glUniform1i(glGetUniformLocation(p, "uBackground"), envOn_ ? 1 : 0);
    const std::pair<const char*, GLuint> textures[] = {
        {"uVisibility", visibility_},
        {"uEnvironment", environmentTexture(env, false)},
        {"uPositions", positions_},
        {"uNormals", normals_},
        {"uTriangles", triangles_},
        {"uRadiance", radiance_[radianceFront_]},
        {"uViewMaps", viewMaps_ ? viewMaps_ : dummy_},
        {"uPrefiltered", specular_ ? environmentTexture(env, true) : dummy_},
    };
    for (int unit = 0; unit < int(std::size(textures)); ++unit) {
        glActiveTexture(GLenum(GL_TEXTURE0 + unit));
        glBindTexture(GL_TEXTURE_2D, textures[unit].second);
        glUniform1i(glGetUniformLocation(p, textures[unit].first), unit);
    }
    glDrawArrays(GL_TRIANGLES, 0, 3);

    glActiveTexture(GL_TEXTURE0);
    glBindVertexArray(0);
    glUseProgram(0);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
}

std::string Viewer::renderCommand() const {
    const Camera& c = camera_;
    const auto vec = [](const glm::dvec3& v) {
        char buf[128];
        std::snprintf(buf, sizeof buf, "%.9g,%.9g,%.9g", v.x, v.y, v.z);
        return std::string(buf);
    };
    char buf[256];
    std::string cmd = "prt-relight render " + s_.meshPath + " -t " + s_.transportPath + " -e " +
                      s_.environments[size_t(environment_)] + " --eye=" + vec(c.eye) + " --target=" +
                      vec(c.target) + " --up=" + vec(c.up);
    std::snprintf(buf, sizeof buf, " --fov %.9g -W %d -H %d --env-rotation=%.9g --exposure=%.9g", c.fovY, c.width,
                  c.height, rotation_, double(exposure_));
    cmd += buf;
    if (lightTerms_ > 0) cmd += " -L " + std::to_string(lightTerms_);
    const LightRequest r = currentRequest();
    if (r.multipleScattering != hasMs_ || r.singleScattering != hasSs_)
        cmd += std::string(" --components ") + (r.multipleScattering && r.singleScattering ? "ms,ss"
                                                : r.multipleScattering                      ? "ms"
                                                                                            : "ss");
    if (specular_) {
        cmd += " --specular";
        if (s_.specularBlur > 0) cmd += " --specular-blur " + std::to_string(s_.specularBlur);
    }
    return cmd + " -o OUT";
}

void Viewer::drawPointLightPanel() {
    ImGui::Separator();
    ImGui::Checkbox("environment light (E)", &envOn_);
    if (!pointWorker_) {
        ImGui::TextDisabled("point lights: the transport file names no material");
        return;
    }
    ImGui::SameLine();
    ImGui::Checkbox("point lights (L)", &pointOn_);
    if (!ImGui::CollapsingHeader("point lights (Chang et al. 2008)", ImGuiTreeNodeFlags_DefaultOpen)) return;
    static const char* kModes[] = {"sampling", "hybrid", "local", "global"};  // TextureSpaceMode order
    ImGui::Combo("R_d by", &splitMode_, kModes, int(std::size(kModes)));
    ImGui::SliderInt("samples N", &pointSamples_, 16, 20000, "%d", ImGuiSliderFlags_Logarithmic);
    const float radius = float(std::max(s_.object.sphereRadius, 1e-3));
    int remove = -1;
    for (int i = 0; i < int(lights_.size()); ++i) {
        Light& l = lights_[size_t(i)];
        ImGui::PushID(i);
        ImGui::Text("light %d (%s)", i + 1, l.type == LightType::Point ? "point, W/sr" : "directional, W/m^2");
        if (l.type == LightType::Point) {
            float p[3] = {float(l.position.x), float(l.position.y), float(l.position.z)};
            if (ImGui::DragFloat3("position (mm)", p, 0.01f * radius, 0.0f, 0.0f, "%.2f"))
                l.position = glm::dvec3(p[0], p[1], p[2]);
        } else {
            float d[3] = {float(l.direction.x), float(l.direction.y), float(l.direction.z)};
            if (ImGui::DragFloat3("toward", d, 0.01f, -1.0f, 1.0f, "%.3f")) {
                const glm::dvec3 v(d[0], d[1], d[2]);
                if (glm::length(v) > 1e-6) l.direction = glm::normalize(v);
            }
        }
        const double peak = std::max({l.rgb.x, l.rgb.y, l.rgb.z});
        float colour[3] = {1.0f, 1.0f, 1.0f};
        if (peak > 0.0)
            for (int c = 0; c < 3; ++c) colour[c] = float(l.rgb[c] / peak);
        float power = float(peak);
        bool changed = ImGui::ColorEdit3("colour", colour, ImGuiColorEditFlags_NoInputs);
        ImGui::SameLine();
        ImGui::SetNextItemWidth(110.0f);
        changed |= ImGui::DragFloat("intensity", &power, std::max(0.01f * power, 1e-6f), 0.0f, 1e9f, "%.4g",
                                    ImGuiSliderFlags_Logarithmic);
        if (changed && std::isfinite(power))
            l.rgb = glm::dvec3(colour[0], colour[1], colour[2]) * double(std::max(power, 0.0f));
        ImGui::SameLine();
        if (ImGui::SmallButton("remove")) remove = i;
        ImGui::PopID();
    }
    if (remove >= 0) lights_.erase(lights_.begin() + remove);
    if (ImGui::Button("add point light")) {
        // Above the camera's side of the object, 3 radii out, giving ~100 W/m^2 at the centre.
        const glm::dvec3 c = s_.object.sphereCentre;
        const glm::dvec3 dir = glm::normalize(glm::normalize(camera_.eye - c) + glm::dvec3(camera_.up));
        const double d = 3.0 * double(radius);
        lights_.push_back(pointLight(c + d * dir, glm::dvec3(100.0 * d * d / kSquareMmPerSquareMetre), "viewer"));
    }
    if (havePoint_) {
        const PointLightResult& r = pointFront_;
        if (!r.message.empty()) ImGui::TextColored(ImVec4(1.0f, 0.5f, 0.3f, 1.0f), "%s", r.message.c_str());
        const TextureSpaceTimings& t = r.timings;
        ImGui::Text("last update %.1f ms: irradiance %.1f, shadow maps %.1f, draws %.1f, sums %.1f", r.totalMs,
                    1e3 * t.irradianceSeconds, 1e3 * t.shadowMapSeconds, 1e3 * t.samplingSeconds, r.evaluationMs);
        ImGui::Text("%zu updates, mean %.1f ms; %zu distinct samples, R_p %.3g mm", pointStats_.count,
                    pointStats_.mean(), r.uniqueSamples, r.rp);
    }
    ImGui::BeginDisabled(comparing_ || lights_.empty() || !pointOn_);
    if (ImGui::Button("RMSE vs Jensen-Buhler")) {
        pointWorker_->compare(camera_, double(exposure_));
        comparing_ = true;
        comparison_ = "rendering the reference ...";
    }
    ImGui::EndDisabled();
    if (!comparison_.empty()) ImGui::TextWrapped("%s", comparison_.c_str());
    const std::string atlas = pointWorker_->atlasSummary();
    ImGui::TextDisabled("%s", atlas.empty() ? "surface atlas: built with the first light" : atlas.c_str());
}

void Viewer::drawLightMarkers() {
    if (!pointWorker_ || !pointOn_) return;
    const Camera& c = camera_;
    const glm::dvec3 forward = glm::normalize(c.target - c.eye);
    const glm::dvec3 right = glm::normalize(glm::cross(forward, c.up));
    const glm::dvec3 up = glm::cross(right, forward);
    const double tanHalf = std::tan(glm::radians(c.fovY) * 0.5), aspect = double(c.width) / c.height;
    const ImVec2 size = ImGui::GetIO().DisplaySize;
    ImDrawList* draw = ImGui::GetBackgroundDrawList();
    for (size_t i = 0; i < lights_.size(); ++i) {
        const Light& l = lights_[i];
        if (l.type != LightType::Point) continue;
        const glm::dvec3 d = l.position - c.eye;
        const double z = glm::dot(d, forward);
        if (!(z > 0.0)) continue;
        const double sx = glm::dot(d, right) / z / (tanHalf * aspect), sy = glm::dot(d, up) / z / tanHalf;
        const ImVec2 p(float((sx + 1.0) * 0.5 * size.x), float((1.0 - sy) * 0.5 * size.y));
        const double peak = std::max({l.rgb.x, l.rgb.y, l.rgb.z, 1e-30});
        const ImU32 colour = ImGui::ColorConvertFloat4ToU32(
            ImVec4(float(l.rgb.x / peak), float(l.rgb.y / peak), float(l.rgb.z / peak), 1.0f));
        draw->AddCircleFilled(p, 6.0f, colour);
        draw->AddCircle(p, 7.0f, IM_COL32(0, 0, 0, 255), 0, 1.5f);
        draw->AddText(ImVec2(p.x + 9.0f, p.y - 7.0f), IM_COL32(255, 255, 255, 255), std::to_string(i + 1).c_str());
    }
}

void Viewer::drawPanel() {
    ImGui::SetNextWindowPos(ImVec2(8, 8), ImGuiCond_FirstUseEver);
    ImGui::SetNextWindowBgAlpha(0.75f);
    ImGui::Begin("prt-relight view", &showPanel_, ImGuiWindowFlags_AlwaysAutoResize);
    ImGui::PushItemWidth(170.0f);
    const TriangleMesh& mesh = s_.object.mesh;
    const TransportFile& file = s_.object.transport;
    ImGui::Text("%s: %zu vertices, %.3g mm", fs::path(s_.meshPath).filename().string().c_str(), mesh.vertexCount(),
                double(s_.object.box.diagonal()));
    ImGui::TextDisabled("eta %.3g, cubemap 6x%ux%u%s", s_.object.eta, file.cubemapSize, file.cubemapSize,
                        fileTerms_ > 0 ? (", K = " + std::to_string(fileTerms_) + " view terms").c_str() : "");

    ImGui::Separator();
    const char* current = environmentNames_[size_t(environment_)].c_str();
    if (ImGui::BeginCombo("environment (N/B)", current)) {
        for (int i = 0; i < int(environments_.size()); ++i)
            if (ImGui::Selectable(environmentNames_[size_t(i)].c_str(), i == environment_)) environment_ = i;
        ImGui::EndCombo();
    }
    float rotation = float(rotation_);
    if (ImGui::SliderFloat("rotation (deg)", &rotation, -180.0f, 180.0f, "%.1f")) rotation_ = double(rotation);
    ImGui::BeginDisabled(!hasMs_);
    ImGui::Checkbox("MS (M)", &ms_);
    ImGui::EndDisabled();
    ImGui::SameLine();
    ImGui::BeginDisabled(!hasSs_);
    ImGui::Checkbox("SS (S)", &ss_);
    ImGui::EndDisabled();
    ImGui::SameLine();
    ImGui::Checkbox("specular (G)", &specular_);
    ImGui::SliderFloat("exposure (+/-)", &exposure_, -10.0f, 10.0f, "%.2f stops");
    const int maxTerms = 6 * int(file.cubemapSize * file.cubemapSize);
    ImGui::SliderInt("light terms ([/])", &lightTerms_, 0, maxTerms, lightTerms_ == 0 ? "all" : "%d",
                     ImGuiSliderFlags_Logarithmic);
    if (haveLight_)
        ImGui::Text("light: %zu of %zu terms, L2 error %.3g", front_.keptTerms, front_.coefficients,
                    front_.relativeL2Error);

    ImGui::Separator();
    ImGui::Text("%.1f fps (%.1f ms), %d x %d", fps_, frameMs_, camera_.width, camera_.height);
    if (haveLight_)
        ImGui::Text("relight %.0f ms = light %.0f + kernel %.1f + upload %.1f",
                    front_.lightMs + front_.relightMs + lastUploadMs_, front_.lightMs, front_.relightMs,
                    lastUploadMs_);
    ImGui::Text("%zu relights (%.0f per second completed), mean %.0f ms%s", relightStats_.count,
                relightRate_, relightStats_.mean(), worker_->busy() ? ", relighting..." : "");
    ImGui::TextDisabled("%zu vertices, %zu triangles, %s", mesh.vertexCount(), mesh.triangleCount(),
                        glRenderer_.substr(0, glRenderer_.find(' ')).c_str());

    drawPointLightPanel();
    if (ImGui::CollapsingHeader("camera")) {
        ImGui::Text("eye (%.4g, %.4g, %.4g) mm", camera_.eye.x, camera_.eye.y, camera_.eye.z);
        ImGui::Text("target (%.4g, %.4g, %.4g), fov %.3g", camera_.target.x, camera_.target.y, camera_.target.z,
                    camera_.fovY);
        if (ImGui::Button("print render command")) {
            std::printf("%s\n", renderCommand().c_str());
            std::fflush(stdout);
        }
    }
    if (ImGui::CollapsingHeader("controls")) {
        ImGui::TextUnformatted(
            "left drag: orbit, right/middle drag: pan,\n"
            "wheel: zoom, R: reset camera\n"
            "shift/ctrl + left drag, arrows: rotate light\n"
            "N, B (PgDn, PgUp): next, previous environment\n"
            "M, S, G: multiple, single scattering, specular\n"
            "E, L: environment light, point lights\n"
            "+, -, 0: exposure; [, ]: light terms\n"
            "F12 or P: screenshot, H: panel, Esc: quit");
    }
    if (ImGui::Button("reset camera (R)")) handleKey(GLFW_KEY_R, 0);
    ImGui::SameLine();
    if (ImGui::Button("screenshot (F12)")) screenshotKey();
    if (!status_.empty()) ImGui::TextWrapped("%s", status_.c_str());
    ImGui::PopItemWidth();
    ImGui::End();
}

void Viewer::writeScreenshot(const std::string& path, bool withPanel) {
    const fs::path parent = fs::path(path).parent_path();
    if (!parent.empty()) fs::create_directories(parent);
    if (lowerExtension(path) == ".exr") {
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
    int width = targetWidth_, height = targetHeight_;
    if (withPanel) glfwGetFramebufferSize(window_, &width, &height);
    std::vector<unsigned char> bytes(size_t(width) * size_t(height) * 4);
    if (withPanel) {
        glBindFramebuffer(GL_READ_FRAMEBUFFER, 0);
        glReadBuffer(GL_BACK);
    } else {
        glBindFramebuffer(GL_READ_FRAMEBUFFER, offscreenFbo_);
        glReadBuffer(GL_COLOR_ATTACHMENT0);
    }
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

void Viewer::writeKeyScreenshot() {
    std::string base;
    do {
        char buf[64];
        std::snprintf(buf, sizeof buf, "prt-view-%03d", screenshotCounter_++);
        base = buf;
    } while (fs::exists(base + ".png") || fs::exists(base + ".exr"));
    try {
        writeScreenshot(base + ".png", false);
        writeScreenshot(base + ".exr", false);
        status_ = "wrote " + base + ".png and .exr";
        std::printf("screenshot: %s.png/.exr; same view offline:\n  %s\n", base.c_str(), renderCommand().c_str());
        std::fflush(stdout);
    } catch (const std::exception& e) {
        status_ = std::string("screenshot failed: ") + e.what();
        warn(status_);
    }
}

void Viewer::printSummary(double seconds) const {
    const size_t frames = stillFrames_.count + busyFrames_.count;
    std::printf("viewer: %zu frames in %.2f s at %d x %d", frames, seconds, camera_.width, camera_.height);
    if (stillFrames_.count)
        std::printf("; still light: %zu frames, %.1f fps (%.2f ms per frame)", stillFrames_.count,
                    1000.0 / stillFrames_.mean(), stillFrames_.mean());
    if (busyFrames_.count)
        std::printf("; while relighting: %zu frames, %.1f fps", busyFrames_.count, 1000.0 / busyFrames_.mean());
    std::printf("\n");
    if (relightStats_.count)
        std::printf("relights: %zu completed (%.1f per second), mean %.1f ms (light vector %.1f + kernel %.1f + "
                    "upload %.1f), min %.1f, max %.1f ms\n",
                    relightStats_.count, seconds > 0.0 ? double(relightStats_.count) / seconds : 0.0,
                    relightStats_.mean(), lightStats_.mean(), kernelStats_.mean(), uploadStats_.mean(),
                    relightStats_.min, relightStats_.max);
    if (pointStats_.count)
        std::printf("point-light updates: %zu, mean %.1f ms (irradiance map, shadow maps, draws and per-vertex sums; "
                    "last: %.1f ms, N = %d, %s), min %.1f, max %.1f ms\n",
                    pointStats_.count, pointStats_.mean(), pointFront_.totalMs, pointFront_.request.samples,
                    toString(pointFront_.request.mode), pointStats_.min, pointStats_.max);
    std::fflush(stdout);
}

int Viewer::run() {
    const TransportFile& file = s_.object.transport;
    hasMs_ = file.find(ComponentKind::MultipleScattering) != nullptr;
    hasSs_ = file.find(ComponentKind::SingleScatteringIsotropic) != nullptr;
    for (const TransportComponent& c : file.components)
        hasSs_ = hasSs_ || c.kind == ComponentKind::SingleScatteringTerm;
    fileTerms_ = file.viewMaps ? file.viewMaps->terms : 0;
    camera_ = s_.camera;
    rotation_ = wrapDegrees(s_.envRotation);
    exposure_ = float(s_.exposure);
    lightTerms_ = int(std::min<size_t>(s_.lightTerms, size_t(6) * file.cubemapSize * file.cubemapSize));
    ms_ = s_.components.multipleScattering;
    ss_ = s_.components.singleScattering;
    specular_ = s_.specular;
    showPanel_ = s_.showPanel;

    loadEnvironments();
    createWindow();
    createResources();
    worker_ = std::make_unique<RelightWorker>(file, environments_);
    envOn_ = s_.environmentLight;
    lights_ = s_.pointLights;
    splitMode_ = int(s_.tsis.mode);
    pointSamples_ = s_.tsis.samples;
    if (s_.material)
        pointWorker_ = std::make_unique<PointLightWorker>(s_.object.mesh, *s_.material, s_.tsis, s_.atlasSize);
    glfwGetCursorPos(window_, &lastX_, &lastY_);

    const bool scripted = s_.frames > 0;
    int framesAfterLight = 0, spinSteps = 0;
    bool screenshotsDone = false;
    const auto start = Clock::now();
    auto previousFrame = start;
    double fpsWindowStart = 0.0;
    int fpsWindowFrames = 0;
    size_t fpsWindowRelights = 0;  // relightStats_.count at the window's start

    while (!glfwWindowShouldClose(window_)) {
        glfwPollEvents();
        if (pendingResize_) {
            pendingResize_ = false;
            if (resizeWidth_ > 0 && resizeHeight_ > 0 &&
                (resizeWidth_ != camera_.width || resizeHeight_ != camera_.height)) {
                camera_.width = resizeWidth_;
                camera_.height = resizeHeight_;
                createTargets(camera_.width, camera_.height);
            }
        }
        int fbWidth = 0, fbHeight = 0;
        glfwGetFramebufferSize(window_, &fbWidth, &fbHeight);
        if (fbWidth <= 0 || fbHeight <= 0) {  // minimised
            glfwWaitEventsTimeout(0.1);
            continue;
        }

        ImGui_ImplOpenGL3_NewFrame();
        ImGui_ImplGlfw_NewFrame();
        ImGui::NewFrame();
        handleInput();

        const bool finishing = scripted && framesAfterLight >= s_.frames;
        // --spin: one step per frame once the first light is on screen; scripted runs
        // take exactly --frames steps (the final rotation is known).
        // --orbit likewise turns the camera about the up axis through the target.
        if ((s_.spinDegreesPerFrame != 0.0 || s_.orbitDegreesPerFrame != 0.0) && haveLight_ &&
            (!scripted || spinSteps < s_.frames)) {
            rotation_ = wrapDegrees(rotation_ + s_.spinDegreesPerFrame);
            if (s_.orbitDegreesPerFrame != 0.0)
                camera_.eye = camera_.target + rotationAxisAngle(camera_.up, s_.orbitDegreesPerFrame) *
                                                   (camera_.eye - camera_.target);
            ++spinSteps;
        }
        const LightRequest wanted = currentRequest();
        if (nextId_ == 1 || !wanted.sameLight(submitted_)) {
            submitted_ = wanted;
            submitted_.id = nextId_++;
            worker_->submit(submitted_);
        }
        const bool envLanded = worker_->take(front_);
        if (envLanded) {
            displayed_ = front_.request;
            haveLight_ = true;
            uploadDirty_ = true;
        }
        if (pointWorker_) {
            const PointLightRequest pw = currentPointRequest();
            if (nextPointId_ == 1 || !pw.sameAs(pointSubmitted_)) {
                pointSubmitted_ = pw;
                pointSubmitted_.id = nextPointId_++;
                pointWorker_->submit(pointSubmitted_);
            }
            if (pointWorker_->take(pointFront_)) {
                pointDisplayed_ = pointFront_.request;
                havePoint_ = true;
                uploadDirty_ = true;
                if (!pointFront_.request.lights.empty()) pointStats_.add(pointFront_.totalMs);
            }
            std::string text;
            if (pointWorker_->takeComparison(text)) {
                comparison_ = text;
                comparing_ = false;
            }
        }
        if (envOn_ != uploadedEnvOn_ || pointOn_ != uploadedPointOn_) uploadDirty_ = true;
        if (uploadDirty_ && (haveLight_ || havePoint_)) {
            uploadCombined();
            uploadDirty_ = false;
            uploadedEnvOn_ = envOn_;
            uploadedPointOn_ = pointOn_;
        }
        if (envLanded) {
            const double total = front_.lightMs + front_.relightMs + lastUploadMs_;
            relightStats_.add(total);
            lightStats_.add(front_.lightMs);
            kernelStats_.add(front_.relightMs);
            uploadStats_.add(lastUploadMs_);
        }
        const bool pointBusy = pointWorker_ && !comparing_ && pointWorker_->busy();
        const bool busy = worker_->busy() || pointBusy;
        // Scripted end: the frames are done and the light on screen is the last asked for.
        const bool lastFrame = finishing && !busy && displayed_.id == submitted_.id &&
                               (!pointWorker_ || (havePoint_ && pointDisplayed_.id == pointSubmitted_.id));
        const bool keyShot = screenshotRequested_;
        screenshotRequested_ = false;

        const bool direct = fbWidth == camera_.width && fbHeight == camera_.height;
        const bool offscreen = !direct || keyShot || (lastFrame && !s_.screenshots.empty());
        renderScene(offscreen);
        if (offscreen) {
            glBindFramebuffer(GL_READ_FRAMEBUFFER, offscreenFbo_);
            glReadBuffer(GL_COLOR_ATTACHMENT0);
            glBindFramebuffer(GL_DRAW_FRAMEBUFFER, 0);
            glViewport(0, 0, fbWidth, fbHeight);
            if (!direct) {
                glClearColor(0.0f, 0.0f, 0.0f, 1.0f);
                glClear(GL_COLOR_BUFFER_BIT);
            }
            glBlitFramebuffer(0, 0, targetWidth_, targetHeight_, 0, 0, fbWidth, fbHeight, GL_COLOR_BUFFER_BIT,
                              direct ? GL_NEAREST : GL_LINEAR);
            glBindFramebuffer(GL_FRAMEBUFFER, 0);
        }
        if (keyShot) writeKeyScreenshot();
        if (lastFrame)
            for (const std::string& path : s_.screenshots)
                if (!s_.screenshotWithPanel || lowerExtension(path) == ".exr") {
                    writeScreenshot(path, false);
                    std::printf("screenshot: %s\n", path.c_str());
                }

        glViewport(0, 0, fbWidth, fbHeight);
        if (showPanel_) {
            drawLightMarkers();
            drawPanel();
        }
        ImGui::Render();
        ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());

        if (lastFrame) {
            for (const std::string& path : s_.screenshots)
                if (s_.screenshotWithPanel && lowerExtension(path) != ".exr") {
                    writeScreenshot(path, true);
                    std::printf("screenshot: %s (with the panel)\n", path.c_str());
                }
            std::fflush(stdout);
            screenshotsDone = true;
            glfwSetWindowShouldClose(window_, GLFW_TRUE);
        }
        glfwSwapBuffers(window_);

        const auto now = Clock::now();
        const double frameMs = std::chrono::duration<double, std::milli>(now - previousFrame).count();
        previousFrame = now;
        if (haveLight_) {
            ++framesAfterLight;
            (busy ? busyFrames_ : stillFrames_).add(frameMs);
        }
        ++fpsWindowFrames;
        const double t = std::chrono::duration<double>(now - start).count();
        if (t - fpsWindowStart >= 0.5) {
            fps_ = fpsWindowFrames / (t - fpsWindowStart);
            frameMs_ = 1000.0 * (t - fpsWindowStart) / fpsWindowFrames;
            relightRate_ = double(relightStats_.count - fpsWindowRelights) / (t - fpsWindowStart);
            fpsWindowRelights = relightStats_.count;
            fpsWindowStart = t;
            fpsWindowFrames = 0;
        }
    }
    worker_.reset();
    pointWorker_.reset();
    printSummary(std::chrono::duration<double>(Clock::now() - start).count());
    if (scripted && !screenshotsDone) {
        if (!s_.screenshots.empty())
            throw Error("view", "the window was closed before the scripted frames were done; no screenshot written");
    }
    return 0;
}

}  // namespace

// ---------------------------------------------------------------------------
// Public functions
// ---------------------------------------------------------------------------

std::vector<std::string> findEnvironments(const std::vector<std::string>& args) {
    std::vector<std::string> paths;
    const auto expand = [&](const fs::path& dir) {
        std::vector<std::string> found;
        for (const fs::directory_entry& e : fs::directory_iterator(dir)) {
            const std::string ext = lowerExtension(e.path());
            if (e.is_regular_file() && (ext == ".exr" || ext == ".hdr")) found.push_back(e.path().string());
        }
        std::sort(found.begin(), found.end());
        return found;
    };
    if (args.empty()) {
        for (const fs::path& dir : {fs::path("data/envmaps"), fs::path(PRT_SOURCE_DIR) / "data/envmaps"}) {
            std::error_code ec;
            if (!fs::is_directory(dir, ec)) continue;
            paths = expand(dir);
            if (!paths.empty()) return paths;
        }
        throw Error("--environment", "none given and no data/envmaps/ folder with .exr/.hdr maps found "
                                     "(run tools/fetch-data.sh, or pass -e FILE_OR_FOLDER)");
    }
    for (const std::string& a : args) {
        std::error_code ec;
        if (fs::is_directory(a, ec)) {
            const std::vector<std::string> found = expand(a);
            if (found.empty()) throw Error(a, "folder holds no .exr or .hdr file");
            paths.insert(paths.end(), found.begin(), found.end());
        } else if (fs::exists(a, ec)) {
            paths.push_back(a);
        } else {
            throw Error(a, "no such file or folder");
        }
    }
    return paths;
}

void checkViewerDisplay() {
    glfwSetErrorCallback(glfwErrorCallback);
    if (!glfwInit())
        throw Error("display", "cannot open a window: " + takeGlfwError() +
                                   " (no X11/Wayland display? Set DISPLAY, or run under xvfb-run -a)");
}

int runViewer(ViewerSetup setup) {
    if (setup.environments.empty()) throw Error("view", "no environment");
    Viewer viewer(std::move(setup));
    return viewer.run();
}

}  // namespace prt
