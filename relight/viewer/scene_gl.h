#pragma once
// The viewer's scene on the GPU (prt-relight view; docs/viewer.md, "How it works"): the
// mesh, its relit per-vertex radiance, the view maps and the environments as OpenGL
// resources, the render targets, and the frame, drawn at the camera's width x height
// so it is prt-relight render's image pixel for pixel:
//   1. visibility, only when the camera changed: the triangle each pixel's ray hits
//      first (as Embree's primary ray), an R32UI target with a float depth buffer;
//   2. shading, one full-screen triangle every frame: TranslucentShader::shade's
//      formula for any number K of view terms, the optional specular layer
//      (specularReflection) and, where no triangle is, the environment along the ray
//      (environmentRadiance), the object's base colour tinting the translucent part
//      (base_colour.h; one texture at most); the ground (RelightObject::ground) as its
//      vertices' blended radiance, after the object's triangles in every buffer;
//      the display transform of writePng (common/tonemap.h),
//      except that chang's Radiance_avg is the area-weighted mean luminance of the
//      uploaded per-vertex radiance (no read-back of the frame), not the image's.
// The frame goes straight to the window, or to an offscreen framebuffer (tone-mapped
// RGBA8 + linear RGBA32F, alpha 1 on the object) for screenshots and for a window
// whose framebuffer is not the camera's size.
//
// Contract: every call needs the GL 3.3 core context the scene was created in to be
// current (relight/viewer/window.h); the object and the environments must outlive the
// scene and not change. Failures throw prt::Error("OpenGL", ...): a mesh or view maps
// too large for this OpenGL's textures, a shader that does not compile, an unsupported
// framebuffer, a pending GL error; screenshot writes throw as writeExr / writePng.

#include <GL/glew.h>
#include <glm/glm.hpp>

#include <cstddef>
#include <string>
#include <vector>

#include "common/camera.h"
#include "common/image.h"
#include "common/tonemap.h"
#include "relight/pointlight/point_lights.h"
#include "relight/prt/eye_path.h"
#include "relight/prt/relight_object.h"

namespace prt {

// What one frame shows.
struct SceneFrame {
    Camera camera;
    int environment = 0;           // the map of the background and the specular layer
    double rotation = 0.0;         // the environment's rotation, degrees about +Y
    DisplayTransform display;      // exposure and tone mapping (chang: Radiance_avg of the uploaded radiance)
    int viewTerms = 0;             // K of the uploaded radiance (0: diffuse only)
    EyePathTable eyePath;          // the single-scattering path's factor (eye_path.h; ones: the normal)
    bool specular = false;         // the specular layer asked for (its pre-filtered map is bound)
    bool environmentLight = true;  // background and specular layer shown
    // The point lights' specular (uploadPointSpecular's lights and vertex irradiance):
    // the GGX lobe of point_specular.h with this alpha and eta, per pixel.
    bool pointSpecular = false;
    double pointSpecularRoughness = 0.3;
    double pointEta = 1.3;
};

class SceneGl {
public:
    // The resources of `object` (mesh buffers and textures, its view maps, the shaders)
    // and width x height targets. Environment textures (and the pre-filtered maps of
    // the specular layer, blurred by specularBlur, 0 = automatic: specularBlurFactor)
    // are made on first use.
    // subpixels: n of --spp n^2 (relight/render/supersample.h): visibility and shading run
    // on an n width x n height sub-pixel grid (the supersampled camera's rays), and a
    // resolve pass box-filters each pixel's n x n sub-pixels before the display
    // transform, as render --spp does; 1 shades each pixel's centre directly.
    SceneGl(const RelightObject& object, const std::vector<Image>& environments, int specularBlur, int width,
            int height, int subpixels = 1);
    ~SceneGl();
    SceneGl(const SceneGl&) = delete;
    SceneGl& operator=(const SceneGl&) = delete;

    // New width x height targets (the camera's size changed).
    void resize(int width, int height);

    // Uploads `slots` blocks of V RGBA values (V = the object mesh's vertices; the
    // diffuse radiance, then each view term's sum) and, with a ground, the ground's
    // vertex radiance (its vertex count, else zeros) into the radiance texture not
    // drawn, which then becomes the one drawn. Does not check for GL errors.
    void uploadRadiance(const std::vector<glm::vec4>& packed, int slots, const std::vector<glm::vec3>& ground = {});
    // Uploads the point lights of the specular (their positions, or directions toward
    // them) and each light's shadowed irradiance at the object's vertices, light l's
    // vertex v at l * V + v (vertexLightIrradiance, vertex_surface_terms.h); no lights:
    // no point-light specular is drawn. Throws prt::Error("OpenGL", ...) for more lights
    // than this OpenGL's textures hold, prt::Error("point lights", ...) for a size mismatch.
    void uploadPointSpecular(const std::vector<Light>& lights, const std::vector<glm::vec3>& irradiance);

    // Draws the frame into the window's framebuffer, or into the offscreen targets.
    void draw(const SceneFrame& frame, bool offscreen);
    // Copies the offscreen image into the window's framebuffer of width x height:
    // pixel for pixel at the targets' size, else scaled (bilinear) over black.
    void blitToWindow(int width, int height);

    // Writes the last frame drawn offscreen: .exr = linear RGBA float (A = 1 on the
    // object), anything else the tone-mapped 8-bit sRGB PNG. Creates the parent folder.
    void writeScreenshot(const std::string& path);
    // Writes the window's back buffer, width x height, as an sRGB PNG (panel included).
    void writeWindowScreenshot(const std::string& path, int width, int height);

private:
    void createTargets(int width, int height);
    void destroyTargets();
    GLuint environmentTexture(int index, bool prefiltered);
    // The sRGB bytes of the bound read buffer as a PNG (exact: the bytes decode to
    // values that writePng encodes back to the same bytes).
    void writeDisplayPng(const std::string& path, int width, int height);

    const RelightObject& object_;
    const std::vector<Image>& environments_;
    std::vector<Image> prefiltered_;  // per environment, made on first use
    int specularBlur_ = 0;
    int fileTerms_ = 0;  // K of the file's view maps

    GLuint vao_ = 0, visibilityProgram_ = 0, shadeProgram_ = 0, resolveProgram_ = 0;
    int subpixels_ = 1;
    GLuint subpixelFbo_ = 0, subpixelLinear_ = 0;  // n > 1: the shading pass's linear sub-pixel target
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
    // The object's base colour (RelightObject::baseColour): per-triangle factors (A = 1
    // where the texture applies), per-corner texture coordinates and the one texture.
    void uploadBaseColour(int maxSize);
    GLuint triangleColours_ = 0, cornerUvs_ = 0, baseTexture_ = 0;
    glm::ivec2 baseTextureSize_{1, 1}, baseWrap_{0, 0};
    std::vector<float> vertexAreas_;  // a third of each adjacent triangle's area, mm^2 (object vertices)
    size_t drawnVertices_ = 0, drawnTriangles_ = 0;  // the object's, plus the ground's
    glm::dvec3 drawnCentre_{0.0};  // a sphere around what is drawn: the depth range
    double drawnRadius_ = 0.0;
    std::vector<glm::vec4> slot0_;    // scratch: slot 0 of the object and the ground
    double radianceAverage_ = 0.0;    // chang's Radiance_avg of the drawn radiance
    // The point lights' specular: one texel per light, and their vertex irradiance in
    // slots of slotRows_ rows as the radiance's.
    GLuint pointLights_ = 0, pointIrradiance_ = 0;
    int pointLightCount_ = 0, pointTextureLights_ = 0;
};

}  // namespace prt
