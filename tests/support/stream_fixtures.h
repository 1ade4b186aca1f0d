// SPDX-License-Identifier: MIT
// Small stream configurations for frame-assembly tests.
#pragma once

#include "telex/proto/messages.h"

namespace telex::test {

// A 40x30 frame in a 2x2 grid of 20x15 tiles, f = 50 px.
inline proto::StreamConfig stream_config_2x2() {
  proto::StreamConfig c;
  c.width = 40;
  c.height = 30;
  c.tile_width = 20;
  c.tile_height = 15;
  c.grid_cols = 2;
  c.grid_rows = 2;
  c.fx = c.fy = 50;
  c.cx = 19.5;
  c.cy = 14.5;
  return c;
}

}  // namespace telex::test
