"""The GL renderer's shaders (:mod:`renderers.gl` explains their math): one triangle per splat around its
α ≥ 1/255 ellipse or its clipped box, and the 3DGS α test and premultiplied colour per fragment."""

VERTEX_SHADER = """
#version 330
in vec2 in_corner;          // per vertex: (0, 2), (-sqrt3, -1), (sqrt3, -1)
in vec4 in_mean_o_k;        // per instance: mean.xy, opacity, K = 2 ln(255 o)
in vec4 in_conic_det;       // a, b, c, ac - b^2 (float64 on the CPU: no cancellation)
in vec4 in_color_r;         // r, g, b, radius
uniform vec2 u_origin;      // tile origin in pixels
uniform vec2 u_size;        // tile size in pixels
uniform vec2 u_image;       // image size in pixels
uniform bool u_tiles;       // footprint "tile" (graphdeco getRect, 16-px tiles) instead of "box"
flat out vec2 v_mean;
flat out vec3 v_conic;
flat out vec4 v_color_o;
flat out vec4 v_bounds;     // tile footprint: pixel indices [x0, x1) x [y0, y1)

void main() {
    vec2 mean = in_mean_o_k.xy;
    float k = in_mean_o_k.w;
    float a = in_conic_det.x, b = in_conic_det.y, c = in_conic_det.z, det = in_conic_det.w;
    float r = in_color_r.w;
    const float grow = 1.001;
    const float pad = 0.01;
    // Semi-axes h1, h2 along the eigenvectors e1, e2 of the ellipse d'Qd <= K (mu2 = det/mu1: no cancellation).
    float half_tr = 0.5 * (a + c);
    float mu1 = half_tr + sqrt(max(half_tr * half_tr - det, 0.0));
    float mu2 = det / mu1;
    vec2 e1 = abs(b) > 1e-12 * mu1 ? normalize(vec2(b, mu1 - a)) : (a >= c ? vec2(1.0, 0.0) : vec2(0.0, 1.0));
    vec2 e2 = vec2(-e1.y, e1.x);
    float h1 = sqrt(k / mu1) * grow + pad;
    float h2 = sqrt(k / mu2) * grow + pad;
    // graphdeco getRect: tiles [floor((m - r)/16), floor((m + r + 15)/16)) clamped to the grid.
    vec2 grid = ceil(u_image / 16.0);
    vec2 t0 = clamp(floor((mean - r) / 16.0), vec2(0.0), grid);
    vec2 t1 = clamp(floor((mean + r + 15.0) / 16.0), vec2(0.0), grid);
    v_bounds = vec4(t0, t1) * 16.0;
    // Axis-aligned box of the same ellipse, clipped to the footprint and to the image.
    vec2 ext = sqrt(k * vec2(c, a) / det) * grow + pad;
    vec2 lo = mean - (u_tiles ? ext : min(ext, vec2(r + pad)));
    vec2 hi = mean + (u_tiles ? ext : min(ext, vec2(r + pad)));
    if (u_tiles) {
        lo = max(lo, v_bounds.xy - 0.5);
        hi = min(hi, v_bounds.zw - 0.5);
    }
    lo = max(lo, vec2(-0.5));
    hi = min(hi, u_image - 0.5);
    vec2 box = max(hi - lo, vec2(0.0));
    // One triangle per splat: the one circumscribing the unit circle, (0, 2), (±sqrt3, -1), mapped onto
    // the ellipse (area 3 sqrt3 h1 h2), or the right triangle lo, lo + (2w, 0), lo + (0, 2h) around the
    // clipped box (area 2 w h), whichever is smaller.
    vec2 pos;
    if (5.196153 * h1 * h2 < 2.0 * box.x * box.y) {
        pos = mean + in_corner.x * h1 * e1 + in_corner.y * h2 * e2;
    } else {
        vec2 t = vec2(in_corner.x > 0.5 ? 2.01 : 0.0, in_corner.y > 1.5 ? 2.01 : 0.0);
        pos = lo + t * box;
    }
    // 3DGS frame -> window (pixel centre i at i + 0.5) -> tile NDC.
    gl_Position = vec4((pos + 0.5 - u_origin) / u_size * 2.0 - 1.0, 0.0, 1.0);
    v_mean = mean;
    v_conic = in_conic_det.xyz;
    v_color_o = vec4(in_color_r.rgb, in_mean_o_k.z);
    if (!u_tiles) v_bounds = vec4(r);
}
"""

FRAGMENT_SHADER = """
#version 330
flat in vec2 v_mean;
flat in vec3 v_conic;
flat in vec4 v_color_o;
flat in vec4 v_bounds;
uniform vec2 u_origin;
uniform bool u_tiles;
out vec4 f_color;

void main() {
    vec2 pix = gl_FragCoord.xy - 0.5 + u_origin;
    vec2 d = pix - v_mean;
    if (u_tiles) {
        if (any(lessThan(pix, v_bounds.xy)) || any(greaterThanEqual(pix, v_bounds.zw))) discard;
    } else if (any(greaterThan(abs(d), v_bounds.xy))) discard;   // v_bounds = radius here
    float power = -0.5 * (v_conic.x * d.x * d.x + v_conic.z * d.y * d.y) - v_conic.y * d.x * d.y;
    if (power > 0.0) discard;
    float alpha = min(0.99, v_color_o.a * exp(power));
    if (alpha < 1.0 / 255.0) discard;
    f_color = vec4(v_color_o.rgb * alpha, alpha);
}
"""
