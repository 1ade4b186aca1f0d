// SPDX-License-Identifier: MIT
// The stereo renderer's body pass: the capsules as one smooth body (each capsule's signed distance
// joined to those it shares an end with by a smooth minimum, sphere-traced once per pixel over the
// capsules binned into that pixel's screen tile), lit to the eye image's brightness, and the
// contact shadows fingertips cast on the remote scene. Internal to the renderer: it needs the
// renderer's current GL context.
#pragma once

#include <array>
#include <cstdint>
#include <glm/glm.hpp>
#include <memory>
#include <opencv2/core.hpp>
#include <span>
#include <string>
#include <vector>

#include "telex/local/view/body_shape.h"
#include "telex/local/view/eye_view.h"

namespace telex::local {

// Which capsules blend with which: each capsule's neighbours are the ones that share an end
// (within 1 mm) with it, at most kMaxBlendNeighbours, in input order. The chain of a finger, the
// palm's fan from the wrist and the arm join up; neighbouring fingers do not touch ends, so they
// stay apart.
inline constexpr std::size_t kMaxBlendNeighbours = 8;
std::vector<std::array<std::int32_t, kMaxBlendNeighbours>> blend_neighbours(
    std::span<const Capsule> capsules);

// The body drawn at 1/divisor of the eye's resolution into an offscreen target (colour with
// coverage, depth) and composited over the eye: each of the four low-resolution samples around an
// eye pixel counts only where it is nearer than the remote depth at that pixel, and the kept ones
// blend bilinearly.
class BodyUpsample {
 public:
  BodyUpsample();  // the GL context must be current
  ~BodyUpsample();
  BodyUpsample(const BodyUpsample&) = delete;
  BodyUpsample& operator=(const BodyUpsample&) = delete;

  // Binds the low-resolution target for the eye `k` (cleared: no body, far) and returns its
  // intrinsics; remembers the framebuffer and viewport bound before.
  Intrinsics begin(const Intrinsics& k, int divisor);
  // Back to the framebuffer and viewport bound at begin(); the target keeps the body.
  void end();
  // The body over the bound framebuffer (the eye's, its viewport) within `areas_px` (eye pixels,
  // rows top-down, disjoint: each is blended once). `scene_depth`: the eye's remote window depths
  // (an R32F texture at the eye's size), 0 for none.
  void composite(int divisor, std::span<const cv::Rect> areas_px, unsigned scene_depth);

 private:
  struct Gl;
  std::unique_ptr<Gl> gl_;
};

// Eye pixels (rows top-down) that hold what the body pass can draw of the capsules (boxes of 1.2
// times the larger radius around each segment) in front of the near plane, padded by `pad_px`.
cv::Rect body_bounds_px(const Intrinsics& k, const glm::dvec3& p_RightEye,
                        std::span<const Capsule> capsules, int pad_px);

// The same pixels as body_bounds_px, each capsule's on its own, as disjoint rectangles of whole
// `tile_px` tiles (a run of tiles along a row, grown down over the rows with the same run) cut to
// the image: two hands far apart do not make the rectangle between them shaded.
std::vector<cv::Rect> body_tiles_px(const Intrinsics& k, const glm::dvec3& p_RightEye,
                                    std::span<const Capsule> capsules, int pad_px, int tile_px);

// The window depth (0 near .. 1 far, as the renderer's depth buffer holds it) of a point z_m
// ahead of the eye, clamped to the near and far planes.
double window_depth_of(double z_m);
// Per kDepthTile x kDepthTile tile of `window_depth` its nearest and farthest value.
inline constexpr int kDepthTile = 16;
void depth_tiles(const cv::Mat1f& window_depth, cv::Mat2f& tiles);
// The pixels of `rect_px` in the tiles holding a depth in [lo, hi] (their bounding box); empty
// if none.
cv::Rect tiles_within(const cv::Mat2f& tiles, const cv::Rect2d& rect_px, double lo, double hi);

// The body's screen tiles at the target's intrinsics `k` (the eye's, or BodyUpsample's reduced
// ones): each capsule is listed in the `tile_px` tiles its box's pixels (body_bounds_px, padded
// by a pixel) touch, each tile's list nearest first (by the capsule's nearest z with the blend's
// reach) with, per entry, its blend neighbours (`neighbours`, as blend_neighbours gives them) in
// the same list as a bit mask; only tiles with a capsule are kept. A tile with more than
// kMaxTileEntries is split in four, down to a pixel; past that the farthest are left out.
inline constexpr int kMaxTileEntries = 32;
struct BodyTiles {
  // x, y (first pixel), offset in list, count | side in pixels << 8
  std::vector<std::array<std::int32_t, 4>> tiles;
  std::vector<std::array<std::int32_t, 2>> list;  // capsule, its neighbours' entries (bit k)
  std::size_t left_out = 0;                       // entries past kMaxTileEntries in a pixel
};
void bin_body_tiles(const Intrinsics& k, const glm::dvec3& p_RightEye,
                    std::span<const Capsule> capsules,
                    std::span<const std::array<std::int32_t, kMaxBlendNeighbours>> neighbours,
                    int tile_px, BodyTiles& out);

// The body pass's shaders (body_pass_shaders.cpp): a quad per tile, and the march of each pixel
// against its tile's capsules. kBodyTilesFs, as the mesh's shaders, is completed by body_shader:
// the version line, kBodyShadeGlsl (the skin's shading) and kBodyFieldGlsl (the capsules' field)
// before it.
extern const char* const kBodyShadeGlsl;
extern const char* const kBodyFieldGlsl;
extern const char* const kBodyTilesVs;
extern const char* const kBodyTilesFs;
// `body` after the version line, kBodyShadeGlsl and kBodyFieldGlsl.
std::string body_shader(const char* body);

// Per capsule 12 floats, in the eye's frame (its centre the origin): a and its radius, b and its
// radius, rgb and lit (1) or a marker (0); a capsule with a radius that is not positive or a
// point that is not finite is all zeros (nothing drawn). The march's and the mesh's texture
// buffer.
inline constexpr std::size_t kCapsuleFloats = 12;
void pack_capsules(std::span<const Capsule> capsules, const glm::dvec3& p_RightEye,
                   std::vector<float>& out);

// The body as triangles (body_mesh.cpp): one canonical capsule mesh (capsule_mesh.h) drawn once
// per capsule, instanced, each vertex placed on its capsule's round cone in the vertex shader and
// pushed out along its normal onto the smooth union with the capsules it shares an end with (the
// march's field: the fillets at the joints), nearest capsules first, with the early depth test
// (no gl_FragDepth) and back faces culled.
class BodyMesh {
 public:
  BodyMesh();  // compiles the shaders and uploads the mesh; the GL context must be current
  ~BodyMesh();
  BodyMesh(const BodyMesh&) = delete;
  BodyMesh& operator=(const BodyMesh&) = delete;

  // Into the bound framebuffer (its viewport k's size) with its depth tested and written, lit
  // with `exposure`; capsules with a radius that is not positive or a point that is not finite
  // are left out.
  void draw(const Intrinsics& k, const glm::dvec3& p_RightEye, std::span<const Capsule> capsules,
            float exposure);

 private:
  struct Gl;
  std::unique_ptr<Gl> gl_;
};

class BodyPass {
 public:
  BodyPass();  // compiles the shaders; the GL context must be current
  ~BodyPass();
  BodyPass(const BodyPass&) = delete;
  BodyPass& operator=(const BodyPass&) = delete;

  // The eye's remote depth for the passes below: the depth buffer's content (window depths, rows
  // top-down); an empty image: none.
  void set_scene_depth(const cv::Mat1f& window_depth);
  // Darkens the framebuffer's colour where the remote surface lies near a fingertip.
  void draw_contact_shadows(const Intrinsics& k, const glm::dvec3& p_RightEye,
                            std::span<const glm::dvec3> fingertips);
  // The body in two steps, so that the eye's picture can be taken after the body is drawn (the
  // video late-latched). The mesh at the eye's size (divisor 1): draw_body keeps what to draw
  // and composite_body draws it into the bound framebuffer (the eye's), depth-tested against its
  // depth buffer, which must then hold the remote depth (draws_into_target says so). Otherwise
  // draw_body draws the body into `slot`'s own offscreen target (one per eye, 0 or 1) at
  // 1/divisor of the eye's resolution, and composite_body puts it over the bound framebuffer,
  // each sample hidden where the remote depth (set_scene_depth's, at composite time) is nearer.
  // The bound framebuffer and viewport are kept by draw_body.
  void draw_body(int slot, const Intrinsics& k, const glm::dvec3& p_RightEye,
                 std::span<const Capsule> capsules, float exposure, int divisor = 1);
  void composite_body(int slot);
  bool draws_into_target(int slot) const;
  static constexpr int kSlots = 2;

  // The mesh (the default) or the ray-marched reference.
  void set_shape(BodyShape shape);
  // While on, the body's draw (draw_body's, or composite_body's when it draws the mesh) counts
  // its fragment shader's runs (a stall: for the benchmark); last_body_fragments() is the last
  // draw's count.
  void set_counting(bool on);
  BodyFragments last_body_fragments() const;

  static constexpr std::size_t kMaxCapsules = 256;  // more are not drawn

 private:
  struct Gl;
  std::unique_ptr<Gl> gl_;
};

}  // namespace telex::local
