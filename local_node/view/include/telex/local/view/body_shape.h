// SPDX-License-Identifier: MIT
// How the stereo renderer draws the body (StereoRenderer::set_body_shape) and what a body layer
// cost in fragments (StereoRenderer::body_fragments): shared by the renderer and its body pass.
#pragma once

#include <cstdint>

namespace telex::local {

// How the body's capsules are drawn: as triangles (the shipped path: one canonical mesh per
// capsule, skinned in the vertex shader, early depth), or ray-marched as one smooth surface
// (their smooth union: the reference the mesh is measured against).
enum class BodyShape { Mesh, Marched };

// What one body layer cost in fragments (StereoRenderer::set_count_body_fragments): the samples
// that passed the depth test (for the mesh, with its early depth test, the fragments shaded) and
// the fragment shader's runs as the driver counts them (0 where it does not; llvmpipe counts
// every lane of each 4x4 block a triangle touches, so small triangles count many).
struct BodyFragments {
  std::uint64_t passed = 0;
  std::uint64_t invocations = 0;
};

}  // namespace telex::local
