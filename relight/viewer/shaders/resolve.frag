
// --spp: the box filter of boxDownsample (relight/render/supersample.h) over the n x n
// sub-pixels of this pixel in the linear sub-pixel target (rows from the bottom in
// both, so sub-pixel (n x + i, n y + j) lies in pixel (x, y)), then writePng's display
// transform, as render --spp writes its PNG from the downsampled image.
uniform sampler2D uSubpixels;  // RGBA32F, n width x n height: radiance, alpha 1 on the object
uniform int uSubpixelGrid;     // n

void main() {
    ivec2 base = ivec2(gl_FragCoord.xy) * uSubpixelGrid;
    vec4 sum = vec4(0.0);
    for (int j = 0; j < uSubpixelGrid; ++j)
        for (int i = 0; i < uSubpixelGrid; ++i) sum += texelFetch(uSubpixels, base + ivec2(i, j), 0);
    sum /= float(uSubpixelGrid * uSubpixelGrid);
    writeColor(sum.rgb, sum.a);
}
