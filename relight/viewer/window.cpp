// The viewer's window and input: see window.h.

#include "relight/viewer/window.h"

#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>
#include <imgui.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <mutex>

#include "common/error.h"
#include "common/envmap.h"

namespace prt {

namespace {

// GLFW's last error message, for clear exceptions.
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

}  // namespace

void initDisplay() {
    glfwSetErrorCallback(glfwErrorCallback);
    if (!glfwInit())
        throw Error("display", "cannot open a window: " + takeGlfwError() +
                                   " (no X11/Wayland display? Set DISPLAY, or run under xvfb-run -a)");
}

ViewerWindow::Session::Session() { initDisplay(); }
ViewerWindow::Session::~Session() { glfwTerminate(); }

void ViewerWindow::DestroyWindow::operator()(GLFWwindow* w) const { glfwDestroyWindow(w); }

ViewerWindow::ViewerWindow(int width, int height, const std::string& title, bool vsync) {
    glfwDefaultWindowHints();
    glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
    glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
    glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
    glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
    glfwWindowHint(GLFW_DEPTH_BITS, 0);  // depth only in the visibility pass (offscreen)
    glfwWindowHint(GLFW_SRGB_CAPABLE, GLFW_FALSE);
    window_.reset(glfwCreateWindow(width, height, title.c_str(), nullptr, nullptr));
    if (!window_)
        throw Error("OpenGL", "cannot create a window with an OpenGL 3.3 core context: " + takeGlfwError() +
                                  " (the viewer needs OpenGL 3.3 core or newer; under Xvfb Mesa's llvmpipe "
                                  "provides 4.5)");
    GLFWwindow* w = window_.get();
    glfwMakeContextCurrent(w);
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
    glfwSwapInterval(vsync ? 1 : 0);
    glfwSetWindowUserPointer(w, this);
    // Installed before ImGui's, which chains to them.
    glfwSetKeyCallback(w, keyCallback);
    glfwSetScrollCallback(w, scrollCallback);
    glfwSetFramebufferSizeCallback(w, framebufferSizeCallback);
    glfwSetCursorPosCallback(w, cursorPosCallback);
    glfwSetMouseButtonCallback(w, mouseButtonCallback);
    glfwSetCharCallback(w, charCallback);

    IMGUI_CHECKVERSION();
    ImGui::CreateContext();
    ImGui::GetIO().IniFilename = nullptr;  // no imgui.ini in the working directory
    ImGui::StyleColorsDark();
    if (!ImGui_ImplGlfw_InitForOpenGL(w, true) || !ImGui_ImplOpenGL3_Init("#version 330 core"))
        throw Error("OpenGL", "cannot initialise the ImGui backends");
    imgui_ = true;
    glfwGetCursorPos(w, &lastX_, &lastY_);
}

ViewerWindow::~ViewerWindow() {
    if (!window_) return;
    glfwMakeContextCurrent(window_.get());
    if (imgui_) {
        ImGui_ImplOpenGL3_Shutdown();
        ImGui_ImplGlfw_Shutdown();
        ImGui::DestroyContext();
    }
}

bool ViewerWindow::shouldClose() const { return glfwWindowShouldClose(window_.get()); }
void ViewerWindow::close() { glfwSetWindowShouldClose(window_.get(), GLFW_TRUE); }
void ViewerWindow::makeCurrent() { glfwMakeContextCurrent(window_.get()); }

std::optional<std::pair<int, int>> ViewerWindow::pollEvents() {
    glfwPollEvents();
    if (!pendingResize_) return std::nullopt;
    pendingResize_ = false;
    return std::make_pair(resizeWidth_, resizeHeight_);
}

void ViewerWindow::waitEvents(double seconds) { glfwWaitEventsTimeout(seconds); }

std::pair<int, int> ViewerWindow::framebufferSize() const {
    int width = 0, height = 0;
    glfwGetFramebufferSize(window_.get(), &width, &height);
    return {width, height};
}

void ViewerWindow::swapBuffers() { glfwSwapBuffers(window_.get()); }

void ViewerWindow::beginImGuiFrame() {
    ImGui_ImplOpenGL3_NewFrame();
    ImGui_ImplGlfw_NewFrame();
    ImGui::NewFrame();
}

void ViewerWindow::renderImGui() {
    ImGui::Render();
    ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
}

void ViewerWindow::skipImGuiFrame() { ImGui::EndFrame(); }

bool ViewerWindow::takeInputSeen() {
    const bool seen = inputSeen_;
    inputSeen_ = false;
    return seen;
}

// ---------------------------------------------------------------------------
// Input
// ---------------------------------------------------------------------------

void ViewerWindow::keyCallback(GLFWwindow* w, int key, int, int action, int mods) {
    auto* v = static_cast<ViewerWindow*>(glfwGetWindowUserPointer(w));
    if (!v) return;
    v->inputSeen_ = true;
    if (action == GLFW_PRESS || action == GLFW_REPEAT) v->keys_.emplace_back(key, mods);
}

void ViewerWindow::scrollCallback(GLFWwindow* w, double, double dy) {
    auto* v = static_cast<ViewerWindow*>(glfwGetWindowUserPointer(w));
    if (!v) return;
    v->inputSeen_ = true;
    v->scroll_ += dy;
}

void ViewerWindow::cursorPosCallback(GLFWwindow* w, double, double) {
    if (auto* v = static_cast<ViewerWindow*>(glfwGetWindowUserPointer(w))) v->inputSeen_ = true;
}

void ViewerWindow::mouseButtonCallback(GLFWwindow* w, int, int, int) {
    if (auto* v = static_cast<ViewerWindow*>(glfwGetWindowUserPointer(w))) v->inputSeen_ = true;
}

void ViewerWindow::charCallback(GLFWwindow* w, unsigned int) {
    if (auto* v = static_cast<ViewerWindow*>(glfwGetWindowUserPointer(w))) v->inputSeen_ = true;
}

void ViewerWindow::framebufferSizeCallback(GLFWwindow* w, int width, int height) {
    auto* v = static_cast<ViewerWindow*>(glfwGetWindowUserPointer(w));
    if (!v) return;
    v->inputSeen_ = true;
    v->pendingResize_ = true;
    v->resizeWidth_ = width;
    v->resizeHeight_ = height;
}

void resetCamera(ViewState& state, const ViewLimits& limits) {
    const int w = state.camera.width, h = state.camera.height;
    state.camera = limits.home;
    state.camera.width = w;
    state.camera.height = h;
}

void ViewerWindow::handleKey(ViewState& s, const ViewLimits& limits, int key, int mods) {
    const bool shift = (mods & GLFW_MOD_SHIFT) != 0;
    const int count = limits.environments;
    switch (key) {
        case GLFW_KEY_ESCAPE:
        case GLFW_KEY_Q: close(); break;
        case GLFW_KEY_R: resetCamera(s, limits); break;
        case GLFW_KEY_LEFT: s.rotation = wrapDegrees(s.rotation - (shift ? 1.0 : 5.0)); break;
        case GLFW_KEY_RIGHT: s.rotation = wrapDegrees(s.rotation + (shift ? 1.0 : 5.0)); break;
        case GLFW_KEY_N:
        case GLFW_KEY_PAGE_DOWN: s.environment = (s.environment + 1) % count; break;
        case GLFW_KEY_B:
        case GLFW_KEY_PAGE_UP: s.environment = (s.environment + count - 1) % count; break;
        case GLFW_KEY_M: s.multipleScattering = !s.multipleScattering; break;
        case GLFW_KEY_S: s.singleScattering = !s.singleScattering; break;
        case GLFW_KEY_G: s.specular = !s.specular; break;
        case GLFW_KEY_E: s.environmentLight = !s.environmentLight; break;
        case GLFW_KEY_L: s.pointLights = !s.pointLights; break;
        case GLFW_KEY_EQUAL:
        case GLFW_KEY_KP_ADD: s.exposure += 0.5f; break;
        case GLFW_KEY_MINUS:
        case GLFW_KEY_KP_SUBTRACT: s.exposure -= 0.5f; break;
        case GLFW_KEY_0: s.exposure = 0.0f; break;
        case GLFW_KEY_T: s.toneMap = (s.toneMap + 1) % 4; break;
        case GLFW_KEY_RIGHT_BRACKET:
            s.lightTerms = s.lightTerms == 0 ? 0 : std::min(s.lightTerms * 2, limits.maxLightTerms);
            break;
        case GLFW_KEY_LEFT_BRACKET:
            s.lightTerms = s.lightTerms == 0 ? limits.maxLightTerms / 2 : std::max(1, s.lightTerms / 2);
            break;
        case GLFW_KEY_H:
        case GLFW_KEY_F1: s.showPanel = !s.showPanel; break;
        case GLFW_KEY_P:
        case GLFW_KEY_F12: s.screenshotRequested = true; break;
        default: break;
    }
}

void ViewerWindow::applyInput(ViewState& s, const ViewLimits& limits) {
    GLFWwindow* w = window_.get();
    const ImGuiIO& io = ImGui::GetIO();
    std::vector<std::pair<int, int>> keys;
    keys.swap(keys_);
    if (!io.WantCaptureKeyboard)
        for (const auto& [key, mods] : keys) handleKey(s, limits, key, mods);

    double x = 0.0, y = 0.0;
    glfwGetCursorPos(w, &x, &y);
    double dx = x - lastX_, dy = y - lastY_;
    lastX_ = x;
    lastY_ = y;
    const bool left = glfwGetMouseButton(w, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS;
    const bool right = glfwGetMouseButton(w, GLFW_MOUSE_BUTTON_RIGHT) == GLFW_PRESS;
    const bool middle = glfwGetMouseButton(w, GLFW_MOUSE_BUTTON_MIDDLE) == GLFW_PRESS;
    if (!left && !right && !middle) {
        drag_ = Drag::None;
    } else if (drag_ == Drag::None && !io.WantCaptureMouse) {
        const bool modifier = glfwGetKey(w, GLFW_KEY_LEFT_SHIFT) == GLFW_PRESS ||
                              glfwGetKey(w, GLFW_KEY_RIGHT_SHIFT) == GLFW_PRESS ||
                              glfwGetKey(w, GLFW_KEY_LEFT_CONTROL) == GLFW_PRESS ||
                              glfwGetKey(w, GLFW_KEY_RIGHT_CONTROL) == GLFW_PRESS;
        drag_ = left ? (modifier ? Drag::Environment : Drag::Orbit) : Drag::Pan;
        dx = dy = 0.0;  // motion before the press (since the last frame) is not part of the drag
    }

    Camera& camera = s.camera;
    const glm::dvec3 up = glm::normalize(camera.up);
    glm::dvec3 offset = camera.eye - camera.target;
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
            camera.eye = camera.target + offset;
        }
    } else if (drag_ == Drag::Pan && (dx != 0.0 || dy != 0.0)) {
        const glm::dvec3 forward = glm::normalize(camera.target - camera.eye);
        const glm::dvec3 rightAxis = glm::normalize(glm::cross(forward, camera.up));
        const glm::dvec3 upAxis = glm::cross(rightAxis, forward);
        const double perPixel = 2.0 * distance * std::tan(glm::radians(camera.fovY) * 0.5) / camera.height;
        const glm::dvec3 move = (-dx * rightAxis + dy * upAxis) * perPixel;
        camera.eye += move;
        camera.target += move;
    } else if (drag_ == Drag::Environment && dx != 0.0) {
        s.rotation = wrapDegrees(s.rotation + 0.5 * dx);
    }
    if (scroll_ != 0.0 && !io.WantCaptureMouse && distance > 0) {
        distance = std::max(distance * std::pow(0.9, scroll_), 1e-3 * std::max(limits.objectRadius, 1e-6));
        camera.eye = camera.target + distance * glm::normalize(offset);
    }
    scroll_ = 0.0;
}

// ---------------------------------------------------------------------------
// Scripted motion
// ---------------------------------------------------------------------------

ScriptedMotion::ScriptedMotion(int frames, double spinDegreesPerFrame, double orbitDegreesPerFrame,
                               double lightOrbitDegreesPerFrame, glm::dvec3 lightPivot)
    : frames_(frames), spin_(spinDegreesPerFrame), orbit_(orbitDegreesPerFrame),
      lightOrbit_(lightOrbitDegreesPerFrame), lightPivot_(lightPivot) {}

void ScriptedMotion::step(ViewState& s, bool lightShown) {
    if ((spin_ == 0.0 && orbit_ == 0.0 && lightOrbit_ == 0.0) || !lightShown || (scripted() && steps_ >= frames_))
        return;
    s.rotation = wrapDegrees(s.rotation + spin_);
    if (orbit_ != 0.0)
        s.camera.eye = s.camera.target + rotationAxisAngle(s.camera.up, orbit_) * (s.camera.eye - s.camera.target);
    if (lightOrbit_ != 0.0) {
        const glm::dmat3 turn = rotationAxisAngle(glm::dvec3(0.0, 1.0, 0.0), lightOrbit_);
        for (Light& light : s.lights) {
            if (hasPosition(light)) light.position = lightPivot_ + turn * (light.position - lightPivot_);
            if (light.type != LightType::Point) light.direction = turn * light.direction;  // a spot's axis turns too
        }
    }
    ++steps_;
}

}  // namespace prt
