
uniform usampler2D uVisibility; // R32UI: triangle index + 1 seen by the pixel, 0 = none
uniform sampler2D uEnvironment; // the lat-long map; GL_LINEAR, s repeats, t clamps
uniform int uRowWidth;         // texels per row of the per-vertex and per-triangle textures
uniform sampler2D uPositions;  // RGBA32F, vertex v at (v % uRowWidth, v / uRowWidth), mm
uniform sampler2D uNormals;    // RGBA32F, unit vertex normals, same layout
uniform usampler2D uTriangles; // RGBA32UI, triangle t's vertex indices at (t % uRowWidth, t / uRowWidth)
uniform sampler2D uRadiance;   // RGBA32F; slot s (0 = diffuse, 1 + k = term k) starts at row s * uSlotRows
uniform int uSlotRows;
uniform int uTermCount;        // K used (0: no view-dependent single scattering)
uniform sampler2D uViewMaps;   // R32F, N x 6NK: texel (i, (k * 6 + face) * N + j) = h_k
uniform int uViewMapSize;
uniform float uEta;
uniform float uEyePath[65];    // EyePathTable (eye_path.h): the eye's-path factor at cos_o' = i / 64
uniform int uObjectTriangles;  // triangles past these are the ground's (its radiance in slot 0)
uniform bool uSpecular;
uniform bool uBackground;      // false: black background (the environment's light is off)
uniform sampler2D uPrefiltered;
uniform bool uHasBaseColour;         // the object's base colour tints the translucent part
uniform sampler2D uTriangleColours;  // RGBA32F per triangle: the factor, A = 1 where the texture applies
uniform sampler2D uCornerUvs;        // RGBA32F, corner k of triangle t at index 3 t + k: (u, v)
uniform sampler2D uBaseTexture;      // RGBA32F, linear, row 0 the top of the image (v = 1)
uniform ivec2 uBaseSize;             // its width, height
uniform ivec2 uBaseWrap;             // TextureWrap per axis: 0 repeat, 1 clamp to edge, 2 mirrored repeat
uniform int uPointLightCount;        // the point lights' specular: its lights (0: none)
uniform sampler2D uPointLights;      // RGBA32F, light l at (l, 0): position mm (w = 0) or direction toward it (w = 1)
uniform sampler2D uPointIrradiance;  // RGBA32F, light l's shadowed irradiance at vertex v in slot l (uSlotRows rows)
uniform float uPointRoughness;       // GGX alpha
uniform float uPointEta;

ivec3 gTriangle;
vec3 gBarycentric;

ivec2 at(int i) { return ivec2(i % uRowWidth, i / uRowWidth); }
vec3 radianceAt(int slot, int v) {
    return texelFetch(uRadiance, ivec2(v % uRowWidth, slot * uSlotRows + v / uRowWidth), 0).rgb;
}
vec3 interpolated(int slot) {
    return gBarycentric.x * radianceAt(slot, gTriangle.x) + gBarycentric.y * radianceAt(slot, gTriangle.y) +
           gBarycentric.z * radianceAt(slot, gTriangle.z);
}

// Barycentrics (1 - u - v, u, v) of the point where the ray eye + s d meets triangle
// `triangle` (Moller-Trumbore), clamped into the triangle.
void findTriangle(int triangle, vec3 d) {
    gTriangle = ivec3(texelFetch(uTriangles, at(triangle), 0).xyz);
    vec3 p0 = texelFetch(uPositions, at(gTriangle.x), 0).xyz;
    vec3 e1 = texelFetch(uPositions, at(gTriangle.y), 0).xyz - p0;
    vec3 e2 = texelFetch(uPositions, at(gTriangle.z), 0).xyz - p0;
    vec3 pv = cross(d, e2);
    float det = dot(e1, pv);
    vec3 tv = uEye - p0;
    float u = dot(tv, pv) / det, v = dot(d, cross(tv, e1)) / det;
    vec3 b = max(vec3(1.0 - u - v, u, v), vec3(0.0));
    float sum = b.x + b.y + b.z;
    gBarycentric = sum > 0.0 && !isinf(sum) ? b / sum : vec3(1.0 / 3.0);
}

// wrapIndex (asset_io.cpp): texel index i of n under a glTF wrap mode.
int floorMod(int i, int n) { return i - n * int(floor(float(i) / float(n))); }
int wrapIndex(int i, int n, int mode) {
    if (mode == 1) return clamp(i, 0, n - 1);
    if (mode == 2) {
        int m = floorMod(i, 2 * n);
        return m < n ? m : 2 * n - 1 - m;
    }
    return floorMod(i, n);
}

// baseColorAt (asset_io.cpp): the factor times the bilinear texel at the interpolated
// texture coordinate (sampleTexture: texel centres, row 0 at v = 1).
vec3 baseColour(int triangle) {
    vec4 f = texelFetch(uTriangleColours, at(triangle), 0);
    if (f.a < 0.5) return f.rgb;
    vec2 uv = gBarycentric.x * texelFetch(uCornerUvs, at(3 * triangle), 0).xy +
              gBarycentric.y * texelFetch(uCornerUvs, at(3 * triangle + 1), 0).xy +
              gBarycentric.z * texelFetch(uCornerUvs, at(3 * triangle + 2), 0).xy;
    if (isnan(uv.x) || isnan(uv.y)) return f.rgb;
    float s = uv.x * float(uBaseSize.x) - 0.5, t = (1.0 - uv.y) * float(uBaseSize.y) - 0.5;
    float s0 = floor(s), t0 = floor(t);
    float fx = s - s0, fy = t - t0;
    int xa = wrapIndex(int(s0), uBaseSize.x, uBaseWrap.x), xb = wrapIndex(int(s0) + 1, uBaseSize.x, uBaseWrap.x);
    int ya = wrapIndex(int(t0), uBaseSize.y, uBaseWrap.y), yb = wrapIndex(int(t0) + 1, uBaseSize.y, uBaseWrap.y);
    vec3 top = mix(texelFetch(uBaseTexture, ivec2(xa, ya), 0).rgb, texelFetch(uBaseTexture, ivec2(xb, ya), 0).rgb, fx);
    vec3 bottom =
        mix(texelFetch(uBaseTexture, ivec2(xa, yb), 0).rgb, texelFetch(uBaseTexture, ivec2(xb, yb), 0).rgb, fx);
    return f.rgb * mix(top, bottom, fy);
}

// fresnelReflectance (bssrdf.cpp): exact unpolarised dielectric reflectance.
float fresnelReflectance(float eta, float cosThetaI) {
    if (eta == 1.0) return 0.0;
    float ci = min(abs(cosThetaI), 1.0);
    float sin2t = (1.0 - ci * ci) / (eta * eta);
    if (sin2t >= 1.0) return 1.0;
    float ct = sqrt(1.0 - sin2t);
    float rs = (ci - eta * ct) / (ci + eta * ct);
    float rp = (eta * ci - ct) / (eta * ci + ct);
    return 0.5 * (rs * rs + rp * rp);
}

// refractDirection (bssrdf.cpp): w away from the surface outside, result into the medium.
bool refractDirection(vec3 w, vec3 n, float eta, out vec3 wt) {
    wt = vec3(0.0);
    float lw = length(w), ln = length(n);
    if (!(lw > 0.0) || !(ln > 0.0)) return false;
    vec3 wi = w / lw;
    vec3 nn = n / ln;
    float ci = dot(wi, nn);
    if (ci < 0.0) return false;
    float c = min(ci, 1.0);
    float sin2t = (1.0 - c * c) / (eta * eta);
    if (sin2t >= 1.0) return false;
    float ct = sqrt(1.0 - sin2t);
    wt = normalize(-wi / eta + (c / eta - ct) * nn);
    return true;
}

// specularBrdf (point_specular.cpp): GGX with the exact Fresnel reflectance at w_i . h.
float ggxMasking(float a2, float c) { return 2.0 * c / (c + sqrt(a2 + (1.0 - a2) * c * c)); }
float specularBrdf(vec3 n, vec3 wi, vec3 wo) {
    float cosI = dot(n, wi), cosO = dot(n, wo);
    if (!(cosI > 0.0) || !(cosO > 0.0)) return 0.0;
    vec3 sum = wi + wo;
    float len = length(sum);
    if (!(len > 0.0)) return 0.0;
    vec3 h = sum / len;
    float cosH = dot(n, h);
    if (!(cosH > 0.0)) return 0.0;
    float a2 = uPointRoughness * uPointRoughness;
    float d = cosH * cosH * (a2 - 1.0) + 1.0;
    float D = a2 / (kPi * d * d);
    return fresnelReflectance(uPointEta, dot(wi, h)) * D * ggxMasking(a2, cosI) * ggxMasking(a2, cosO) /
           (4.0 * cosI * cosO);
}

// vertexSpecular (vertex_surface_terms.cpp): the lobe per pixel, each light's shadowed
// irradiance interpolated from the triangle's vertices.
vec3 pointSpecular(vec3 n, vec3 wo) {
    vec3 p0 = texelFetch(uPositions, at(gTriangle.x), 0).xyz;
    vec3 p1 = texelFetch(uPositions, at(gTriangle.y), 0).xyz;
    vec3 p2 = texelFetch(uPositions, at(gTriangle.z), 0).xyz;
    vec3 x = gBarycentric.x * p0 + gBarycentric.y * p1 + gBarycentric.z * p2;
    vec3 c = cross(p1 - p0, p2 - p0);
    float cl = length(c);
    vec3 ng = cl > 0.0 ? c / cl : vec3(0.0);
    vec3 sum = vec3(0.0);
    for (int l = 0; l < uPointLightCount; ++l) {
        vec4 light = texelFetch(uPointLights, ivec2(l, 0), 0);
        vec3 wi = light.xyz;
        if (light.w < 0.5) {
            vec3 dl = light.xyz - x;
            float len = length(dl);
            if (!(len > 0.0)) continue;
            wi = dl / len;
        }
        float cosI = dot(n, wi);
        if (!(cosI > 0.0) || !(dot(ng, wi) > 0.0)) continue;
        int row = l * uSlotRows;
        vec3 e = gBarycentric.x * texelFetch(uPointIrradiance, ivec2(gTriangle.x % uRowWidth, row + gTriangle.x / uRowWidth), 0).rgb +
                 gBarycentric.y * texelFetch(uPointIrradiance, ivec2(gTriangle.y % uRowWidth, row + gTriangle.y / uRowWidth), 0).rgb +
                 gBarycentric.z * texelFetch(uPointIrradiance, ivec2(gTriangle.z % uRowWidth, row + gTriangle.z / uRowWidth), 0).rgb;
        sum += specularBrdf(n, wi, wo) * cosI * e;
    }
    return sum;
}

// directionToFaceUV (cubemap.cpp), ties to X before Y before Z.
void faceUV(vec3 d, out int face, out float s, out float t) {
    float ax = abs(d.x), ay = abs(d.y), az = abs(d.z);
    float sc, tc, ma;
    if (ax >= ay && ax >= az) {
        ma = ax;
        if (d.x >= 0.0) { face = 0; sc = -d.z; tc = -d.y; } else { face = 1; sc = d.z; tc = -d.y; }
    } else if (ay >= az) {
        ma = ay;
        if (d.y >= 0.0) { face = 2; sc = d.x; tc = d.z; } else { face = 3; sc = d.x; tc = -d.z; }
    } else {
        ma = az;
        if (d.z >= 0.0) { face = 4; sc = d.x; tc = -d.y; } else { face = 5; sc = -d.x; tc = -d.y; }
    }
    s = 0.5 * (sc / ma + 1.0);
    t = 0.5 * (tc / ma + 1.0);
}

// Cubemap::sampleBilinear of view map k: between texel centres of d's face, clamped
// at the face border.
float viewMap(int k, vec3 d) {
    int face;
    float s, t;
    faceUV(d, face, s, t);
    int n = uViewMapSize;
    float x = clamp(s * float(n) - 0.5, 0.0, float(n - 1));
    float y = clamp(t * float(n) - 0.5, 0.0, float(n - 1));
    int i0 = int(x), j0 = int(y);
    int i1 = min(i0 + 1, n - 1), j1 = min(j0 + 1, n - 1);
    float fx = x - float(i0), fy = y - float(j0);
    int row = (k * 6 + face) * n;
    float top = (1.0 - fx) * texelFetch(uViewMaps, ivec2(i0, row + j0), 0).r +
                fx * texelFetch(uViewMaps, ivec2(i1, row + j0), 0).r;
    float bottom = (1.0 - fx) * texelFetch(uViewMaps, ivec2(i0, row + j1), 0).r +
                   fx * texelFetch(uViewMaps, ivec2(i1, row + j1), 0).r;
    return (1.0 - fy) * top + fy * bottom;
}

// The background: the same lookup as latLongRadiance with the texture unit's bilinear
// filter, which has the same convention (texel centres, u wraps, v clamps) and is
// several times faster on software rasterisers; it may round the weights (to 8 bits on
// many GPUs), which is invisible in a display and outside the compared object pixels.
vec3 background(vec3 d) {
    vec3 l = uEnvRotationT * d;
    float u = 0.5 + atan(l.x, -l.z) / (2.0 * kPi);
    float v = acos(clamp(l.y / length(l), -1.0, 1.0)) / kPi;
    return texture(uEnvironment, vec2(u, v)).rgb;
}

// TranslucentShader::shade (+ specularReflection when uSpecular, + the point lights'
// specular when uPointLightCount > 0) on object pixels.
void main() {
    vec3 d = rayDirection();
    uint id = texelFetch(uVisibility, ivec2(gl_FragCoord.xy), 0).r;
    if (id == 0u) {
        writeColor(uBackground ? background(d) : vec3(0.0), 0.0);
        return;
    }
    findTriangle(int(id - 1u), d);
    if (int(id - 1u) >= uObjectTriangles) {  // the ground: its vertices' Lambertian radiance (groundRadiance)
        writeColor(d.y < 0.0 ? interpolated(0) : vec3(0.0), 1.0);  // its back, seen from below, is black
        return;
    }
    vec3 wo = -d;
    vec3 s = gBarycentric.x * texelFetch(uNormals, at(gTriangle.x), 0).xyz +
             gBarycentric.y * texelFetch(uNormals, at(gTriangle.y), 0).xyz +
             gBarycentric.z * texelFetch(uNormals, at(gTriangle.z), 0).xyz;
    float len = length(s);
    vec3 n = len > 1e-12 ? s / len : vec3(0.0);
    float cosO = dot(n, wo);
    vec3 L = vec3(0.0);
    if (cosO > 0.0) {  // else F_t(eta, 0) = 0: black, as the offline renderer
        float fr = fresnelReflectance(uEta, cosO);
        vec3 sum = interpolated(0);
        if (uTermCount > 0) {
            vec3 wt;
            if (refractDirection(wo, n, uEta, wt)) {
                vec3 ss = vec3(0.0);
                for (int k = 0; k < uTermCount; ++k) ss += viewMap(k, wt) * interpolated(k + 1);
                float x = clamp(-dot(wt, n), 0.0, 1.0) * 64.0;
                int i = min(int(x), 63);
                float eyePath = mix(uEyePath[i], uEyePath[i + 1], x - float(i));
                sum += eyePath * max(ss, vec3(0.0));  // the K-term phase's negative lobes, as translucent_shader.cpp
            }
        }
        L = (1.0 - fr) * max(sum, vec3(0.0));
        if (uHasBaseColour) L *= baseColour(int(id - 1u));
        if (uSpecular) L += fr * latLongRadiance(uPrefiltered, 2.0 * cosO * n - wo);
        if (uPointLightCount > 0) L += pointSpecular(n, wo);
    }
    writeColor(L, 1.0);
}
