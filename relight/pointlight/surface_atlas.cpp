#include "relight/pointlight/surface_atlas.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>
#include <string>

#include "common/error.h"
#include "common/util.h"

namespace prt {

namespace {

// A triangle laid out isometrically in its own 2D frame (mm): base from (0, 0) to
// (base, 0) along its longest edge, apex at (apexX, height), apexX in [0, base].
struct Chart {
    uint32_t triangle = 0;
    int baseCorner = 0;  // the base runs from corner baseCorner to corner baseCorner + 1 (mod 3)
    double base = 0.0, height = 0.0, apexX = 0.0;
    double x = 0.0, y = 0.0;  // packed position of the rectangle's lower-left corner (mm, before scaling)
};

Chart makeChart(const TriangleMesh& mesh, uint32_t f) {
    const glm::uvec3 t = mesh.triangles[f];
    const std::array<glm::dvec3, 3> p{glm::dvec3(mesh.positions[t.x]), glm::dvec3(mesh.positions[t.y]),
                                      glm::dvec3(mesh.positions[t.z])};
    Chart c;
    c.triangle = f;
    double longest = -1.0;
    for (int k = 0; k < 3; ++k) {
        const double len = glm::length(p[(k + 1) % 3] - p[k]);
        if (len > longest) {
            longest = len;
            c.baseCorner = k;
        }
    }
    const glm::dvec3 a = p[c.baseCorner], b = p[(c.baseCorner + 1) % 3], apex = p[(c.baseCorner + 2) % 3];
    c.base = longest;
    const glm::dvec3 e = (b - a) / longest;
    c.apexX = std::clamp(glm::dot(apex - a, e), 0.0, longest);
    c.height = glm::length(glm::cross(b - a, apex - a)) / longest;
    return c;
}

// Shelf packing of the charts' rectangles (in the given order) into a square of side
// `side` mm. Returns false when they do not fit.
bool shelfPack(std::vector<Chart>& charts, double side) {
    double x = 0.0, y = 0.0, shelf = 0.0;
    for (Chart& c : charts) {
        if (c.base > side) return false;
        if (x + c.base > side) {
            y += shelf;
            x = 0.0;
            shelf = 0.0;
        }
        if (shelf == 0.0) shelf = c.height;  // the first (tallest) chart of a shelf sets its height
        if (y + c.height > side) return false;
        c.x = x;
        c.y = y;
        x += c.base;
    }
    return true;
}

// Convex polygon clipping (Sutherland-Hodgman) of a triangle against the square
// [x0, x0 + 1] x [y0, y0 + 1] (texel units).
struct Poly {
    std::array<glm::dvec2, 9> v;
    int n = 0;
};

Poly clipAxis(const Poly& in, int axis, double bound, bool keepBelow) {
    Poly out;
    for (int i = 0; i < in.n; ++i) {
        const glm::dvec2 a = in.v[i], b = in.v[(i + 1) % in.n];
        const double da = keepBelow ? bound - a[axis] : a[axis] - bound;
        const double db = keepBelow ? bound - b[axis] : b[axis] - bound;
        if (da >= 0.0) out.v[out.n++] = a;
        if ((da >= 0.0) != (db >= 0.0)) {
            const double t = da / (da - db);
            out.v[out.n++] = a + t * (b - a);
        }
    }
    return out;
}

// Area and centroid of the part of triangle tri (texel units) inside texel (i, j).
double clipToTexel(const std::array<glm::dvec2, 3>& tri, int i, int j, glm::dvec2* centroid) {
    Poly p;
    p.n = 3;
    for (int k = 0; k < 3; ++k) p.v[k] = tri[k];
    p = clipAxis(p, 0, double(i), false);
    if (p.n < 3) return 0.0;
    p = clipAxis(p, 0, double(i + 1), true);
    if (p.n < 3) return 0.0;
    p = clipAxis(p, 1, double(j), false);
    if (p.n < 3) return 0.0;
    p = clipAxis(p, 1, double(j + 1), true);
    if (p.n < 3) return 0.0;
    double area2 = 0.0;
    glm::dvec2 c(0.0);
    for (int k = 0; k < p.n; ++k) {
        const glm::dvec2 a = p.v[k], b = p.v[(k + 1) % p.n];
        const double cr = a.x * b.y - b.x * a.y;
        area2 += cr;
        c += (a + b) * cr;
    }
    if (!(std::abs(area2) > 0.0)) return 0.0;
    if (centroid) *centroid = c / (3.0 * area2);
    return 0.5 * std::abs(area2);
}

struct Piece {
    uint32_t texel;
    float area;         // texel units^2
    glm::vec2 centroid;  // texel units
};

// Every texel piece of triangle f (texel units), in row-major texel order.
template <class Fn>
void forEachPiece(const SurfaceAtlas& atlas, uint32_t f, Fn&& fn) {
    const double r = double(atlas.resolution);
    const std::array<glm::dvec2, 3> tri{glm::dvec2(atlas.cornerUv[3 * f]) * r, glm::dvec2(atlas.cornerUv[3 * f + 1]) * r,
                                        glm::dvec2(atlas.cornerUv[3 * f + 2]) * r};
    const glm::dvec2 lo = glm::min(tri[0], glm::min(tri[1], tri[2]));
    const glm::dvec2 hi = glm::max(tri[0], glm::max(tri[1], tri[2]));
    const int i0 = std::clamp(int(std::floor(lo.x)), 0, atlas.resolution - 1);
    const int i1 = std::clamp(int(std::floor(hi.x)), 0, atlas.resolution - 1);
    const int j0 = std::clamp(int(std::floor(lo.y)), 0, atlas.resolution - 1);
    const int j1 = std::clamp(int(std::floor(hi.y)), 0, atlas.resolution - 1);
    for (int j = j0; j <= j1; ++j)
        for (int i = i0; i <= i1; ++i) {
            glm::dvec2 c;
            const double a = clipToTexel(tri, i, j, &c);
            if (a > 0.0) fn(uint32_t(j) * uint32_t(atlas.resolution) + uint32_t(i), a, c);
        }
}

}  // namespace

void validateAtlasResolution(int resolution, const char* option) {
    if (resolution < 16 || resolution > 8192 || (resolution & (resolution - 1)) != 0)
        throw Error(option, "must be a power of two from 16 to 8192, got " + std::to_string(resolution));
}

SurfaceAtlas buildSurfaceAtlas(const TriangleMesh& mesh, int resolution) {
    const Stopwatch clock;
    validateAtlasResolution(resolution, "atlas resolution");
    const size_t nv = mesh.positions.size(), nf = mesh.triangleCount();
    for (const glm::vec3& p : mesh.positions)
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
            throw Error("mesh", "a vertex position is not finite");
    for (size_t f = 0; f < nf; ++f) {
        const glm::uvec3 t = mesh.triangles[f];
        if (t.x >= nv || t.y >= nv || t.z >= nv)
            throw Error("mesh", "triangle " + std::to_string(f) + " has a vertex index out of range");
    }

    SurfaceAtlas atlas;
    atlas.resolution = resolution;
    atlas.cornerUv.assign(3 * nf, glm::vec2(0.0f));
    SurfaceAtlasStats& st = atlas.stats;

    // Charts, tallest first (ties by triangle index: a fixed order).
    std::vector<Chart> charts;
    charts.reserve(nf);
    double rectArea = 0.0;
    for (size_t f = 0; f < nf; ++f) {
        const double area = double(faceArea(mesh, f));
        st.meshAreaMm2 += area;
        if (!(area > 0.0)) {
            ++st.skippedTriangles;
            continue;
        }
        charts.push_back(makeChart(mesh, uint32_t(f)));
        rectArea += charts.back().base * charts.back().height;
    }
    if (charts.empty()) throw Error("mesh", "no triangle has a positive area; nothing to map");
    std::stable_sort(charts.begin(), charts.end(), [](const Chart& a, const Chart& b) { return a.height > b.height; });

    // The largest scale at which the shelves fit the unit square: bisection on the
    // square's side in mm (the packing of a side that fits is kept).
    double lo = std::sqrt(rectArea), hi = lo;
    while (!shelfPack(charts, hi)) hi *= 1.25;
    std::vector<Chart> best = charts;
    for (int it = 0; it < 40 && hi > lo * (1.0 + 1e-4); ++it) {
        const double mid = 0.5 * (lo + hi);
        if (shelfPack(charts, mid)) {
            hi = mid;
            best = charts;
        } else {
            lo = mid;
        }
    }
    if (!shelfPack(best, hi)) throw Error("atlas", "internal error: the final packing does not fit");
    // A hair of slack so that no corner lands exactly on u = 1 after rounding.
    const double s = (1.0 - 1e-6) / hi;
    st.scale = s;

    st.minDistortion = 1e300;
    st.maxDistortion = 0.0;
    for (const Chart& c : best) {
        const int k0 = c.baseCorner, k1 = (k0 + 1) % 3, k2 = (k0 + 2) % 3;
        glm::vec2* uv = &atlas.cornerUv[3 * size_t(c.triangle)];
        uv[k0] = glm::vec2(glm::dvec2(c.x, c.y) * s);
        uv[k1] = glm::vec2(glm::dvec2(c.x + c.base, c.y) * s);
        uv[k2] = glm::vec2(glm::dvec2(c.x + c.apexX, c.y + c.height) * s);
        const glm::dvec2 e1 = glm::dvec2(uv[k1] - uv[k0]), e2 = glm::dvec2(uv[k2] - uv[k0]);
        const double textureArea = 0.5 * std::abs(e1.x * e2.y - e1.y * e2.x);
        const double ratio = textureArea / (s * s * double(faceArea(mesh, c.triangle)));
        st.minDistortion = std::min(st.minDistortion, ratio);
        st.maxDistortion = std::max(st.maxDistortion, ratio);
    }
    st.triangles = best.size();

    // Clip every chart against its texels (parallel), then accumulate per texel in
    // triangle order (deterministic).
    std::vector<std::vector<Piece>> pieces(nf);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, best.size(), 512), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t k = r.begin(); k != r.end(); ++k) {
            const uint32_t f = best[k].triangle;
            forEachPiece(atlas, f, [&](uint32_t texel, double area, glm::dvec2 c) {
                pieces[f].push_back({texel, float(area), glm::vec2(c)});
            });
        }
    });
    const size_t texels = atlas.texelCount();
    const double texelToMm2 = 1.0 / (s * s * double(resolution) * double(resolution));
    std::vector<double> area(texels, 0.0);
    std::vector<float> bestArea(texels, 0.0f);
    std::vector<uint32_t> bestTriangle(texels, kNoTriangle);
    std::vector<glm::vec2> bestCentroid(texels, glm::vec2(0.0f));
    double texelsPerTriangle = 0.0;
    for (size_t f = 0; f < nf; ++f) {
        double sum = 0.0;
        for (const Piece& p : pieces[f]) {
            area[p.texel] += double(p.area) * texelToMm2;
            sum += p.area;
            if (p.area > bestArea[p.texel]) {
                bestArea[p.texel] = p.area;
                bestTriangle[p.texel] = uint32_t(f);
                bestCentroid[p.texel] = p.centroid;
            }
        }
        if (!pieces[f].empty()) {
            texelsPerTriangle += sum;
            if (sum < 1.0) ++st.subTexelTriangles;
        }
    }
    pieces.clear();
    pieces.shrink_to_fit();
    st.meanTexelsPerTriangle = texelsPerTriangle / double(best.size());

    // The texel samples: surface point at the centroid of the largest piece.
    const bool haveNormals = mesh.normals.size() == nv;
    atlas.texelArea.assign(texels, 0.0f);
    atlas.texelSample.assign(texels, SurfaceAtlas::kNoSample);
    IrradianceSamples& smp = atlas.samples;
    const double r = double(resolution);
    // Samples in triangle order (texel order within a triangle): neighbouring samples are
    // neighbouring surface points, so the irradiance map's shadow rays, traced in
    // packets of consecutive samples, are coherent.
    std::vector<uint32_t> covered;
    for (size_t t = 0; t < texels; ++t)
        if (bestTriangle[t] != kNoTriangle) covered.push_back(uint32_t(t));
    std::stable_sort(covered.begin(), covered.end(),
                     [&](uint32_t a, uint32_t b) { return bestTriangle[a] < bestTriangle[b]; });
    for (const uint32_t t : covered) {
        const uint32_t f = bestTriangle[t];
        const glm::uvec3 tri = mesh.triangles[f];
        const glm::dvec2 a = glm::dvec2(atlas.cornerUv[3 * f]) * r, b = glm::dvec2(atlas.cornerUv[3 * f + 1]) * r,
                         c = glm::dvec2(atlas.cornerUv[3 * f + 2]) * r;
        const glm::dvec2 q = glm::dvec2(bestCentroid[t]);
        const double det = (b.x - a.x) * (c.y - a.y) - (c.x - a.x) * (b.y - a.y);
        double w1 = ((q.x - a.x) * (c.y - a.y) - (c.x - a.x) * (q.y - a.y)) / det;
        double w2 = ((b.x - a.x) * (q.y - a.y) - (q.x - a.x) * (b.y - a.y)) / det;
        w1 = std::clamp(w1, 0.0, 1.0);
        w2 = std::clamp(w2, 0.0, 1.0 - w1);
        const double w0 = 1.0 - w1 - w2;
        const glm::dvec3 p = w0 * glm::dvec3(mesh.positions[tri.x]) + w1 * glm::dvec3(mesh.positions[tri.y]) +
                             w2 * glm::dvec3(mesh.positions[tri.z]);
        const glm::vec3 ng = faceNormal(mesh, f);
        glm::vec3 n = ng;
        if (haveNormals) {
            const glm::vec3 sum = float(w0) * mesh.normals[tri.x] + float(w1) * mesh.normals[tri.y] +
                                  float(w2) * mesh.normals[tri.z];
            const float len = glm::length(sum);
            if (len > 1e-12f && glm::dot(sum, ng) > 0.0f) n = sum / len;
        }
        atlas.texelArea[t] = float(area[t]);
        atlas.texelSample[t] = uint32_t(smp.positions.size());
        atlas.sampleTexel.push_back(uint32_t(t));
        smp.positions.emplace_back(p);
        smp.normals.push_back(n);
        smp.geometricNormals.push_back(ng);
        smp.areas.push_back(float(area[t]));
        smp.triangles.push_back(f);
        st.mappedAreaMm2 += area[t];
    }
    smp.irradiance.assign(smp.positions.size(), glm::vec3(0.0f));
    st.coveredTexels = smp.positions.size();
    st.coverage = double(st.coveredTexels) / double(texels);
    st.buildSeconds = clock.seconds();
    return atlas;
}

std::vector<double> atlasTriangleAreas(const TriangleMesh& mesh, const SurfaceAtlas& atlas) {
    const double s = atlas.stats.scale;
    const double texelToMm2 = 1.0 / (s * s * double(atlas.resolution) * double(atlas.resolution));
    std::vector<double> out(mesh.triangleCount(), 0.0);
    for (size_t f = 0; f < mesh.triangleCount(); ++f)
        forEachPiece(atlas, uint32_t(f), [&](uint32_t, double a, glm::dvec2) { out[f] += a * texelToMm2; });
    return out;
}

}  // namespace prt
