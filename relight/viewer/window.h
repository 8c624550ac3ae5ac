#pragma once
// The viewer's window and input (prt-relight view, docs/viewer.md, "Controls" and
// "Scripting"): a GLFW window with an OpenGL 3.3+ core context and Dear ImGui's
// GLFW + OpenGL 3 backends; the keys, drags and wheel that change the ViewState (orbit
// camera, pan, zoom, environment rotation and switching, toggles); and the scripted
// motion of --frames, --spin and --orbit.
//
// Everything here runs on the thread that created the window, which owns the GL context.

#define GLFW_INCLUDE_NONE
#include <GL/glew.h>
#include <GLFW/glfw3.h>
#include <glm/glm.hpp>

#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "relight/viewer/view_state.h"

namespace prt {

// Initialises GLFW with an error callback that keeps GLFW's last message. Throws
// prt::Error("display", ...) when no window can be opened (no X11 display or Wayland
// compositor). GLFW stays initialised (the window's session terminates it).
void initDisplay();

class ViewerWindow {
public:
    // Opens a width x height window titled `title`, its OpenGL 3.3+ core context current
    // with the entry points loaded (GLEW), swapping with vsync or not, with ImGui's
    // context and backends on it (no imgui.ini). Prints "OpenGL <version>, <renderer>".
    // Throws prt::Error("display", ...) without a display and ("OpenGL", ...) without a
    // 3.3 core context, when GLEW cannot load the functions or ImGui cannot start.
    ViewerWindow(int width, int height, const std::string& title, bool vsync);
    ~ViewerWindow();  // ImGui, the window, then GLFW; GL objects must be deleted before
    ViewerWindow(const ViewerWindow&) = delete;
    ViewerWindow& operator=(const ViewerWindow&) = delete;

    bool shouldClose() const;
    void close();
    void makeCurrent();
    // Processes pending events; returns the framebuffer size the window was resized to
    // since the last call, if it was.
    std::optional<std::pair<int, int>> pollEvents();
    void waitEvents(double seconds);
    // The framebuffer's size in pixels: 0 x 0 while minimised.
    std::pair<int, int> framebufferSize() const;
    void swapBuffers();

    // ImGui's frame: begin it (before any widget or applyInput), render its draw data
    // into the current framebuffer.
    void beginImGuiFrame();
    void renderImGui();
    // Ends a begun ImGui frame without drawing it (a frame the viewer skips).
    void skipImGuiFrame();
    // Whether an input event (a key, a character, a mouse button or motion, the wheel, a
    // resize) arrived since the last call.
    bool takeInputSeen();

    // Applies the keys, drags and wheel turns since the last call to `state` (those
    // ImGui wants go to the panel): the table of docs/viewer.md, "Controls". Esc and Q
    // close the window.
    void applyInput(ViewState& state, const ViewLimits& limits);

    const std::string& glVersion() const { return glVersion_; }
    const std::string& glRenderer() const { return glRenderer_; }

private:
    struct Session {  // glfwInit .. glfwTerminate
        Session();
        ~Session();
    };
    struct DestroyWindow {
        void operator()(GLFWwindow* w) const;
    };
    void handleKey(ViewState& state, const ViewLimits& limits, int key, int mods);
    static void keyCallback(GLFWwindow* w, int key, int scancode, int action, int mods);
    static void scrollCallback(GLFWwindow* w, double dx, double dy);
    static void framebufferSizeCallback(GLFWwindow* w, int width, int height);
    static void cursorPosCallback(GLFWwindow* w, double x, double y);
    static void mouseButtonCallback(GLFWwindow* w, int button, int action, int mods);
    static void charCallback(GLFWwindow* w, unsigned int codepoint);

    Session session_;  // first: terminates GLFW after the window is gone
    std::unique_ptr<GLFWwindow, DestroyWindow> window_;
    bool imgui_ = false;
    std::string glVersion_, glRenderer_;

    enum class Drag { None, Orbit, Pan, Environment } drag_ = Drag::None;
    double lastX_ = 0.0, lastY_ = 0.0, scroll_ = 0.0;
    std::vector<std::pair<int, int>> keys_;  // key, mods
    bool pendingResize_ = false;
    int resizeWidth_ = 0, resizeHeight_ = 0;
    bool inputSeen_ = true;
};

// The camera back at `home`, keeping the current image size (R, the panel's button).
void resetCamera(ViewState& state, const ViewLimits& limits);

// The scripted motion (--frames, --spin, --orbit, --light-orbit; docs/viewer.md, "Scripting").
class ScriptedMotion {
public:
    // frames > 0: a scripted run of that many frames with light on screen. Degrees per
    // frame: spin turns the environment about +Y, orbit the camera about its up axis
    // through the target (+ = toward +X from +Z), lightOrbit every point light about
    // the +Y axis through lightPivot (mm, the object's frame) and every directional
    // light's direction about +Y (a new light position every frame).
    ScriptedMotion(int frames, double spinDegreesPerFrame, double orbitDegreesPerFrame,
                   double lightOrbitDegreesPerFrame = 0.0, glm::dvec3 lightPivot = glm::dvec3(0.0));

    bool scripted() const { return frames_ > 0; }
    // Whether it turns anything each frame (spin, orbit or light orbit).
    bool moving() const { return spin_ != 0.0 || orbit_ != 0.0 || lightOrbit_ != 0.0; }
    // Before a frame: one step of spin and orbit once light is on screen; a scripted
    // run takes exactly `frames` steps, so its final rotation and camera are known.
    void step(ViewState& state, bool lightShown);
    // After a frame was shown.
    void frameShown(bool lightShown) {
        if (lightShown) ++framesWithLight_;
    }
    // Frames shown with light so far (the clock of the scripted edit, view.h).
    int framesWithLight() const { return framesWithLight_; }
    // A scripted run's frames are done: it ends once the light on screen is the last
    // asked for.
    bool finishing() const { return scripted() && framesWithLight_ >= frames_; }

private:
    int frames_;
    double spin_, orbit_, lightOrbit_;
    glm::dvec3 lightPivot_;
    int steps_ = 0, framesWithLight_ = 0;
};

}  // namespace prt
