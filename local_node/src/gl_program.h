// SPDX-License-Identifier: MIT
// One GLSL program from a vertex and a fragment shader, for the view's passes (the body, the
// warp): compile errors and link errors come back as std::runtime_error with the driver's log.
#pragma once

#include <epoxy/gl.h>

#include <string_view>

namespace telex::local {

// `what` names the pass in the error ("stereo view: body", "warp"). The GL context must be current.
GLuint link_program(const char* vertex_source, const char* fragment_source, std::string_view what);

}  // namespace telex::local
