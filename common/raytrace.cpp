#include "common/raytrace.h"

#include "common/error.h"
#include "common/mesh.h"

#include <embree3/rtcore.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <string>

namespace prt {

namespace {

// ---------------------------------------------------------------------------
// Process-wide device
// ---------------------------------------------------------------------------

// Embree reports errors through a C callback on the thread that made the failing
// call. Throwing through Embree's C frames is not safe, so the callback only records
// the message (in a trivially destructible thread-local buffer); the construction
// code then checks rtcGetDeviceError after each call and throws prt::Error.
thread_local char tlsLastError[512] = {0};
thread_local bool tlsCapturing = false;

const char* errorCodeName(RTCError code) {
    switch (code) {
        case RTC_ERROR_NONE: return "no error";
        case RTC_ERROR_UNKNOWN: return "unknown error";
        case RTC_ERROR_INVALID_ARGUMENT: return "invalid argument";
        case RTC_ERROR_INVALID_OPERATION: return "invalid operation";
        case RTC_ERROR_OUT_OF_MEMORY: return "out of memory";
        case RTC_ERROR_UNSUPPORTED_CPU: return "unsupported CPU";
        case RTC_ERROR_CANCELLED: return "cancelled";
    }
    return "unrecognised error code";
}

void embreeErrorCallback(void* /*userPtr*/, RTCError code, const char* message) {
    std::snprintf(tlsLastError, sizeof tlsLastError, "%s%s%s", errorCodeName(code),
                  message && *message ? ": " : "", message ? message : "");
    // Outside construction nobody checks the error flag: say it now.
    if (!tlsCapturing) warn(std::string("Embree: ") + tlsLastError);
}

struct Device {
    RTCDevice handle = nullptr;
    RayDeviceInfo info;

    Device() {
        // verbose=0: no banner; the thread count is irrelevant to queries and TBB
        // decides it for commits.
        handle = rtcNewDevice("verbose=0");
        if (!handle) {
            RTCError code = rtcGetDeviceError(nullptr);
            throw Error("Embree", std::string("cannot create a device (") + errorCodeName(code) +
                                      "); is this CPU supported by the installed libembree3?");
        }
        rtcSetDeviceErrorFunction(handle, embreeErrorCallback, nullptr);

        auto prop = [&](RTCDeviceProperty p) { return rtcGetDeviceProperty(handle, p); };
        info.version = std::to_string(prop(RTC_DEVICE_PROPERTY_VERSION_MAJOR)) + "." +
                       std::to_string(prop(RTC_DEVICE_PROPERTY_VERSION_MINOR)) + "." +
                       std::to_string(prop(RTC_DEVICE_PROPERTY_VERSION_PATCH));
        info.nativeRay4 = prop(RTC_DEVICE_PROPERTY_NATIVE_RAY4_SUPPORTED) != 0;
        info.nativeRay8 = prop(RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED) != 0;
        info.nativeRay16 = prop(RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED) != 0;
        info.rayStreams = prop(RTC_DEVICE_PROPERTY_RAY_STREAM_SUPPORTED) != 0;
        info.taskingSystem = int(prop(RTC_DEVICE_PROPERTY_TASKING_SYSTEM));

        // Our contract is that back faces occlude; a libembree3 built with back-face
        // culling would silently break every visibility computation.
        if (prop(RTC_DEVICE_PROPERTY_BACKFACE_CULLING_ENABLED) != 0) {
            rtcReleaseDevice(handle);
            handle = nullptr;
            throw Error("Embree", "the installed libembree3 was built with back-face culling; "
                                  "this toolkit needs back faces to occlude");
        }
        if (prop(RTC_DEVICE_PROPERTY_TRIANGLE_GEOMETRY_SUPPORTED) == 0) {
            rtcReleaseDevice(handle);
            handle = nullptr;
            throw Error("Embree", "the installed libembree3 has no triangle geometry support");
        }
        // intersectBatchWithBeyond (single scattering's visibility) relies on a context
        // filter; without filter support Embree would skip it silently and every exit
        // ray would look like a miss.
        if (prop(RTC_DEVICE_PROPERTY_FILTER_FUNCTION_SUPPORTED) == 0) {
            rtcReleaseDevice(handle);
            handle = nullptr;
            throw Error("Embree", "the installed libembree3 was built without filter-function support");
        }
    }
    // Scenes hold their own reference to the device, so releasing ours at exit is
    // safe even if some scene outlives this object.
    ~Device() {
        if (handle) rtcReleaseDevice(handle);
    }
    Device(const Device&) = delete;
    Device& operator=(const Device&) = delete;
};

Device& device() {
    static Device d;  // thread-safe lazy initialisation
    return d;
}

// Runs an Embree construction call and turns a raised error into prt::Error.
class ErrorCapture {
public:
    ErrorCapture() {
        tlsCapturing = true;
        tlsLastError[0] = 0;
        rtcGetDeviceError(device().handle);  // clear a stale flag of this thread
    }
    ~ErrorCapture() { tlsCapturing = false; }
    ErrorCapture(const ErrorCapture&) = delete;
    ErrorCapture& operator=(const ErrorCapture&) = delete;

    void check(const char* what) {
        RTCError code = rtcGetDeviceError(device().handle);
        if (code == RTC_ERROR_NONE) return;
        std::string message = tlsLastError[0] ? tlsLastError : errorCodeName(code);
        tlsLastError[0] = 0;
        throw Error("ray scene", std::string(what) + " failed: " + message);
    }
};

RTCScene asScene(RTCSceneTy* s) { return s; }

// ---------------------------------------------------------------------------
// Packet helpers
// ---------------------------------------------------------------------------

template <int N>
struct Packet;

template <>
struct Packet<4> {
    using Ray = RTCRay4;
    using RayHit = RTCRayHit4;
    static void occluded(const int* valid, RTCScene s, RTCIntersectContext* c, Ray* r) {
        rtcOccluded4(valid, s, c, r);
    }
    static void intersect(const int* valid, RTCScene s, RTCIntersectContext* c, RayHit* r) {
        rtcIntersect4(valid, s, c, r);
    }
};
template <>
struct Packet<8> {
    using Ray = RTCRay8;
    using RayHit = RTCRayHit8;
    static void occluded(const int* valid, RTCScene s, RTCIntersectContext* c, Ray* r) {
        rtcOccluded8(valid, s, c, r);
    }
    static void intersect(const int* valid, RTCScene s, RTCIntersectContext* c, RayHit* r) {
        rtcIntersect8(valid, s, c, r);
    }
};
template <>
struct Packet<16> {
    using Ray = RTCRay16;
    using RayHit = RTCRayHit16;
    static void occluded(const int* valid, RTCScene s, RTCIntersectContext* c, Ray* r) {
        rtcOccluded16(valid, s, c, r);
    }
    static void intersect(const int* valid, RTCScene s, RTCIntersectContext* c, RayHit* r) {
        rtcIntersect16(valid, s, c, r);
    }
};

// Fills the per-ray constants of lane k of a packet ray.
template <typename R>
void initLane(R& r, int k, float tnear) {
    r.tnear[k] = tnear;
    r.time[k] = 0.0f;
    r.mask[k] = 0xffffffffu;
    r.id[k] = unsigned(k);
    r.flags[k] = 0u;
}

RTCIntersectContext makeContext(bool coherent) {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    ctx.flags = coherent ? RTC_INTERSECT_CONTEXT_FLAG_COHERENT
                         : RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
    return ctx;
}

void initSingleRay(RTCRay& r, const glm::vec3& org, const glm::vec3& dir, float tnear,
                   float tfar) {
    r.org_x = org.x;
    r.org_y = org.y;
    r.org_z = org.z;
    r.tnear = tnear;
    r.dir_x = dir.x;
    r.dir_y = dir.y;
    r.dir_z = dir.z;
    r.time = 0.0f;
    r.tfar = tfar;
    r.mask = 0xffffffffu;
    r.id = 0u;
    r.flags = 0u;
}

// Occlusion rays from one origin in packets of N consecutive directions. The tail
// packet repeats its last ray in the inactive lanes so that no lane holds garbage.
template <int N>
void occludedFromPointPackets(RTCScene scene, bool coherent, const glm::vec3& org,
                              const float* dx, const float* dy, const float* dz, size_t count,
                              float tnear, float tfar, uint8_t* out) {
    using P = Packet<N>;
    RTCIntersectContext ctx = makeContext(coherent);
    alignas(64) typename P::Ray ray;
    alignas(64) int valid[N];
    for (int k = 0; k < N; ++k) {
        ray.org_x[k] = org.x;
        ray.org_y[k] = org.y;
        ray.org_z[k] = org.z;
        initLane(ray, k, tnear);
    }
    for (size_t base = 0; base < count; base += N) {
        const int n = int(std::min<size_t>(N, count - base));
        for (int k = 0; k < N; ++k) {
            const size_t i = base + size_t(std::min(k, n - 1));
            ray.dir_x[k] = dx[i];
            ray.dir_y[k] = dy[i];
            ray.dir_z[k] = dz[i];
            ray.tfar[k] = tfar;
            valid[k] = k < n ? -1 : 0;
        }
        P::occluded(valid, scene, &ctx, &ray);
        for (int k = 0; k < n; ++k) out[base + size_t(k)] = ray.tfar[k] < 0.0f ? 1 : 0;
    }
}

// Occlusion rays with their own origins, in packets of N.
template <int N>
void occludedBatchPackets(RTCScene scene, const float* ox, const float* oy, const float* oz,
                          const float* dx, const float* dy, const float* dz, size_t count,
                          float tnear, float tfar, uint8_t* out, bool coherent) {
    using P = Packet<N>;
    RTCIntersectContext ctx = makeContext(coherent);
    alignas(64) typename P::Ray ray;
    alignas(64) int valid[N];
    for (int k = 0; k < N; ++k) initLane(ray, k, tnear);
    for (size_t base = 0; base < count; base += N) {
        const int n = int(std::min<size_t>(N, count - base));
        for (int k = 0; k < N; ++k) {
            const size_t i = base + size_t(std::min(k, n - 1));
            ray.org_x[k] = ox[i];
            ray.org_y[k] = oy[i];
            ray.org_z[k] = oz[i];
            ray.dir_x[k] = dx[i];
            ray.dir_y[k] = dy[i];
            ray.dir_z[k] = dz[i];
            ray.tfar[k] = tfar;
            valid[k] = k < n ? -1 : 0;
        }
        P::occluded(valid, scene, &ctx, &ray);
        for (int k = 0; k < n; ++k) out[base + size_t(k)] = ray.tfar[k] < 0.0f ? 1 : 0;
    }
}

// Chunk size of the stream kernels (rays per Embree call, kept on the stack).
constexpr size_t kStreamChunk = 256;

void occludedFromPointStream1M(RTCScene scene, bool coherent, const glm::vec3& org,
                               const float* dx, const float* dy, const float* dz, size_t count,
                               float tnear, float tfar, uint8_t* out) {
    RTCIntersectContext ctx = makeContext(coherent);
    RTCRay rays[kStreamChunk];
    for (size_t base = 0; base < count; base += kStreamChunk) {
        const size_t n = std::min(kStreamChunk, count - base);
        for (size_t k = 0; k < n; ++k)
            initSingleRay(rays[k], org, glm::vec3(dx[base + k], dy[base + k], dz[base + k]),
                          tnear, tfar);
        rtcOccluded1M(scene, &ctx, rays, unsigned(n), sizeof(RTCRay));
        for (size_t k = 0; k < n; ++k) out[base + k] = rays[k].tfar < 0.0f ? 1 : 0;
    }
}

void occludedFromPointStreamNp(RTCScene scene, bool coherent, const glm::vec3& org,
                               const float* dx, const float* dy, const float* dz, size_t count,
                               float tnear, float tfar, uint8_t* out) {
    RTCIntersectContext ctx = makeContext(coherent);
    alignas(64) float ox[kStreamChunk], oy[kStreamChunk], oz[kStreamChunk];
    alignas(64) float vx[kStreamChunk], vy[kStreamChunk], vz[kStreamChunk];
    alignas(64) float tn[kStreamChunk], tf[kStreamChunk], tm[kStreamChunk];
    alignas(64) unsigned mask[kStreamChunk], id[kStreamChunk], flags[kStreamChunk];
    for (size_t k = 0; k < kStreamChunk; ++k) {
        ox[k] = org.x;
        oy[k] = org.y;
        oz[k] = org.z;
        tn[k] = tnear;
        tm[k] = 0.0f;
        mask[k] = 0xffffffffu;
        id[k] = unsigned(k);
        flags[k] = 0u;
    }
    RTCRayNp rays;
    rays.org_x = ox;
    rays.org_y = oy;
    rays.org_z = oz;
    rays.tnear = tn;
    rays.dir_x = vx;
    rays.dir_y = vy;
    rays.dir_z = vz;
    rays.time = tm;
    rays.tfar = tf;
    rays.mask = mask;
    rays.id = id;
    rays.flags = flags;
    for (size_t base = 0; base < count; base += kStreamChunk) {
        const size_t n = std::min(kStreamChunk, count - base);
        std::memcpy(vx, dx + base, n * sizeof(float));
        std::memcpy(vy, dy + base, n * sizeof(float));
        std::memcpy(vz, dz + base, n * sizeof(float));
        std::fill(tf, tf + n, tfar);
        rtcOccludedNp(scene, &ctx, &rays, unsigned(n));
        for (size_t k = 0; k < n; ++k) out[base + k] = tf[k] < 0.0f ? 1 : 0;
    }
}

OcclusionKernel chooseDefaultKernel() {
    // The widest native packet, coherent: the fastest of the kernels in
    // Benchmark.DISABLED_OcclusionKernels (docs/performance.md, "Design measurements").
    const RayDeviceInfo& info = device().info;
    if (info.nativeRay16) return OcclusionKernel::Packet16;
    if (info.nativeRay8) return OcclusionKernel::Packet8;
    if (info.nativeRay4) return OcclusionKernel::Packet4;
    return OcclusionKernel::Single;
}

bool inactive(float tnear, float tfar) { return !(tnear <= tfar); }

}  // namespace

// ---------------------------------------------------------------------------
// Public free functions
// ---------------------------------------------------------------------------

RayDeviceInfo rayDeviceInfo() { return device().info; }

const char* toString(OcclusionKernel kernel) {
    switch (kernel) {
        case OcclusionKernel::Auto: return "auto";
        case OcclusionKernel::Single: return "single";
        case OcclusionKernel::Packet4: return "packet4";
        case OcclusionKernel::Packet8: return "packet8";
        case OcclusionKernel::Packet16: return "packet16";
        case OcclusionKernel::Stream1M: return "stream1M";
        case OcclusionKernel::StreamNp: return "streamNp";
    }
    return "?";
}

OcclusionKernel defaultOcclusionKernel() {
    static const OcclusionKernel k = chooseDefaultKernel();
    return k;
}

glm::vec3 offsetRayOrigin(const glm::vec3& p, const glm::vec3& geometricNormal,
                          const glm::vec3& dir, float scale) {
    const float magnitude =
        std::max({std::fabs(p.x), std::fabs(p.y), std::fabs(p.z), std::fabs(scale)});
    const float eps = kOffsetRelative * magnitude + kOffsetAbsolute;
    const float len = glm::length(geometricNormal);
    if (!(len > 0.0f)) return p;
    const glm::vec3 n = geometricNormal / len;
    const float side = glm::dot(dir, n) >= 0.0f ? eps : -eps;
    return p + side * n;
}

// ---------------------------------------------------------------------------
// RayScene
// ---------------------------------------------------------------------------

RayScene::RayScene(const TriangleMesh& mesh, const RaySceneOptions& options) {
    build(mesh.positions, mesh.triangles, options);
}

RayScene::RayScene(const std::vector<glm::vec3>& positions,
                   const std::vector<glm::uvec3>& triangles, const RaySceneOptions& options) {
    build(positions, triangles, options);
}

RayScene::~RayScene() { release(); }

RayScene::RayScene(RayScene&& other) noexcept
    : scene_(other.scene_),
      faceNormals_(std::move(other.faceNormals_)),
      boundsMin_(other.boundsMin_),
      boundsMax_(other.boundsMax_),
      coordinateScale_(other.coordinateScale_) {
    other.scene_ = nullptr;
    other.faceNormals_.clear();
}

RayScene& RayScene::operator=(RayScene&& other) noexcept {
    if (this != &other) {
        release();
        scene_ = other.scene_;
        faceNormals_ = std::move(other.faceNormals_);
        boundsMin_ = other.boundsMin_;
        boundsMax_ = other.boundsMax_;
        coordinateScale_ = other.coordinateScale_;
        other.scene_ = nullptr;
        other.faceNormals_.clear();
    }
    return *this;
}

void RayScene::release() noexcept {
    if (scene_) rtcReleaseScene(asScene(scene_));
    scene_ = nullptr;
}

void RayScene::build(const std::vector<glm::vec3>& positions,
                     const std::vector<glm::uvec3>& triangles, const RaySceneOptions& options) {
    if (positions.empty()) throw Error("ray scene", "the mesh has no vertices");
    if (triangles.empty()) throw Error("ray scene", "the mesh has no triangles");
    if (positions.size() > size_t(0xffffffffu) || triangles.size() > size_t(0xffffffffu))
        throw Error("ray scene", "the mesh is too large for 32-bit indices");

    boundsMin_ = glm::vec3(std::numeric_limits<float>::infinity());
    boundsMax_ = -boundsMin_;
    for (size_t i = 0; i < positions.size(); ++i) {
        const glm::vec3& p = positions[i];
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
            throw Error("ray scene", "vertex " + std::to_string(i) + " has a non-finite coordinate");
        boundsMin_ = glm::min(boundsMin_, p);
        boundsMax_ = glm::max(boundsMax_, p);
    }
    coordinateScale_ = std::max({std::fabs(boundsMin_.x), std::fabs(boundsMin_.y),
                                 std::fabs(boundsMin_.z), std::fabs(boundsMax_.x),
                                 std::fabs(boundsMax_.y), std::fabs(boundsMax_.z)});

    const size_t nv = positions.size();
    faceNormals_.resize(triangles.size());
    for (size_t t = 0; t < triangles.size(); ++t) {
        const glm::uvec3& tri = triangles[t];
        if (tri.x >= nv || tri.y >= nv || tri.z >= nv)
            throw Error("ray scene", "triangle " + std::to_string(t) +
                                         " refers to a vertex beyond the " + std::to_string(nv) +
                                         " vertices");
        const glm::dvec3 p0(positions[tri.x]), p1(positions[tri.y]), p2(positions[tri.z]);
        const glm::dvec3 c = glm::cross(p1 - p0, p2 - p0);
        const double len = glm::length(c);
        faceNormals_[t] = len > 0.0 ? glm::vec3(c / len) : glm::vec3(0.0f);
    }

    RTCDevice dev = device().handle;
    ErrorCapture capture;
    RTCScene scene = rtcNewScene(dev);
    capture.check("rtcNewScene");
    scene_ = scene;  // from here on release() cleans up if something throws
    try {
        RTCGeometry geom = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
        capture.check("rtcNewGeometry");
        struct GeometryRef {
            RTCGeometry g;
            ~GeometryRef() { rtcReleaseGeometry(g); }
        } geomRef{geom};

        // Copies: rtcSetNewGeometryBuffer pads vertex buffers for Embree's 16-byte loads.
        auto* vb = static_cast<float*>(rtcSetNewGeometryBuffer(
            geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), nv));
        capture.check("allocating the vertex buffer");
        std::memcpy(vb, positions.data(), nv * 3 * sizeof(float));
        static_assert(sizeof(glm::vec3) == 3 * sizeof(float));
        static_assert(sizeof(glm::uvec3) == 3 * sizeof(unsigned));
        auto* ib = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
            geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned),
            triangles.size()));
        capture.check("allocating the index buffer");
        std::memcpy(ib, triangles.data(), triangles.size() * 3 * sizeof(unsigned));

        const RTCBuildQuality quality = options.quality == RayBuildQuality::High
                                            ? RTC_BUILD_QUALITY_HIGH
                                            : RTC_BUILD_QUALITY_MEDIUM;
        rtcSetGeometryBuildQuality(geom, quality);
        rtcCommitGeometry(geom);
        capture.check("rtcCommitGeometry");
        rtcAttachGeometryByID(scene, geom, 0);
        capture.check("rtcAttachGeometry");

        rtcSetSceneBuildQuality(scene, quality);
        // The context filter of intersectBatchWithBeyond; it costs nothing measurable
        // on queries without one (docs/performance.md, "Design measurements").
        rtcSetSceneFlags(scene, RTCSceneFlags((options.robust ? RTC_SCENE_FLAG_ROBUST : RTC_SCENE_FLAG_NONE) |
                                              RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION));
        rtcCommitScene(scene);
        capture.check("building the BVH (rtcCommitScene)");
    } catch (...) {
        release();
        faceNormals_.clear();
        throw;
    }
}

float RayScene::epsilon() const { return kOffsetRelative * coordinateScale_ + kOffsetAbsolute; }

glm::vec3 RayScene::offsetRayOrigin(const glm::vec3& p, const glm::vec3& geometricNormal,
                                    const glm::vec3& dir) const {
    return prt::offsetRayOrigin(p, geometricNormal, dir, coordinateScale_);
}

void RayScene::fillHit(Hit& out, float t, uint32_t primID, float u, float v) const {
    out.hit = true;
    out.t = t;
    out.triangle = primID;
    out.u = u;
    out.v = v;
    out.geometricNormal = faceNormals_[primID];
}

bool RayScene::occluded(const glm::vec3& org, const glm::vec3& dir, float tnear,
                        float tfar) const {
    tnear = std::max(tnear, 0.0f);
    if (inactive(tnear, tfar)) return false;
    RTCIntersectContext ctx = makeContext(false);
    RTCRay ray;
    initSingleRay(ray, org, dir, tnear, tfar);
    rtcOccluded1(asScene(scene_), &ctx, &ray);
    return ray.tfar < 0.0f;
}

Hit RayScene::intersect(const glm::vec3& org, const glm::vec3& dir, float tnear,
                        float tfar) const {
    Hit result;
    tnear = std::max(tnear, 0.0f);
    if (inactive(tnear, tfar)) return result;
    RTCIntersectContext ctx = makeContext(false);
    RTCRayHit rh;
    initSingleRay(rh.ray, org, dir, tnear, tfar);
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(asScene(scene_), &ctx, &rh);
    if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID)
        fillHit(result, rh.ray.tfar, rh.hit.primID, rh.hit.u, rh.hit.v);
    return result;
}

void RayScene::occludedFromPoint(const glm::vec3& org, const float* dirX, const float* dirY,
                                 const float* dirZ, size_t count, float tnear, float tfar,
                                 uint8_t* occludedOut) const {
    occludedFromPointWith(OcclusionKernel::Auto, true, org, dirX, dirY, dirZ, count, tnear,
                          tfar, occludedOut);
}

void RayScene::occludedFromPointReference(const glm::vec3& org, const float* dirX,
                                          const float* dirY, const float* dirZ, size_t count,
                                          float tnear, float tfar, uint8_t* occludedOut) const {
    occludedFromPointWith(OcclusionKernel::Single, false, org, dirX, dirY, dirZ, count, tnear,
                          tfar, occludedOut);
}

void RayScene::occludedFromPointWith(OcclusionKernel kernel, bool coherent, const glm::vec3& org,
                                     const float* dirX, const float* dirY, const float* dirZ,
                                     size_t count, float tnear, float tfar,
                                     uint8_t* occludedOut) const {
    tnear = std::max(tnear, 0.0f);
    if (inactive(tnear, tfar)) {
        std::fill(occludedOut, occludedOut + count, uint8_t(0));
        return;
    }
    if (kernel == OcclusionKernel::Auto) kernel = defaultOcclusionKernel();
    RTCScene scene = asScene(scene_);
    switch (kernel) {
        case OcclusionKernel::Auto:  // resolved above
        case OcclusionKernel::Single: {
            RTCIntersectContext ctx = makeContext(coherent);
            RTCRay ray;
            for (size_t i = 0; i < count; ++i) {
                initSingleRay(ray, org, glm::vec3(dirX[i], dirY[i], dirZ[i]), tnear, tfar);
                rtcOccluded1(scene, &ctx, &ray);
                occludedOut[i] = ray.tfar < 0.0f ? 1 : 0;
            }
            return;
        }
        case OcclusionKernel::Packet4:
            occludedFromPointPackets<4>(scene, coherent, org, dirX, dirY, dirZ, count, tnear,
                                        tfar, occludedOut);
            return;
        case OcclusionKernel::Packet8:
            occludedFromPointPackets<8>(scene, coherent, org, dirX, dirY, dirZ, count, tnear,
                                        tfar, occludedOut);
            return;
        case OcclusionKernel::Packet16:
            occludedFromPointPackets<16>(scene, coherent, org, dirX, dirY, dirZ, count, tnear,
                                         tfar, occludedOut);
            return;
        case OcclusionKernel::Stream1M:
            occludedFromPointStream1M(scene, coherent, org, dirX, dirY, dirZ, count, tnear, tfar,
                                      occludedOut);
            return;
        case OcclusionKernel::StreamNp:
            occludedFromPointStreamNp(scene, coherent, org, dirX, dirY, dirZ, count, tnear, tfar,
                                      occludedOut);
            return;
    }
}

void RayScene::occludedBatch(const float* orgX, const float* orgY, const float* orgZ,
                             const float* dirX, const float* dirY, const float* dirZ,
                             size_t count, float tnear, float tfar,
                             uint8_t* occludedOut, bool coherent) const {
    tnear = std::max(tnear, 0.0f);
    if (inactive(tnear, tfar)) {
        std::fill(occludedOut, occludedOut + count, uint8_t(0));
        return;
    }
    RTCScene scene = asScene(scene_);
    switch (defaultOcclusionKernel()) {
        case OcclusionKernel::Packet16:
            occludedBatchPackets<16>(scene, orgX, orgY, orgZ, dirX, dirY, dirZ, count, tnear,
                                     tfar, occludedOut, coherent);
            return;
        case OcclusionKernel::Packet8:
            occludedBatchPackets<8>(scene, orgX, orgY, orgZ, dirX, dirY, dirZ, count, tnear,
                                     tfar, occludedOut, coherent);
            return;
        case OcclusionKernel::Packet4:
            occludedBatchPackets<4>(scene, orgX, orgY, orgZ, dirX, dirY, dirZ, count, tnear,
                                     tfar, occludedOut, coherent);
            return;
        default:
            for (size_t i = 0; i < count; ++i)
                occludedOut[i] = occluded(glm::vec3(orgX[i], orgY[i], orgZ[i]),
                                          glm::vec3(dirX[i], dirY[i], dirZ[i]), tnear, tfar)
                                     ? 1
                                     : 0;
            return;
    }
}

namespace {

// Loads rays [base, base + N) of the arrays into a hit packet (the tail packet repeats
// its last ray in the inactive lanes, so no lane holds garbage) with tfar and no hit;
// valid[k] = -1 for the active lanes. Returns the number of active lanes.
template <int N, typename RayHit>
int loadRayHitPacket(RayHit& rh, int* valid, size_t base, size_t count, const float* ox, const float* oy,
                     const float* oz, const float* dx, const float* dy, const float* dz, float tfar) {
    const int n = int(std::min<size_t>(N, count - base));
    for (int k = 0; k < N; ++k) {
        const size_t i = base + size_t(std::min(k, n - 1));
        rh.ray.org_x[k] = ox[i];
        rh.ray.org_y[k] = oy[i];
        rh.ray.org_z[k] = oz[i];
        rh.ray.dir_x[k] = dx[i];
        rh.ray.dir_y[k] = dy[i];
        rh.ray.dir_z[k] = dz[i];
        rh.ray.tfar[k] = tfar;
        rh.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
        rh.hit.primID[k] = RTC_INVALID_GEOMETRY_ID;
        rh.hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID;
        valid[k] = k < n ? -1 : 0;
    }
    return n;
}

template <int N, typename FillHit>
void intersectBatchPackets(RTCScene scene, const float* ox, const float* oy, const float* oz,
                           const float* dx, const float* dy, const float* dz, size_t count,
                           float tnear, float tfar, Hit* out, const FillHit& fill, bool coherent) {
    using P = Packet<N>;
    RTCIntersectContext ctx = makeContext(coherent);
    alignas(64) typename P::RayHit rh;
    alignas(64) int valid[N];
    for (int k = 0; k < N; ++k) initLane(rh.ray, k, tnear);
    for (size_t base = 0; base < count; base += N) {
        const int n = loadRayHitPacket<N>(rh, valid, base, count, ox, oy, oz, dx, dy, dz, tfar);
        P::intersect(valid, scene, &ctx, &rh);
        for (int k = 0; k < n; ++k) {
            Hit& h = out[base + size_t(k)];
            h = Hit{};
            if (rh.hit.geomID[k] != RTC_INVALID_GEOMETRY_ID)
                fill(h, rh.ray.tfar[k], rh.hit.primID[k], rh.hit.u[k], rh.hit.v[k]);
        }
    }
}

// intersectBatchWithBeyond's per-ray record of the hits the traversal reported, and
// its context (RTCIntersectContext first, so the filter can cast back to it).
struct BeyondLane {
    float tMin, tMax;  // the closest and the farthest hit reported
    uint32_t prim;     // the closest hit's triangle and barycentrics
    float u, v;
    bool any, beyond;
};
struct BeyondContext {
    RTCIntersectContext base;
    BeyondLane* lanes;  // indexed by the ray's id (the lane of the packet passed to Embree)
    float separation;
};

// Records every reported hit and rejects it, until the ray has two hits more than
// `separation` apart: that one is accepted, so the ray's tfar drops to it and the
// traversal only reports closer hits from then on (which are recorded and rejected).
// Embree may call this with any packet size (1, 4, 8, 16), so lanes go by ray id.
// Bit i set for the lanes i < n (n <= 32; Embree passes 1, 4, 8 or 16) with
// valid[i] == -1: the filter's loop then visits only the lanes that hit (usually a
// few of 16).
uint32_t validLanes(const int* valid, unsigned n) {
    uint32_t bits = 0;
    unsigned i = 0;
#if defined(__SSE2__)
    const __m128i all = _mm_set1_epi32(-1);
    for (; i + 4 <= n; i += 4) {
        const __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(valid + i));
        bits |= uint32_t(_mm_movemask_ps(_mm_castsi128_ps(_mm_cmpeq_epi32(v, all)))) << i;
    }
#endif
    for (; i < n; ++i) bits |= uint32_t(valid[i] == -1) << i;
    return bits;
}

void beyondFilter(const RTCFilterFunctionNArguments* args) {
    const BeyondContext* ctx = reinterpret_cast<const BeyondContext*>(args->context);
    for (uint32_t bits = validLanes(args->valid, args->N); bits != 0; bits &= bits - 1) {
        const unsigned i = unsigned(__builtin_ctz(bits));
        BeyondLane& lane = ctx->lanes[RTCRayN_id(args->ray, args->N, i)];
        const float t = RTCRayN_tfar(args->ray, args->N, i);
        if (!lane.any || t < lane.tMin) {
            lane.prim = RTCHitN_primID(args->hit, args->N, i);
            lane.u = RTCHitN_u(args->hit, args->N, i);
            lane.v = RTCHitN_v(args->hit, args->N, i);
        }
        lane.tMin = lane.any ? std::min(lane.tMin, t) : t;
        lane.tMax = lane.any ? std::max(lane.tMax, t) : t;
        lane.any = true;
        if (!lane.beyond && lane.tMax - lane.tMin > ctx->separation) {
            lane.beyond = true;  // accept: tfar = t from here on
            continue;
        }
        args->valid[i] = 0;
    }
}

BeyondContext makeBeyondContext(bool coherent, BeyondLane* lanes, float separation) {
    BeyondContext ctx;
    ctx.base = makeContext(coherent);
    ctx.base.filter = beyondFilter;
    ctx.lanes = lanes;
    ctx.separation = separation;
    return ctx;
}

template <int N, typename FillHit>
void intersectWithBeyondPackets(RTCScene scene, const float* ox, const float* oy, const float* oz,
                                const float* dx, const float* dy, const float* dz, size_t count,
                                float tnear, float separation, Hit* out, uint8_t* beyond,
                                const FillHit& fill, bool coherent) {
    using P = Packet<N>;
    BeyondLane lanes[N];
    BeyondContext ctx = makeBeyondContext(coherent, lanes, separation);
    alignas(64) typename P::RayHit rh;
    alignas(64) int valid[N];
    for (int k = 0; k < N; ++k) initLane(rh.ray, k, tnear);
    for (size_t base = 0; base < count; base += N) {
        const int n = loadRayHitPacket<N>(rh, valid, base, count, ox, oy, oz, dx, dy, dz,
                                          std::numeric_limits<float>::infinity());
        for (int k = 0; k < N; ++k) lanes[k].any = lanes[k].beyond = false;
        P::intersect(valid, scene, &ctx.base, &rh);
        for (int k = 0; k < n; ++k) {
            Hit& h = out[base + size_t(k)];
            h = Hit{};
            if (lanes[k].any) fill(h, lanes[k].tMin, lanes[k].prim, lanes[k].u, lanes[k].v);
            beyond[base + size_t(k)] = lanes[k].beyond ? 1 : 0;
        }
    }
}

}  // namespace

void RayScene::intersectBatchWithBeyond(const float* orgX, const float* orgY, const float* orgZ,
                                        const float* dirX, const float* dirY, const float* dirZ,
                                        size_t count, float tnear, float separation, Hit* hitsOut,
                                        uint8_t* beyondOut, bool coherent,
                                        OcclusionKernel kernel) const {
    if (kernel == OcclusionKernel::Stream1M || kernel == OcclusionKernel::StreamNp)
        throw std::invalid_argument("intersectBatchWithBeyond: stream kernels are not supported");
    if (kernel == OcclusionKernel::Auto) kernel = defaultOcclusionKernel();
    tnear = std::max(tnear, 0.0f);
    separation = std::max(separation, 0.0f);
    RTCScene scene = asScene(scene_);
    auto fill = [this](Hit& h, float t, uint32_t prim, float u, float v) {
        fillHit(h, t, prim, u, v);
    };
    switch (kernel) {
        case OcclusionKernel::Packet16:
            intersectWithBeyondPackets<16>(scene, orgX, orgY, orgZ, dirX, dirY, dirZ, count, tnear,
                                           separation, hitsOut, beyondOut, fill, coherent);
            return;
        case OcclusionKernel::Packet8:
            intersectWithBeyondPackets<8>(scene, orgX, orgY, orgZ, dirX, dirY, dirZ, count, tnear,
                                          separation, hitsOut, beyondOut, fill, coherent);
            return;
        case OcclusionKernel::Packet4:
            intersectWithBeyondPackets<4>(scene, orgX, orgY, orgZ, dirX, dirY, dirZ, count, tnear,
                                          separation, hitsOut, beyondOut, fill, coherent);
            return;
        default: {  // Single (no native packets): single rays through the same filter (N = 1, id 0)
            BeyondLane lane;
            BeyondContext ctx = makeBeyondContext(coherent, &lane, separation);
            for (size_t i = 0; i < count; ++i) {
                RTCRayHit rh;
                initSingleRay(rh.ray, glm::vec3(orgX[i], orgY[i], orgZ[i]), glm::vec3(dirX[i], dirY[i], dirZ[i]),
                              tnear, std::numeric_limits<float>::infinity());
                rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
                rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
                rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
                lane.any = lane.beyond = false;
                rtcIntersect1(scene, &ctx.base, &rh);
                hitsOut[i] = Hit{};
                if (lane.any) fill(hitsOut[i], lane.tMin, lane.prim, lane.u, lane.v);
                beyondOut[i] = lane.beyond ? 1 : 0;
            }
            return;
        }
    }
}

void RayScene::intersectWithBeyondReference(const float* orgX, const float* orgY, const float* orgZ,
                                            const float* dirX, const float* dirY, const float* dirZ,
                                            size_t count, float tnear, float separation, Hit* hitsOut,
                                            uint8_t* beyondOut) const {
    separation = std::max(separation, 0.0f);
    const float inf = std::numeric_limits<float>::infinity();
    for (size_t i = 0; i < count; ++i) {
        const glm::vec3 org(orgX[i], orgY[i], orgZ[i]), dir(dirX[i], dirY[i], dirZ[i]);
        hitsOut[i] = intersect(org, dir, tnear, inf);
        beyondOut[i] = hitsOut[i].hit && occluded(org, dir, hitsOut[i].t + separation, inf) ? 1 : 0;
    }
}

void RayScene::intersectBatch(const float* orgX, const float* orgY, const float* orgZ,
                              const float* dirX, const float* dirY, const float* dirZ,
                              size_t count, float tnear, float tfar, Hit* hitsOut,
                              bool coherent) const {
    tnear = std::max(tnear, 0.0f);
    if (inactive(tnear, tfar)) {
        std::fill(hitsOut, hitsOut + count, Hit{});
        return;
    }
    RTCScene scene = asScene(scene_);
    auto fill = [this](Hit& h, float t, uint32_t prim, float u, float v) {
        fillHit(h, t, prim, u, v);
    };
    switch (defaultOcclusionKernel()) {
        case OcclusionKernel::Packet16:
            intersectBatchPackets<16>(scene, orgX, orgY, orgZ, dirX, dirY, dirZ, count, tnear,
                                      tfar, hitsOut, fill, coherent);
            return;
        case OcclusionKernel::Packet8:
            intersectBatchPackets<8>(scene, orgX, orgY, orgZ, dirX, dirY, dirZ, count, tnear,
                                      tfar, hitsOut, fill, coherent);
            return;
        case OcclusionKernel::Packet4:
            intersectBatchPackets<4>(scene, orgX, orgY, orgZ, dirX, dirY, dirZ, count, tnear,
                                      tfar, hitsOut, fill, coherent);
            return;
        default:
            for (size_t i = 0; i < count; ++i)
                hitsOut[i] = intersect(glm::vec3(orgX[i], orgY[i], orgZ[i]),
                                       glm::vec3(dirX[i], dirY[i], dirZ[i]), tnear, tfar);
            return;
    }
}

}  // namespace prt
