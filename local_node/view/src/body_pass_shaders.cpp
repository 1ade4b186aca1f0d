// SPDX-License-Identifier: MIT
// The body pass's shaders: the body's screen tiles, each pixel ray-marched once against its
// tile's capsules (nearest first), each capsule smoothly joined to its neighbours.
#include "body_pass.h"

namespace telex::local {

// The body's surface colour at a point with outward unit normal n seen along rd (unit, from the
// eye): both the ray-marched body and the mesh body shade with it.
const char* const kBodyShadeGlsl = R"(
// Skin (color.a 1): a key light from above and to the left (the camera's y is down), wrapped so
// the shadow side stays soft, a sky-and-ground ambient, the creases (`crease`: how deep in a
// fillet between two capsules, 0..1) darkened, a warm rim where light scatters under the skin,
// and a faint sheen, all times the video's `exposure`. A marker (color.a 0): its colour, shaded
// by how squarely it faces the eye.
vec3 shade_body(vec3 n, vec3 rd, vec4 color, float crease, float exposure) {
  float facing = max(dot(n, -rd), 0.0);
  vec3 albedo = color.rgb;
  if (color.a < 0.5) return albedo * (0.55 + 0.45 * facing);
  vec3 l = normalize(vec3(-0.35, -0.85, -0.4));
  float diffuse = max((dot(n, l) + 0.35) / 1.35, 0.0);
  float ambient = 0.22 + 0.14 * (0.5 - 0.5 * n.y);
  float ao = 1.0 - 0.12 * crease * crease;
  vec3 rim = vec3(0.85, 0.35, 0.25) * pow(1.0 - facing, 3.0) * 0.12;
  float sheen = pow(max(dot(reflect(-l, n), -rd), 0.0), 20.0) * 0.06;
  return (albedo * (0.78 * diffuse + ambient) * ao + rim + sheen) * exposure;
}
)";

// The round cone's signed distance and the smooth minimum that joins two: the ray-marched body's
// field and the mesh body's fillets (its vertex shader) are made of these.
const char* const kBodyFieldGlsl = R"(
float dot2(vec3 v) { return dot(v, v); }
// Quilez's round cone: spheres of radii r1 at a and r2 at b and the cone tangent to both.
float round_cone(vec3 p, vec3 a, vec3 b, float r1, float r2) {
  vec3 ba = b - a;
  float l2 = dot(ba, ba);
  float rr = r1 - r2;
  float a2 = l2 - rr * rr;
  vec3 pa = p - a;
  if (l2 < 1e-12 || a2 <= 1e-12) return min(length(pa) - r1, length(p - b) - r2);
  float il2 = 1.0 / l2;
  float y = dot(pa, ba);
  float z = y - l2;
  float x2 = dot2(pa * l2 - ba * y);
  float y2 = y * y * l2;
  float z2 = z * z * l2;
  float k = sign(rr) * rr * rr * x2;
  if (sign(z) * a2 * z2 > k) return sqrt(x2 + z2) * il2 - r2;
  if (sign(y) * a2 * y2 < k) return sqrt(x2 + y2) * il2 - r1;
  return (sqrt(x2 * a2 * il2) + y * rr) * il2 - r1;
}
float smin(float a, float b, float k) {
  if (k <= 0.0) return min(a, b);
  float h = max(k - abs(a - b), 0.0) / k;
  return min(a, b) - h * h * k * 0.25;
}
// How far a capsule of larger radius r blends into its neighbour a-b (radii a.w, b.w).
float blend_reach(float r, vec4 a, vec4 b) { return 0.7 * min(r, max(a.w, b.w)); }
)";

// One quad per non-empty tile (per instance: its first pixel, rows top-down, and where its
// capsule list lies in the list buffer), cut to the target.
const char* const kBodyTilesVs = R"(#version 330 core
layout(location = 0) in ivec4 a_tile;  // x, y (pixels), list offset, count | side << 8
uniform vec2 u_size;                   // the target's pixels
flat out ivec2 v_list;                 // offset, count
void main() {
  vec2 c = vec2(gl_VertexID & 1, gl_VertexID >> 1);
  vec2 px = min(vec2(a_tile.xy) + c * float(a_tile.w >> 8), u_size);
  v_list = ivec2(a_tile.z, a_tile.w & 255);
  gl_Position = vec4(2.0 * px / u_size - 1.0, 0.0, 1.0);
}
)";

// The eye sits at the origin. Each capsule of this pixel's tile (nearest first) is met by the
// ray where its field, the capsule smoothly joined to its neighbours, first reaches zero; the
// nearest of those hits is shaded. A capsule that starts beyond the nearest hit so far is not
// marched, and the list ends once a capsule's nearest z is past it: the union of all the fields
// is shaded once per pixel instead of once per overlapping capsule box.
const char* const kBodyTilesFs = R"(
// Per capsule: a and its radius, b and its radius, rgb and lit (1) or a flat marker (0).
// A texture buffer, not a uniform block: llvmpipe fetches a texel's four components per pixel
// at once, and a uniform block's one by one.
uniform samplerBuffer u_caps;
// Per tile entry (each tile's nearest first): its capsule, and as bit k its neighbours' entries
// in the same tile.
uniform isamplerBuffer u_list;
uniform vec4 u_k;               // fx, fy, cx, cy of the target
uniform float u_near;
uniform float u_far;
uniform float u_exposure;
flat in ivec2 v_list;  // this tile's offset and count in u_list
out vec4 o_color;

vec4 g_self_a, g_self_b;  // this capsule
int g_near_lo, g_near_hi;  // the neighbours near this pixel's ray, a byte each
int g_count;
// llvmpipe runs both sides of a branch but leaves a loop once every pixel of a block is done: the
// neighbours are looped over by their count, never skipped by a test.
// g_blend: how deep in a fillet the last point was (0 on a lone capsule, 1 in a crease).
float g_blend = 0.0;
float field(vec3 p) {
  float d = round_cone(p, g_self_a.xyz, g_self_b.xyz, g_self_a.w, g_self_b.w);
  float r = max(g_self_a.w, g_self_b.w);
  g_blend = 0.0;
  for (int k = 0; k < g_count; ++k) {
    int j = ((k < 4 ? g_near_lo : g_near_hi) >> (8 * (k & 3))) & 255;
    vec4 a = texelFetch(u_caps, 3 * j), b = texelFetch(u_caps, 3 * j + 1);
    float kj = blend_reach(r, a, b);
    float dj = round_cone(p, a.xyz, b.xyz, a.w, b.w);
    g_blend = max(g_blend, max(kj - abs(d - dj), 0.0) / kj);
    d = smin(d, dj, kj);
  }
  return d;
}
// Where the ray from the eye along rd is inside the capsule a-b of radius r: (enter, leave), or
// enter > leave on a miss. The capsule is convex: its interval is the union of its cylinder's and
// its two balls'.
vec2 capsule_span(vec3 rd, vec3 a, vec3 b, float r) {
  vec2 span = vec2(1e30, -1e30);
  vec3 ba = b - a, oa = -a;
  float baba = dot(ba, ba), bard = dot(ba, rd), baoa = dot(ba, oa);
  float rdoa = dot(rd, oa), oaoa = dot(oa, oa);
  float qa = baba - bard * bard;
  if (qa > 1e-9 * max(baba, 1e-12)) {
    float qb = baba * rdoa - baoa * bard;
    float qc = baba * oaoa - baoa * baoa - r * r * baba;
    float h = qb * qb - qa * qc;
    if (h >= 0.0) {
      float s = sqrt(h);
      vec2 cyl = vec2(-qb - s, -qb + s) / qa;
      // Between the end planes: y(t) = baoa + t bard in [0, baba].
      if (abs(bard) > 1e-20) {
        vec2 ends = vec2(-baoa, baba - baoa) / bard;
        cyl = vec2(max(cyl.x, min(ends.x, ends.y)), min(cyl.y, max(ends.x, ends.y)));
      } else if (baoa < 0.0 || baoa > baba) {
        cyl = vec2(1e30, -1e30);
      }
      if (cyl.x <= cyl.y) span = cyl;
    }
  }
  for (int e = 0; e < 2; ++e) {
    vec3 c = e == 0 ? a : b;
    float pb = dot(rd, c);
    float h = pb * pb - (dot(c, c) - r * r);
    if (h < 0.0) continue;
    float s = sqrt(h);
    span = vec2(min(span.x, pb - s), max(span.y, pb + s));
  }
  return span;
}
// Where the ray from the eye along rd enters the round cone (Quilez's intersector), with the
// outward normal there; x < 0: a miss.
vec4 round_cone_hit(vec3 rd, vec3 pa, vec3 pb, float ra, float rb) {
  vec3 ba = pb - pa, oa = -pa, ob = -pb;
  float rr = ra - rb;
  float m0 = dot(ba, ba), m1 = dot(ba, oa), m2 = dot(ba, rd), m3 = dot(rd, oa), m5 = dot(oa, oa);
  float m6 = dot(ob, rd), m7 = dot(ob, ob);
  float d2 = m0 - rr * rr;
  if (d2 > 1e-6 * max(m0, 1e-12)) {
    // The cone's side, where it touches neither ball.
    float k2 = d2 - m2 * m2;
    float k1 = d2 * m3 - m1 * m2 + m2 * rr * ra;
    float k0 = d2 * m5 - m1 * m1 + m1 * rr * ra * 2.0 - m0 * ra * ra;
    float h = k1 * k1 - k0 * k2;
    if (abs(k2) > 1e-12 && h >= 0.0) {
      float t = (-sqrt(h) - k1) / k2;
      float y = m1 - ra * rr + t * m2;
      if (t > 0.0 && y > 0.0 && y < d2) return vec4(t, normalize(d2 * (oa + t * rd) - ba * y));
    }
  }
  // The balls (the larger alone where it holds the other).
  vec4 best = vec4(-1.0);
  float h1 = m3 * m3 - m5 + ra * ra, h2 = m6 * m6 - m7 + rb * rb;
  if (h1 >= 0.0) {
    float t = -m3 - sqrt(h1);
    if (t > 0.0) best = vec4(t, (oa + t * rd) / ra);
  }
  if (h2 >= 0.0) {
    float t = -m6 - sqrt(h2);
    if (t > 0.0 && (best.x < 0.0 || t < best.x)) best = vec4(t, (ob + t * rd) / rb);
  }
  return best;
}
// The index of the lowest bit set in m (not 0), by the exponent of that bit as a float: GLSL 3.30
// has no findLSB.
int lowest_bit(int m) { return ((floatBitsToInt(float(m & -m)) >> 23) & 255) - 127; }
// The squared distance between the line through the eye along rd (unit) and the segment a-b.
float ray_segment_distance2(vec3 rd, vec3 a, vec3 b) {
  vec3 d = b - a;
  float au = dot(a, rd), du = dot(d, rd);
  float pa2 = dot(a, a) - au * au, pd2 = dot(d, d) - du * du, pad = dot(a, d) - au * du;
  float s = pd2 > 1e-12 ? clamp(-pad / pd2, 0.0, 1.0) : 0.0;
  return max(pa2 + s * (2.0 * pad + s * pd2), 0.0);
}
// Bit k: the ray meets the blend reach of the tile's entry k (1.875 times its capsule's radius:
// the reach of its own fillets, 1.2 r, and of a neighbour's, r + 0.875 r at most).
int g_met;
void compare_swap(inout int a, inout int b) {
  int lo = min(a, b);
  b = max(a, b);
  a = lo;
}
// The near neighbours (g_near_lo, g_near_hi, g_count) in the capsules' order, as
// blend_neighbours lists them: the smooth minimum's result depends a little on the order it
// joins them in, and the tile lists them nearest first. A 19-comparator sorting network; the
// unused bytes sort last.
void sort_near() {
  int v[8];
  for (int k = 0; k < 8; ++k)
    v[k] = k < g_count ? ((k < 4 ? g_near_lo : g_near_hi) >> (8 * (k & 3))) & 255 : 256;
  compare_swap(v[0], v[2]); compare_swap(v[1], v[3]); compare_swap(v[4], v[6]);
  compare_swap(v[5], v[7]); compare_swap(v[0], v[4]); compare_swap(v[1], v[5]);
  compare_swap(v[2], v[6]); compare_swap(v[3], v[7]); compare_swap(v[0], v[1]);
  compare_swap(v[2], v[3]); compare_swap(v[4], v[5]); compare_swap(v[6], v[7]);
  compare_swap(v[2], v[4]); compare_swap(v[3], v[5]); compare_swap(v[1], v[4]);
  compare_swap(v[3], v[6]); compare_swap(v[1], v[2]); compare_swap(v[3], v[4]);
  compare_swap(v[5], v[6]);
  g_near_lo = (v[0] & 255) | ((v[1] & 255) << 8) | ((v[2] & 255) << 16) | ((v[3] & 255) << 24);
  g_near_hi = (v[4] & 255) | ((v[5] & 255) << 8) | ((v[6] & 255) << 16) | ((v[7] & 255) << 24);
}
// The ray from the eye along rd against the tile's entry k, its capsule joined to its neighbours,
// looking no farther than t_best: the hit's t, or -1. On a hit on the capsule's own round cone
// `exact` is set and n is its normal; g_self_a, g_self_b and the near neighbours are left as
// field() needs them.
float trace(int k, vec3 rd, float t_best, out bool exact, out vec3 n) {
  exact = false;
  n = vec3(0.0);
  g_self_a = vec4(0.0);
  g_self_b = vec4(0.0);
  ivec2 entry = texelFetch(u_list, v_list.x + k).xy;
  g_self_a = texelFetch(u_caps, 3 * entry.x);
  g_self_b = texelFetch(u_caps, 3 * entry.x + 1);
  // This capsule grown by the blend's reach bounds what the ray can meet (the eye may be inside).
  vec4 ca = g_self_a, cb = g_self_b;
  float r = max(ca.w, cb.w);
  vec2 span = capsule_span(rd, ca.xyz, cb.xyz, r * 1.2 + 5e-4);
  if (span.x > span.y || span.y < u_near || span.x >= t_best) return -1.0;
  float t = max(span.x, u_near), t_exit = span.y;
  // A neighbour j changes the smooth union only where this capsule's distance and j's differ by
  // less than k_j and the union is below zero: within 1.25 k_j of j. Only the neighbours whose
  // so grown capsule the ray meets are kept (their indices packed a byte each: llvmpipe runs a
  // loop as long as its longest lane, and indexes local arrays slowly), and the ray is marched
  // only from where it meets the first of them; elsewhere the surface is this round cone's,
  // found and shaded exactly. Only neighbours in this tile whose reach main's test met can pass.
  int near_entries = entry.y & g_met;
  g_near_lo = 0;
  g_near_hi = 0;
  g_count = 0;
  float blend_lo = 1e30, blend_hi = -1e30;
  while (near_entries != 0 && g_count < 8) {
    int e = lowest_bit(near_entries);
    near_entries &= near_entries - 1;
    int j = texelFetch(u_list, v_list.x + e).x;
    vec4 a = texelFetch(u_caps, 3 * j), b = texelFetch(u_caps, 3 * j + 1);
    float rj = max(a.w, b.w);
    vec2 s = capsule_span(rd, a.xyz, b.xyz, rj + 0.875 * min(r, rj) + 2e-4);
    if (s.x <= s.y && s.y > t && s.x < t_exit) {
      if (g_count < 4) g_near_lo |= j << (8 * g_count);
      else g_near_hi |= j << (8 * (g_count - 4));
      ++g_count;
      blend_lo = min(blend_lo, s.x);
      blend_hi = max(blend_hi, s.y);
    }
  }
  sort_near();
  vec4 self_hit = round_cone_hit(rd, ca.xyz, cb.xyz, ca.w, cb.w);
  exact = self_hit.x > 0.0 && (g_count == 0 || self_hit.x <= blend_lo);
  if (!exact && g_count == 0) return -1.0;
  // Past the blends the field is this cone's alone again.
  float t_end = min(t_exit, blend_hi);
  bool hit = exact;
  t = exact ? self_hit.x : max(t, blend_lo);
  // Marching on past t_best cannot find a nearer hit.
  float t_stop = min(t_end, t_best);
  for (int i = 0; i < 32 && !hit && t < t_stop; ++i) {
    float d = field(rd * t);
    if (d < 1.5e-4 + 2e-4 * t) hit = true;
    else t += d;
  }
  if (!hit && self_hit.x >= t_end && t >= t_end) {
    t = self_hit.x;
    hit = exact = true;
  }
  if (!hit || t >= t_best) return -1.0;
  n = self_hit.yzw;
  return t;
}
void main() {
  vec3 rd = normalize(vec3((gl_FragCoord.xy - 0.5 - u_k.zw) / u_k.xy, 1.0));
  // llvmpipe runs every statement for a block of pixels and skips only loop iterations no pixel
  // needs: each capsule of the tile is first tested once against the ray (within its blend
  // reach), and only those met are traced, nearest first, for as many rounds as the block's pixel
  // that meets the most needs; their neighbours come from the same tests.
  g_met = 0;
  int to_trace = 0;  // a bit per tile entry whose own bound the ray meets, not yet traced
  for (int k = 0; k < v_list.y; ++k) {
    int j = texelFetch(u_list, v_list.x + k).x;
    vec4 a = texelFetch(u_caps, 3 * j), b = texelFetch(u_caps, 3 * j + 1);
    float r = max(a.w, b.w);
    float d2 = ray_segment_distance2(rd, a.xyz, b.xyz);
    float reach = r * 1.875 + 5e-4, own = r * 1.2 + 5e-4;
    if (d2 <= reach * reach) g_met |= 1 << k;
    if (d2 <= own * own) to_trace |= 1 << k;
  }
  float t = 1e30;
  int id = -1;
  bool exact = false;
  vec3 n = vec3(0.0);
  ivec3 near = ivec3(0);  // the hit's near neighbours: g_near_lo, g_near_hi, g_count
  while (to_trace != 0) {
    int k = lowest_bit(to_trace);
    to_trace &= to_trace - 1;
    bool exact_k;
    vec3 n_k;
    float t_k = trace(k, rd, t, exact_k, n_k);
    if (t_k > 0.0) {
      t = t_k;
      id = texelFetch(u_list, v_list.x + k).x;
      exact = exact_k;
      n = n_k;
      near = ivec3(g_near_lo, g_near_hi, g_count);
    }
  }
  if (id < 0) discard;
  g_self_a = texelFetch(u_caps, 3 * id);
  g_self_b = texelFetch(u_caps, 3 * id + 1);
  g_near_lo = near.x;
  g_near_hi = near.y;
  g_count = near.z;
  vec4 color = texelFetch(u_caps, 3 * id + 2);
  vec3 p = rd * t;
  float crease = 0.0;
  if (!exact) {
    // The crease depth at the hit, then the normal from three forward differences (the field is
    // about zero at the hit).
    float d0 = field(p);
    crease = g_blend;
    const float e = 2e-4;
    n = normalize(vec3(field(p + vec3(e, 0.0, 0.0)), field(p + vec3(0.0, e, 0.0)),
                       field(p + vec3(0.0, 0.0, e))) - d0);
  }
  vec3 c = shade_body(n, rd, color, crease, u_exposure);
  o_color = vec4(c, 1.0);
  float z = clamp(p.z, u_near, u_far);
  float ndc = (u_far + u_near) / (u_far - u_near) - 2.0 * u_far * u_near / ((u_far - u_near) * z);
  gl_FragDepth = ndc * 0.5 + 0.5;
}
)";

}  // namespace telex::local
