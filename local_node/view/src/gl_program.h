// SPDX-License-Identifier: MIT
// One GLSL program from a vertex and a fragment shader, for the view's passes (the body, the
// warp): compile errors and link errors come back as std::runtime_error with the driver's log.
// And the passes' offscreen textures.
#pragma once

#include <epoxy/gl.h>

#include <cstddef>
#include <string_view>

namespace telex::local {

// `what` names the pass in the error ("stereo view: body", "warp"). The GL context must be current.
GLuint link_program(const char* vertex_source, const char* fragment_source, std::string_view what);

// A vertex shader drawing one screen rectangle (uniform vec4 u_rect: x0, y0, x1, y1 in NDC) as a
// 4-vertex triangle strip, for passes that shade only part of the screen.
inline constexpr const char* kRectVertexShader = R"(#version 330 core
uniform vec4 u_rect;  // x0, y0, x1, y1 in NDC
void main() {
  vec2 c = vec2(gl_VertexID & 1, gl_VertexID >> 1);
  gl_Position = vec4(mix(u_rect.xy, u_rect.zw, c), 0.0, 1.0);
}
)";

// `bytes` from `data` into `buffer`, read by the shader as the texture buffer `texture` of texel
// `format` on texture unit `unit` (its sampler uniform at `location`).
void texture_buffer(GLuint buffer, GLuint texture, const void* data, std::size_t bytes,
                    GLenum format, int unit, GLint location);

// A 2D texture of w x h with no data yet, `filter` for both directions, edges clamped.
GLuint make_texture(GLenum internal, int w, int h, GLenum format, GLenum type, GLint filter);

}  // namespace telex::local
