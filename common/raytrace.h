#pragma once
// Ray queries against a triangle mesh, on Embree 3 (one process-wide device).
//
// Units. Positions are in whatever unit the mesh is in (millimetres in this
// project). A ray is org + t * dir for t in [tnear, tfar]; directions need NOT be
// normalised, and t (tnear, tfar, Hit::t) is then measured in units of |dir|, not
// in mesh units. With unit directions t is a distance. tnear must be >= 0 (negative
// values are clamped to 0); tfar may be +infinity; a ray with tnear > tfar (or NaN)
// is inactive: never occluded, never hit. dir must be finite and non-zero.
//
// What counts as a hit. Every triangle counts, whichever side the ray meets it from:
// back faces occlude and are hit exactly like front faces (the device is checked at
// start-up to have back-face culling compiled out). occluded() is true when some
// triangle is hit at tnear <= t <= tfar; as Embree documents, hits at (or within
// rounding of) exactly tnear or tfar may go either way, so leave a margin when it
// matters. Degenerate (zero-area) triangles are never hit.
//
// Self-intersection. A ray leaving a surface point must start slightly off the
// surface: use offsetRayOrigin() (or RayScene::offsetRayOrigin, which also accounts
// for the scene's coordinate magnitude) and tnear = 0.
//
// Threads. A RayScene is immutable after construction: all queries are const and
// may be called concurrently from any number of threads (TBB or otherwise). The
// process-wide device is created lazily and thread-safely on first use.
//
// Errors. Invalid meshes and Embree failures during construction throw prt::Error.
// Queries do no error checking (Embree's queries do none); an Embree error raised
// during a query is reported through prt::warn.

#include <glm/glm.hpp>

#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

struct RTCSceneTy;  // Embree's opaque scene type (RTCScene is RTCSceneTy*).

namespace prt {

struct TriangleMesh;

// ---------------------------------------------------------------------------
// Device
// ---------------------------------------------------------------------------

// What the installed Embree offers (creates the process-wide device if needed).
struct RayDeviceInfo {
    std::string version;        // e.g. "3.13.5"
    bool nativeRay4 = false;    // RTC_DEVICE_PROPERTY_NATIVE_RAY4_SUPPORTED
    bool nativeRay8 = false;
    bool nativeRay16 = false;
    bool rayStreams = false;    // RTC_DEVICE_PROPERTY_RAY_STREAM_SUPPORTED
    int taskingSystem = -1;     // 0 internal, 1 TBB, 2 PPL
};
RayDeviceInfo rayDeviceInfo();

// ---------------------------------------------------------------------------
// Scene
// ---------------------------------------------------------------------------

enum class RayBuildQuality { Medium, High };

struct RaySceneOptions {
    // HIGH (spatial splits) costs a few times the build time of MEDIUM and pays off
    // when billions of rays are traced, as in pass 1.
    RayBuildQuality quality = RayBuildQuality::High;
    // RTC_SCENE_FLAG_ROBUST: robust traversal, fewer rays slipping through shared edges.
    bool robust = true;
};

// How occludedFromPoint / occludedBatch (and intersectBatchWithBeyond: packet widths
// and Single only) hand rays to Embree. Auto is defaultOcclusionKernel(); the others
// exist so that benchmarks and tests can compare them, and give the same flags
// (tested; their rates: docs/performance.md, "Design measurements").
enum class OcclusionKernel {
    Auto,
    Single,    // a loop of rtcOccluded1 (the reference)
    Packet4,   // rtcOccluded4
    Packet8,   // rtcOccluded8
    Packet16,  // rtcOccluded16
    Stream1M,  // rtcOccluded1M (array of single rays)
    StreamNp,  // rtcOccludedNp (SoA stream)
};
const char* toString(OcclusionKernel kernel);
// The kernel Auto stands for: the widest packet the device supports natively, traced
// with the coherent flag (Single when it has none).
OcclusionKernel defaultOcclusionKernel();

inline constexpr uint32_t kNoTriangle = 0xffffffffu;

struct Hit {
    bool hit = false;
    float t = std::numeric_limits<float>::infinity();  // in units of |dir|
    uint32_t triangle = kNoTriangle;  // index into the mesh's triangles
    // Embree's barycentrics: the hit point is (1-u-v) p0 + u p1 + v p2 of the
    // triangle's vertices in the order the mesh lists them.
    float u = 0.0f, v = 0.0f;
    // Unit normal of the hit triangle, normalize(cross(p1 - p0, p2 - p0)): outward for
    // CCW-outward meshes, whichever side the ray came from. Zero when !hit.
    glm::vec3 geometricNormal{0.0f};
};

class RayScene {
public:
    // Builds a static Embree scene from a copy of the mesh's positions and triangles
    // (the mesh may be destroyed afterwards). Throws prt::Error for an empty mesh, an
    // index out of range or a non-finite position, and for Embree failures.
    explicit RayScene(const TriangleMesh& mesh, const RaySceneOptions& options = {});
    RayScene(const std::vector<glm::vec3>& positions, const std::vector<glm::uvec3>& triangles,
             const RaySceneOptions& options = {});
    ~RayScene();

    RayScene(const RayScene&) = delete;
    RayScene& operator=(const RayScene&) = delete;
    // A moved-from scene may only be destroyed or assigned to.
    RayScene(RayScene&& other) noexcept;
    RayScene& operator=(RayScene&& other) noexcept;

    size_t triangleCount() const { return faceNormals_.size(); }
    glm::vec3 boundsMin() const { return boundsMin_; }
    glm::vec3 boundsMax() const { return boundsMax_; }
    // Largest absolute coordinate of any vertex (the magnitude rounding errors scale with).
    float coordinateScale() const { return coordinateScale_; }
    // Offset distance offsetRayOrigin uses for points of this scene:
    // kOffsetRelative * coordinateScale() + kOffsetAbsolute.
    float epsilon() const;
    // offsetRayOrigin(p, n, dir, coordinateScale()): the robust choice for points
    // anywhere on this scene's surface (even those near the coordinate origin).
    glm::vec3 offsetRayOrigin(const glm::vec3& p, const glm::vec3& geometricNormal,
                              const glm::vec3& dir) const;

    // --- single rays -------------------------------------------------------------
    // Any hit with tnear <= t <= tfar (front or back face).
    bool occluded(const glm::vec3& org, const glm::vec3& dir, float tnear, float tfar) const;
    // Closest hit with tnear <= t <= tfar.
    Hit intersect(const glm::vec3& org, const glm::vec3& dir, float tnear, float tfar) const;

    // --- many rays from one origin (the pass-1 hot loop) ---------------------------
    // occludedOut[i] = 1 if the ray org + t (dirX[i], dirY[i], dirZ[i]) is occluded
    // for some t in [tnear, tfar], else 0. Any count (not only multiples of the packet
    // width); the arrays need no particular alignment. Rays are traced in packets of
    // consecutive directions (16 on AVX-512) with Embree's coherent-ray flag, so order
    // directions coherently: cube face by face, neighbouring texels together (2x2-texel
    // tiles of 2x2 sub-directions, a 4x4 block per packet, beat row order).
    void occludedFromPoint(const glm::vec3& org, const float* dirX, const float* dirY,
                           const float* dirZ, size_t count, float tnear, float tfar,
                           uint8_t* occludedOut) const;
    // Same with an explicit kernel; coherent sets RTC_INTERSECT_CONTEXT_FLAG_COHERENT.
    void occludedFromPointWith(OcclusionKernel kernel, bool coherent, const glm::vec3& org,
                               const float* dirX, const float* dirY, const float* dirZ,
                               size_t count, float tnear, float tfar,
                               uint8_t* occludedOut) const;
    // The plain rtcOccluded1 loop: the reference the fast path is tested and
    // benchmarked against.
    void occludedFromPointReference(const glm::vec3& org, const float* dirX, const float* dirY,
                                    const float* dirZ, size_t count, float tnear, float tfar,
                                    uint8_t* occludedOut) const;

    // --- many rays with their own origins ----------------------------------------
    // occludedOut[i] for the ray (org[i], dir[i]) as in occluded(). coherent sets
    // RTC_INTERSECT_CONTEXT_FLAG_COHERENT: for packets of rays that share a direction
    // (single scattering: one direction from 16 neighbouring points); the hits are the
    // same either way.
    void occludedBatch(const float* orgX, const float* orgY, const float* orgZ,
                       const float* dirX, const float* dirY, const float* dirZ, size_t count,
                       float tnear, float tfar, uint8_t* occludedOut, bool coherent = false) const;
    // hitsOut[i] = intersect(org[i], dir[i], tnear, tfar), traced in packets; coherent as
    // above.
    void intersectBatch(const float* orgX, const float* orgY, const float* orgZ,
                        const float* dirX, const float* dirY, const float* dirZ, size_t count,
                        float tnear, float tfar, Hit* hitsOut, bool coherent = false) const;
    // The first hit of each ray and whether the ray goes on to meet another surface:
    // hitsOut[i] = intersect(org[i], dir[i], tnear, infinity), and beyondOut[i] = 1 when
    // the ray also hits something at t > hitsOut[i].t + separation, i.e.
    // occluded(org[i], dir[i], hitsOut[i].t + separation, infinity) (0 when it hits
    // nothing): whether the first hit point is shadowed toward dir, without a second ray
    // from it. One traversal per ray, in packets like intersectBatch: a context filter
    // rejects the hits Embree reports (so the traversal goes on past the first) until
    // two lie more than `separation` apart, then accepts one, which bounds the rest of
    // the traversal below it, where every closer hit is still reported; the first hit is
    // the closest reported: one traversal instead of intersectBatch followed by
    // occludedBatch from the offset hits (docs/single-scattering.md, "visibility from the
    // exit ray"). separation >= 0; hits closer together than it (a shared edge,
    // coincident triangles) count as one surface.
    // kernel: the packet width (Auto: the device's native one; Single: rtcIntersect1
    // through the same filter, what a device without packets runs); the stream kernels
    // are refused (std::invalid_argument). Every width gives the same results (tested).
    void intersectBatchWithBeyond(const float* orgX, const float* orgY, const float* orgZ,
                                  const float* dirX, const float* dirY, const float* dirZ,
                                  size_t count, float tnear, float separation, Hit* hitsOut,
                                  uint8_t* beyondOut, bool coherent = false,
                                  OcclusionKernel kernel = OcclusionKernel::Auto) const;
    // The definition above with two single rays each (intersect, then occluded beyond the
    // hit): the reference intersectBatchWithBeyond is tested against.
    void intersectWithBeyondReference(const float* orgX, const float* orgY, const float* orgZ,
                                      const float* dirX, const float* dirY, const float* dirZ,
                                      size_t count, float tnear, float separation, Hit* hitsOut,
                                      uint8_t* beyondOut) const;

private:
    void build(const std::vector<glm::vec3>& positions, const std::vector<glm::uvec3>& triangles,
               const RaySceneOptions& options);
    void release() noexcept;
    void fillHit(Hit& out, float t, uint32_t primID, float u, float v) const;

    RTCSceneTy* scene_ = nullptr;
    std::vector<glm::vec3> faceNormals_;  // unit, per triangle (zero if degenerate)
    glm::vec3 boundsMin_{0.0f}, boundsMax_{0.0f};
    float coordinateScale_ = 0.0f;
};

// ---------------------------------------------------------------------------
// Ray origins on surfaces
// ---------------------------------------------------------------------------

// Relative and absolute terms of the offset distance (see offsetRayOrigin).
inline constexpr float kOffsetRelative = 1.0f / 262144.0f;  // 2^-18 = 32 float ulps at 1
inline constexpr float kOffsetAbsolute = 1.0f / 1048576.0f;  // 2^-20 (mesh units)

// Moves a surface point p off the surface along its triangle's geometric normal, to
// the side dir points to: p + s * eps * normalize(n) with s = +1 if dot(dir, n) >= 0
// else -1, and eps = kOffsetRelative * max(|p.x|, |p.y|, |p.z|, scale) +
// kOffsetAbsolute. Float positions near magnitude M carry rounding errors of a few
// ulps (M 2^-23); eps is 32 of them, enough that Embree never reports the surface the
// point lies on (nor a convex neighbour) for rays leaving it, even at grazing angles
// (|dot(dir, n)| >= 0.01 tested), while remaining far below any feature size (3.8e-4
// for M = 100). Pass scale = the scene's coordinateScale() when p may be much
// closer to the coordinate origin than the triangle's vertices are.
glm::vec3 offsetRayOrigin(const glm::vec3& p, const glm::vec3& geometricNormal,
                          const glm::vec3& dir, float scale = 0.0f);

}  // namespace prt
