#version 330 core

const float kPi = 3.14159265358979323846;
uniform vec3 uEye;                   // camera position, mm
uniform vec3 uForward, uRight, uUp;  // camera basis (camera.cpp)
uniform float uTanHalf;              // tan(fovY / 2)
uniform vec2 uViewSize;              // width, height in pixels
uniform mat3 uEnvRotationT;          // R^T: the environment is L(R^T d)
uniform float uScale;                // 2^exposure (divided by Radiance_avg for chang)
uniform int uToneMap;                // ToneMapOperator: 0 clamp, 1 reinhard, 2 filmic, 3 chang
layout(location = 0) out vec4 displayColor;  // tone-mapped, sRGB-encoded (RGBA8 target or window)
layout(location = 1) out vec4 linearColor;   // radiance, alpha 1 on the object (RGBA32F target)

// writePng's display transform (common/tonemap.h): scale, the operator, then the exact
// sRGB encoding; the 8-bit target rounds to the nearest of 256 levels. Negatives and NaN
// display as 0.
float encodeSrgb(float v) {
    if (!(v > 0.0)) v = 0.0;
    if (v > 1.0) v = 1.0;
    return v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1.0 / 2.4) - 0.055;
}
float positive(float v) { return v > 0.0 ? v : 0.0; }
vec3 toneMap(vec3 c) {
    if (uToneMap == 1) {  // Reinhard et al. 2002 eq. 3 on the luminance, hue kept
        float y = dot(c, vec3(0.2126, 0.7152, 0.0722));
        return y > 0.0 ? c / (1.0 + y) : vec3(0.0);
    }
    if (uToneMap == 2)  // ACES filmic, Narkowicz's fit
        return (c * (2.51 * c + 0.03)) / (c * (2.43 * c + 0.59) + 0.14);
    if (uToneMap == 3)  // Chang et al. 2008: R / (1 + R)
        return c / (1.0 + c);
    return c;
}
void writeColor(vec3 L, float alpha) {
    // +Inf displays as 1, as in C++: keep the operators' ratios finite.
    vec3 c = toneMap(min(vec3(positive(L.r), positive(L.g), positive(L.b)) * uScale, vec3(1e30)));
    displayColor = vec4(encodeSrgb(c.r), encodeSrgb(c.g), encodeSrgb(c.b), 1.0);
    linearColor = vec4(L, alpha);
}

// cameraRayDirection at the centre of this pixel; pixel rows count from the top.
vec3 rayDirection() {
    float aspect = uViewSize.x / uViewSize.y;
    float px = gl_FragCoord.x;
    float py = uViewSize.y - gl_FragCoord.y;
    float sx = (2.0 * px / uViewSize.x - 1.0) * uTanHalf * aspect;
    float sy = (1.0 - 2.0 * py / uViewSize.y) * uTanHalf;
    return normalize(uForward + sx * uRight + sy * uUp);
}

// environmentRadiance: lat-long map (row 0 = top = +Y), rotated, bilinear between
// pixel centres, u wraps, v clamps.
vec3 latLongRadiance(sampler2D map, vec3 d) {
    vec3 l = uEnvRotationT * d;
    float len = length(l);
    if (!(len > 0.0)) return vec3(0.0);
    ivec2 size = textureSize(map, 0);
    float cy = clamp(l.y / len, -1.0, 1.0);
    float u = 0.5 + atan(l.x, -l.z) / (2.0 * kPi);
    if (u >= 1.0) u -= 1.0;
    if (u < 0.0) u += 1.0;
    float v = acos(cy) / kPi;
    float x = u * float(size.x) - 0.5;
    float y = clamp(v * float(size.y) - 0.5, 0.0, float(size.y - 1));
    float xf = floor(x);
    float fx = x - xf;
    int x0 = int(xf);
    if (x0 < 0) x0 += size.x;
    if (x0 >= size.x) x0 -= size.x;
    int x1 = x0 + 1 == size.x ? 0 : x0 + 1;
    int y0 = int(y);
    int y1 = min(y0 + 1, size.y - 1);
    float fy = y - float(y0);
    vec3 top = (1.0 - fx) * texelFetch(map, ivec2(x0, y0), 0).rgb + fx * texelFetch(map, ivec2(x1, y0), 0).rgb;
    vec3 bottom = (1.0 - fx) * texelFetch(map, ivec2(x0, y1), 0).rgb + fx * texelFetch(map, ivec2(x1, y1), 0).rgb;
    return (1.0 - fy) * top + fy * bottom;
}
