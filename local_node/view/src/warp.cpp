// SPDX-License-Identifier: MIT
// The depth-image-based warp: an attributeless grid mesh whose vertex shader reads the depth
// texture, drops triangles across discontinuities and moves each vertex from the capture pose to
// the display pose; a full-screen pass first lays the hole fill (the previous output, turned by the
// display's rotation since, or grey). Two framebuffers alternate so the previous output stays.
#include "telex/local/view/warp.h"

#include <epoxy/egl.h>
#include <epoxy/gl.h>

#include <algorithm>
#include <array>
#include <glm/gtc/type_ptr.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "egl_headless.h"
#include "gl_program.h"
#include "telex/local/view/stereo_renderer.h"

namespace telex::local {
namespace {

// One vertex per grid point, at the pixel it samples (clamped to the image, so the last row and
// column end on the last pixel), moved from the capture pose to the display pose. Which triangles
// are drawn is the index buffer's (mesh_triangles): one shared vertex each, so llvmpipe shades a
// grid point once instead of once per triangle.
constexpr const char* kMeshVs = R"(#version 330 core
uniform usampler2D u_depth_mm;
uniform ivec2 u_size;
uniform int u_step;
uniform int u_vertices_per_row;
uniform vec4 u_k;  // fx, fy, cx, cy
uniform mat3 u_R_DisplayCapture;
uniform vec3 u_p_DisplayCapture_m;
uniform bool u_video_apart;  // the video was captured at another pose than the depth
uniform mat3 u_R_VideoDepth;
uniform vec3 u_p_VideoDepth_m;
uniform mat4 u_projection;
out vec2 v_uv;
out float v_z_mm;
void main() {
  ivec2 grid = ivec2(gl_VertexID % u_vertices_per_row, gl_VertexID / u_vertices_per_row);
  ivec2 p = min(grid * u_step, u_size - 1);
  float z_m = float(texelFetch(u_depth_mm, p, 0).r) * 1e-3;
  vec3 p_Capture = vec3((vec2(p) - u_k.zw) / u_k.xy * z_m, z_m);
  vec3 p_Display = u_R_DisplayCapture * p_Capture + u_p_DisplayCapture_m;
  gl_Position = u_projection * vec4(p_Display, 1.0);
  v_uv = (vec2(p) + 0.5) / vec2(u_size);
  vec3 p_Video = u_R_VideoDepth * p_Capture + u_p_VideoDepth_m;
  if (u_video_apart && p_Video.z > 0.0)
    v_uv = (u_k.xy * p_Video.xy / p_Video.z + u_k.zw + 0.5) / vec2(u_size);
  v_z_mm = p_Display.z * 1000.0;
}
)";

constexpr const char* kMeshFs = R"(#version 330 core
uniform sampler2D u_color;
in vec2 v_uv;
in float v_z_mm;
layout(location = 0) out vec4 o_color;
layout(location = 1) out uint o_depth_mm;
void main() {
  o_color = vec4(texture(u_color, v_uv).rgb, 1.0);
  o_depth_mm = uint(clamp(v_z_mm + 0.5, 1.0, 65535.0));
}
)";

// One triangle over the whole target, on the far plane: with the depth test (LEQUAL, the buffer
// cleared to 1) it reaches only the pixels the mesh left empty.
constexpr const char* kFillVs = R"(#version 330 core
void main() {
  vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
  gl_Position = vec4(p * 2.0 - 1.0, 1.0, 1.0);
}
)";

// A pixel the mesh left empty. First the capture's own pixel that lands here, found by iterating
// the inverse warp from the rotation-only guess (H_capture = K R^T K^-1) and accepted only when it
// lands within half a pixel: this fills the strips where an edge's triangles were dropped although
// nothing was uncovered. Where the capture has no depth the guess itself is taken. Where the guess
// is outside the capture (the border a turn uncovers) the previous output, turned by the display's
// rotation since (H_previous = K R_PreviousDisplay K^-1), takes over; a disocclusion inside the
// view is shaded neutrally, since the previous output there may hold the occluder's old edge (a
// ghost). Never a stretched neighbour.
constexpr const char* kFillFs = R"(#version 330 core
uniform sampler2D u_color;
uniform usampler2D u_depth_mm;
uniform sampler2D u_previous;
uniform bool u_has_previous;
uniform mat3 u_H_capture;
uniform mat3 u_H_previous;
uniform vec4 u_k;  // fx, fy, cx, cy
uniform mat3 u_R_DisplayCapture;
uniform vec3 u_p_DisplayCapture_m;
uniform bool u_video_apart;
uniform mat3 u_R_VideoDepth;
uniform vec3 u_p_VideoDepth_m;
uniform mat3 u_H_video;  // display pixel -> video pixel, the rotation only
uniform vec2 u_size;
uniform vec3 u_neutral_rgb;
uniform float u_sliver_px;
layout(location = 0) out vec4 o_color;
layout(location = 1) out uint o_depth_mm;
bool in_image(vec2 px) {
  return all(greaterThanEqual(px, vec2(-0.5))) && all(lessThanEqual(px, u_size - 0.5));
}
// The video's colour of a depth pixel `source` whose point is p_Capture (the depth's frame).
vec3 video_at(vec2 source, vec3 p_Capture) {
  vec3 p_Video = u_R_VideoDepth * p_Capture + u_p_VideoDepth_m;
  if (u_video_apart && p_Video.z > 0.0) source = u_k.xy * p_Video.xy / p_Video.z + u_k.zw;
  return texture(u_color, (source + 0.5) / u_size).rgb;
}
void main() {
  vec2 want = gl_FragCoord.xy - 0.5;
  vec3 q = u_H_capture * vec3(want, 1.0);
  vec2 source = q.xy / q.z;
  bool unseen = q.z <= 0.0 || !in_image(source);
  float best_e2 = 1e30;
  vec3 best_rgb = u_neutral_rgb;
  for (int i = 0; i < 4 && q.z > 0.0 && in_image(source); ++i) {
    float z_m = float(texelFetch(u_depth_mm, ivec2(floor(source + 0.5)), 0).r) * 1e-3;
    if (z_m <= 0.0) {
      // The remote has no depth there (a sensor's shadow, beyond its range or view): the video
      // as if far away, turned only, which is exact for the eye the head turns about.
      if (i == 0) {
        vec3 v = u_H_video * vec3(want, 1.0);
        vec2 seen = u_video_apart && v.z > 0.0 ? v.xy / v.z : source;
        o_color = vec4(texture(u_color, (seen + 0.5) / u_size).rgb, 1.0);
        o_depth_mm = 0u;
        return;
      }
      break;
    }
    vec3 p_Capture = vec3((source - u_k.zw) / u_k.xy * z_m, z_m);
    vec3 p_Display = u_R_DisplayCapture * p_Capture + u_p_DisplayCapture_m;
    if (p_Display.z <= 0.0) break;
    vec2 error = u_k.xy * p_Display.xy / p_Display.z + u_k.zw - want;
    float e2 = dot(error, error);
    if (e2 <= 0.25) {
      o_color = vec4(video_at(source, p_Capture), 1.0);
      o_depth_mm = uint(clamp(p_Display.z * 1000.0 + 0.5, 1.0, 65535.0));
      return;
    }
    if (e2 < best_e2) {
      best_e2 = e2;
      best_rgb = video_at(source, p_Capture);
    }
    source -= error;
  }
  // A sliver uncovered by the eye's own small move (a millimetres' shift of an eye off the turn's
  // axis opens a pixel or two along an edge): the capture's pixel that lands nearest, since a
  // neutral line there would outline the edge. A wider disocclusion stays neutral below.
  if (best_e2 <= u_sliver_px * u_sliver_px) {
    o_color = vec4(best_rgb, 1.0);
    o_depth_mm = 0u;
    return;
  }
  vec3 r = u_H_previous * vec3(want, 1.0);
  vec2 px = r.xy / r.z;
  o_color = vec4(unseen && u_has_previous && r.z > 0.0 && in_image(px)
                     ? texture(u_previous, (px + 0.5) / u_size).rgb : u_neutral_rgb, 1.0);
  o_depth_mm = 0u;
}
)";

std::string egl_error(const char* what) { return local::egl_error("warp", what); }

glm::mat3 to_float(const glm::dmat3& m) { return glm::mat3(m); }

// One warp's poses: the depth's capture to the display, and to the video's capture.
struct WarpPoses {
  RigidTransform X_DisplayDepth, X_VideoDepth;
  bool video_apart = false;  // X_VideoDepth is not the identity
};

}  // namespace

void mesh_triangles(const cv::Mat1w& depth_mm, int step, double max_depth_step_ratio,
                    std::vector<std::uint32_t>& indices, int merge) {
  indices.clear();
  const int w = depth_mm.cols, h = depth_mm.rows;
  if (w < 2 || h < 2 || step < 1) return;
  const int vx = (w - 1 + step - 1) / step + 1, vy = (h - 1 + step - 1) / step + 1;
  const int cells_x = vx - 1, cells_y = vy - 1;
  const auto ratio = static_cast<float>(max_depth_step_ratio);
  const auto sample = [&](int gx, int gy) -> float {
    return depth_mm(std::min(gy * step, h - 1), std::min(gx * step, w - 1));
  };
  const auto keep = [ratio](float a, float b, float c) {
    const float lo = std::min({a, b, c}), hi = std::max({a, b, c});
    return lo > 0.0f && hi - lo <= ratio * lo;
  };
  const auto vertex = [vx](int gx, int gy) { return static_cast<std::uint32_t>(gy * vx + gx); };
  // One cell of `size` grid steps from (gx, gy): two triangles, each kept by its corners.
  const auto cell = [&](int gx, int gy, int size) {
    const float z00 = sample(gx, gy), z10 = sample(gx + size, gy), z01 = sample(gx, gy + size),
                z11 = sample(gx + size, gy + size);
    const std::uint32_t v00 = vertex(gx, gy), v10 = vertex(gx + size, gy),
                        v01 = vertex(gx, gy + size), v11 = vertex(gx + size, gy + size);
    if (keep(z00, z10, z11)) indices.insert(indices.end(), {v00, v10, v11});
    if (keep(z00, z11, z01)) indices.insert(indices.end(), {v00, v11, v01});
  };
  if (merge <= 1) {
    for (int gy = 0; gy < cells_y; ++gy)
      for (int gx = 0; gx < cells_x; ++gx) cell(gx, gy, 1);
    return;
  }
  // Each cell's depth range over all its pixels (its border included): a coarse cell is drawn
  // whole only where no pixel inside it jumps or lacks depth, so an edge between its corners
  // still splits it into the fine cells, whose triangles drop there and open the hole.
  std::vector<float> lo(static_cast<std::size_t>(cells_x * cells_y)), hi(lo.size());
  for (int gy = 0; gy < cells_y; ++gy)
    for (int gx = 0; gx < cells_x; ++gx) {
      float l = 65536.0f, u = 0.0f;
      for (int y = gy * step; y <= std::min((gy + 1) * step, h - 1); ++y) {
        const std::uint16_t* row = depth_mm.ptr<std::uint16_t>(y);
        for (int x = gx * step; x <= std::min((gx + 1) * step, w - 1); ++x) {
          l = std::min(l, static_cast<float>(row[x]));
          u = std::max(u, static_cast<float>(row[x]));
        }
      }
      lo[static_cast<std::size_t>(gy * cells_x + gx)] = l;
      hi[static_cast<std::size_t>(gy * cells_x + gx)] = u;
    }
  for (int cy = 0; cy < cells_y; cy += merge)
    for (int cx = 0; cx < cells_x; cx += merge) {
      bool smooth = cx + merge <= cells_x && cy + merge <= cells_y;
      float l = 65536.0f, u = 0.0f;
      for (int gy = cy; smooth && gy < cy + merge; ++gy)
        for (int gx = cx; gx < cx + merge; ++gx) {
          l = std::min(l, lo[static_cast<std::size_t>(gy * cells_x + gx)]);
          u = std::max(u, hi[static_cast<std::size_t>(gy * cells_x + gx)]);
        }
      if (smooth && l > 0.0f && u - l <= ratio * l) {
        cell(cx, cy, merge);
        continue;
      }
      for (int gy = cy; gy < std::min(cy + merge, cells_y); ++gy)
        for (int gx = cx; gx < std::min(cx + merge, cells_x); ++gx) cell(gx, gy, 1);
    }
}

RigidTransform eye_display_from_capture(const glm::dmat3& R_DisplayCapture,
                                        const glm::dvec3& p_RightEye) {
  return {R_DisplayCapture, R_DisplayCapture * p_RightEye - p_RightEye};
}

struct DepthWarp::Impl {
  int width = 0, height = 0;
  // The context the GL objects live in; owned only when the warp made it.
  EGLDisplay display = EGL_NO_DISPLAY;
  EGLContext context = EGL_NO_CONTEXT;
  bool owns_context = false;
  GLuint mesh = 0, fill = 0, vao = 0, elements = 0;
  std::vector<std::uint32_t> indices;  // this frame's triangles, reused
  GLuint color_in = 0, depth_in = 0;
  std::array<GLuint, 2> color_out{}, fbo{};
  GLuint depth_mm_out = 0, z_buffer = 0;
  int current = 0;  // the output slot written last
  bool has_previous = false;

  void make_context() {
    const HeadlessEgl egl = create_headless_egl("warp");
    display = egl.display;
    context = egl.context;
    owns_context = true;
    // Everything is drawn into the warp's own framebuffers: no surface is needed.
    if (!eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context))
      throw std::runtime_error(egl_error("cannot make a surfaceless OpenGL context current"));
  }

  void make_objects() {
    mesh = link_program(kMeshVs, kMeshFs, "warp");
    fill = link_program(kFillVs, kFillFs, "warp");
    glGenVertexArrays(1, &vao);
    glGenBuffers(1, &elements);
    color_in = make_texture(GL_RGBA8, width, height, GL_BGR, GL_UNSIGNED_BYTE, GL_LINEAR);
    depth_in = make_texture(GL_R16UI, width, height, GL_RED_INTEGER, GL_UNSIGNED_SHORT, GL_NEAREST);
    depth_mm_out =
        make_texture(GL_R16UI, width, height, GL_RED_INTEGER, GL_UNSIGNED_SHORT, GL_NEAREST);
    glGenRenderbuffers(1, &z_buffer);
    glBindRenderbuffer(GL_RENDERBUFFER, z_buffer);
    glRenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT32F, width, height);
    glGenFramebuffers(2, fbo.data());
    for (std::size_t i = 0; i < 2; ++i) {
      color_out[i] = make_texture(GL_RGBA8, width, height, GL_BGR, GL_UNSIGNED_BYTE, GL_LINEAR);
      glBindFramebuffer(GL_FRAMEBUFFER, fbo[i]);
      glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, color_out[i], 0);
      glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT1, GL_TEXTURE_2D, depth_mm_out, 0);
      glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, z_buffer);
      const GLenum buffers[2] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1};
      glDrawBuffers(2, buffers);
      if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
        throw std::runtime_error("warp: the offscreen framebuffer is incomplete");
    }
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
  }

  void delete_objects() {
    glDeleteProgram(mesh);
    glDeleteProgram(fill);
    glDeleteVertexArrays(1, &vao);
    glDeleteBuffers(1, &elements);
    const std::array<GLuint, 5> textures{color_in, depth_in, depth_mm_out, color_out[0],
                                         color_out[1]};
    glDeleteTextures(static_cast<GLsizei>(textures.size()), textures.data());
    glDeleteRenderbuffers(1, &z_buffer);
    glDeleteFramebuffers(2, fbo.data());
  }

  void upload(const cv::Mat3b& eye_bgr, const cv::Mat1w& depth) {
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glPixelStorei(GL_UNPACK_ROW_LENGTH, 0);
    const cv::Mat3b c = eye_bgr.isContinuous() ? eye_bgr : eye_bgr.clone();
    const cv::Mat1w d = depth.isContinuous() ? depth : depth.clone();
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_2D, color_in);
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, width, height, GL_BGR, GL_UNSIGNED_BYTE, c.data);
    glBindTexture(GL_TEXTURE_2D, depth_in);
    glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, width, height, GL_RED_INTEGER, GL_UNSIGNED_SHORT,
                    d.data);
  }

  // A rigid transform's rotation and translation as the uniforms `R_name` and `p_name`.
  static void set_transform(GLuint program, const char* R_name, const char* p_name,
                            const RigidTransform& X) {
    const glm::mat3 R = to_float(X.rotation);
    glUniformMatrix3fv(glGetUniformLocation(program, R_name), 1, GL_FALSE, glm::value_ptr(R));
    glUniform3f(glGetUniformLocation(program, p_name), static_cast<float>(X.translation_m.x),
                static_cast<float>(X.translation_m.y), static_cast<float>(X.translation_m.z));
  }

  // The poses' uniforms, shared by both programs.
  static void set_pose(GLuint program, const Intrinsics& k, const WarpPoses& poses) {
    glUniform4f(glGetUniformLocation(program, "u_k"), static_cast<float>(k.fx),
                static_cast<float>(k.fy), static_cast<float>(k.cx), static_cast<float>(k.cy));
    set_transform(program, "u_R_DisplayCapture", "u_p_DisplayCapture_m", poses.X_DisplayDepth);
    glUniform1i(glGetUniformLocation(program, "u_video_apart"), poses.video_apart ? 1 : 0);
    set_transform(program, "u_R_VideoDepth", "u_p_VideoDepth_m", poses.X_VideoDepth);
  }

  void draw_fill(const WarpOptions& o, const Intrinsics& k, const WarpPoses& poses,
                 const glm::dmat3& R_DisplayPrevious, int previous) {
    const glm::dmat3 K(k.fx, 0.0, 0.0, 0.0, k.fy, 0.0, k.cx, k.cy, 1.0);  // column-major
    const glm::dmat3 K_inv = glm::inverse(K);
    const glm::dmat3 R_DepthDisplay = glm::transpose(poses.X_DisplayDepth.rotation);
    const glm::mat3 H_previous = to_float(K * glm::transpose(R_DisplayPrevious) * K_inv);
    const glm::mat3 H_capture = to_float(K * R_DepthDisplay * K_inv);
    const glm::mat3 H_video = to_float(K * poses.X_VideoDepth.rotation * R_DepthDisplay * K_inv);
    glUseProgram(fill);
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_2D, color_in);
    glUniform1i(glGetUniformLocation(fill, "u_color"), 0);
    glActiveTexture(GL_TEXTURE1);
    glBindTexture(GL_TEXTURE_2D, depth_in);
    glUniform1i(glGetUniformLocation(fill, "u_depth_mm"), 1);
    glActiveTexture(GL_TEXTURE2);
    glBindTexture(GL_TEXTURE_2D, color_out[static_cast<std::size_t>(previous)]);
    glUniform1i(glGetUniformLocation(fill, "u_previous"), 2);
    glUniform1i(glGetUniformLocation(fill, "u_has_previous"),
                has_previous && o.hole_fill == HoleFill::Previous ? 1 : 0);
    glUniformMatrix3fv(glGetUniformLocation(fill, "u_H_capture"), 1, GL_FALSE,
                       glm::value_ptr(H_capture));
    glUniformMatrix3fv(glGetUniformLocation(fill, "u_H_previous"), 1, GL_FALSE,
                       glm::value_ptr(H_previous));
    glUniformMatrix3fv(glGetUniformLocation(fill, "u_H_video"), 1, GL_FALSE,
                       glm::value_ptr(H_video));
    set_pose(fill, k, poses);
    glUniform2f(glGetUniformLocation(fill, "u_size"), static_cast<float>(width),
                static_cast<float>(height));
    glUniform3f(glGetUniformLocation(fill, "u_neutral_rgb"), o.neutral_bgr[2] / 255.0f,
                o.neutral_bgr[1] / 255.0f, o.neutral_bgr[0] / 255.0f);
    glUniform1f(glGetUniformLocation(fill, "u_sliver_px"), static_cast<float>(o.sliver_px));
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LEQUAL);
    glDepthMask(GL_FALSE);
    glDrawArrays(GL_TRIANGLES, 0, 3);
    glDepthMask(GL_TRUE);
    glActiveTexture(GL_TEXTURE0);
  }

  void draw_mesh(const WarpOptions& o, const Intrinsics& k, const WarpPoses& poses) {
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, elements);  // the VAO's
    glBufferData(GL_ELEMENT_ARRAY_BUFFER,
                 static_cast<GLsizeiptr>(indices.size() * sizeof(std::uint32_t)), indices.data(),
                 GL_STREAM_DRAW);
    glUseProgram(mesh);
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_2D, depth_in);
    glUniform1i(glGetUniformLocation(mesh, "u_depth_mm"), 0);
    glActiveTexture(GL_TEXTURE1);
    glBindTexture(GL_TEXTURE_2D, color_in);
    glUniform1i(glGetUniformLocation(mesh, "u_color"), 1);
    const int step = o.grid_step_px;
    const int quads_x = (width - 1 + step - 1) / step;
    glUniform2i(glGetUniformLocation(mesh, "u_size"), width, height);
    glUniform1i(glGetUniformLocation(mesh, "u_step"), step);
    glUniform1i(glGetUniformLocation(mesh, "u_vertices_per_row"), quads_x + 1);
    set_pose(mesh, k, poses);
    const glm::mat4 projection = projection_from_intrinsics(k, kViewNear_m, kViewFar_m);
    glUniformMatrix4fv(glGetUniformLocation(mesh, "u_projection"), 1, GL_FALSE,
                       glm::value_ptr(projection));
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LESS);
    glDepthMask(GL_TRUE);
    if (!indices.empty())
      glDrawElements(GL_TRIANGLES, static_cast<GLsizei>(indices.size()), GL_UNSIGNED_INT, nullptr);
    glActiveTexture(GL_TEXTURE0);
  }

  // Fresh images each time: the caller keeps them while the next warp runs.
  void read_back(WarpedEye& out, bool bgr) const {
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    out.depth_mm.create(height, width);
    if (bgr) {
      out.bgr.create(height, width);
      glReadBuffer(GL_COLOR_ATTACHMENT0);
      glReadPixels(0, 0, width, height, GL_BGR, GL_UNSIGNED_BYTE, out.bgr.data);
    }
    glReadBuffer(GL_COLOR_ATTACHMENT1);
    glReadPixels(0, 0, width, height, GL_RED_INTEGER, GL_UNSIGNED_SHORT, out.depth_mm.data);
  }
};

DepthWarp::DepthWarp(int width, int height, WarpOptions options)
    : options_(options), impl_(std::make_unique<Impl>()) {
  if (width <= 0 || height <= 0 || width > 8192 || height > 8192)
    throw std::invalid_argument("warp: eye size " + std::to_string(width) + "x" +
                                std::to_string(height) + " is not in 1..8192");
  if (options.grid_step_px < 1 || options.grid_step_px > 64)
    throw std::invalid_argument("warp: grid step " + std::to_string(options.grid_step_px) +
                                " px is not in 1..64");
  if (options.merge_cells < 1 || options.merge_cells > 8)
    throw std::invalid_argument("warp: merge_cells " + std::to_string(options.merge_cells) +
                                " is not in 1..8");
  if (!(options.max_depth_step_ratio > 0.0))
    throw std::invalid_argument("warp: the depth step ratio must be positive");
  if (!(options.sliver_px >= 0.0 && options.sliver_px <= 16.0))
    throw std::invalid_argument("warp: sliver_px must be in 0..16");
  Impl& g = *impl_;
  g.width = width;
  g.height = height;
  g.context = eglGetCurrentContext();
  g.display = eglGetCurrentDisplay();
  if (g.context == EGL_NO_CONTEXT) g.make_context();
  if (epoxy_gl_version() < 33)
    throw std::runtime_error("warp: OpenGL " + std::to_string(epoxy_gl_version()) +
                             " is below 3.3 core");
  g.make_objects();
}

DepthWarp::~DepthWarp() {
  Impl& g = *impl_;
  // The objects die with their context; they are deleted only while it is still current here.
  if (g.context != EGL_NO_CONTEXT && eglGetCurrentContext() == g.context) g.delete_objects();
  if (g.owns_context) {
    eglMakeCurrent(g.display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    eglDestroyContext(g.display, g.context);
  }
}

void DepthWarp::reset_previous() { impl_->has_previous = false; }

WarpedEye DepthWarp::warp(const cv::Mat3b& eye_bgr, const cv::Mat1w& depth_mm, const Intrinsics& k,
                          const RigidTransform& X_DisplayCapture,
                          const glm::dmat3& R_DisplayPrevious) {
  return warp(eye_bgr, depth_mm, k, X_DisplayCapture, RigidTransform{}, R_DisplayPrevious);
}

WarpedEye DepthWarp::warp(const cv::Mat3b& video_bgr, const cv::Mat1w& depth_mm,
                          const Intrinsics& k, const RigidTransform& X_DisplayDepth,
                          const RigidTransform& X_VideoDepth, const glm::dmat3& R_DisplayPrevious) {
  Impl& g = *impl_;
  const WarpPoses poses{
      X_DisplayDepth, X_VideoDepth,
      X_VideoDepth.rotation != glm::dmat3(1.0) || X_VideoDepth.translation_m != glm::dvec3(0.0)};
  const cv::Size size(g.width, g.height);
  if (k.width != g.width || k.height != g.height || video_bgr.size() != size ||
      depth_mm.size() != size)
    throw std::invalid_argument("warp: the image, depth and intrinsics must be " +
                                std::to_string(g.width) + "x" + std::to_string(g.height));
  g.upload(video_bgr, depth_mm);
  mesh_triangles(depth_mm, options_.grid_step_px, options_.max_depth_step_ratio, g.indices,
                 options_.merge_cells);
  const int previous = g.current, now = 1 - g.current;
  glBindFramebuffer(GL_FRAMEBUFFER, g.fbo[static_cast<std::size_t>(now)]);
  glViewport(0, 0, g.width, g.height);
  glDisable(GL_CULL_FACE);
  glDisable(GL_BLEND);
  const GLfloat far_plane = 1.0f;
  glClearBufferfv(GL_DEPTH, 0, &far_plane);
  glBindVertexArray(g.vao);
  g.draw_mesh(options_, k, poses);
  g.draw_fill(options_, k, poses, R_DisplayPrevious, previous);
  glBindVertexArray(0);
  WarpedEye out;
  g.read_back(out, options_.read_back_bgr);
  glUseProgram(0);
  g.current = now;
  g.has_previous = true;
  out.texture = g.color_out[static_cast<std::size_t>(now)];
  return out;
}

}  // namespace telex::local
