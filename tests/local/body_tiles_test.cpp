// SPDX-License-Identifier: MIT
// The body pass's screen tiles (bin_body_tiles): each capsule listed in every tile its pixels
// touch, nearest first, with its blend neighbours in the same list as a bit mask, and a tile with
// too many split down to a pixel, where the nearest are kept.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <random>
#include <vector>

#include "body_pass.h"

namespace telex::local {
namespace {

double z_near_of(const Capsule& c) {
  const double rb = c.radius_b_m < 0.0 ? c.radius_m : c.radius_b_m;
  return std::min(c.a.z, c.b.z) - (std::max(c.radius_m, rb) * 1.875 + 5e-4);
}

// The tile holding pixel p, or -1.
int tile_of(const BodyTiles& tiles, cv::Point p) {
  for (std::size_t t = 0; t < tiles.tiles.size(); ++t) {
    const auto& tile = tiles.tiles[t];
    const int side = tile[3] >> 8;
    if (cv::Rect(tile[0], tile[1], side, side).contains(p)) return static_cast<int>(t);
  }
  return -1;
}

// A hand-sized pile: finger chains (capsules sharing ends, which blend) and loose balls.
std::vector<Capsule> pile() {
  std::mt19937 rng(29);
  std::uniform_real_distribution<double> u(-0.04, 0.04), z(0.35, 0.5);
  std::vector<Capsule> out;
  for (int f = 0; f < 5; ++f) {
    glm::dvec3 p(u(rng), u(rng), z(rng));
    for (int s = 0; s < 3; ++s) {
      const glm::dvec3 q = p + glm::dvec3(0.01, 0.02, 0.005);
      out.push_back({p, q, 0.008, {180, 200, 230}, true, 0.007});
      p = q;
    }
  }
  for (int i = 0; i < 20; ++i) {
    const glm::dvec3 c(u(rng), u(rng), z(rng));
    out.push_back({c, c, 0.006, {180, 200, 230}, true, -1.0});
  }
  return out;
}

TEST(BodyTiles, EachCapsuleIsListedInTheTilesItsPixelsTouchNearestFirstWithItsNeighbours) {
  const Intrinsics k = kinect_v1_intrinsics(640, 480).scaled(320, 180);
  const glm::dvec3 p_RightEye(-0.064, 0.0, 0.0);
  const std::vector<Capsule> capsules = pile();
  const auto neighbours = blend_neighbours(capsules);
  BodyTiles tiles;
  bin_body_tiles(k, p_RightEye, capsules, neighbours, 16, tiles);
  ASSERT_FALSE(tiles.tiles.empty());
  EXPECT_EQ(tiles.left_out, 0u);
  std::size_t pairs = 0;
  for (const auto& tile : tiles.tiles) {
    const int count = tile[3] & 255;
    ASSERT_GE(count, 1);
    ASSERT_LE(count, kMaxTileEntries);
    for (int e = 0; e < count; ++e) {
      const auto& entry = tiles.list[static_cast<std::size_t>(tile[2] + e)];
      const Capsule& c = capsules[static_cast<std::size_t>(entry[0])];
      if (e > 0) {
        const auto& before = tiles.list[static_cast<std::size_t>(tile[2] + e - 1)];
        EXPECT_LE(z_near_of(capsules[static_cast<std::size_t>(before[0])]), z_near_of(c));
      }
      // Bit f set exactly when entry f is one of this capsule's blend neighbours.
      for (int f = 0; f < count; ++f) {
        const std::int32_t other = tiles.list[static_cast<std::size_t>(tile[2] + f)][0];
        const auto& n = neighbours[static_cast<std::size_t>(entry[0])];
        const bool is_neighbour = std::find(n.begin(), n.end(), other) != n.end();
        EXPECT_EQ((entry[1] >> f) & 1, is_neighbour ? 1 : 0);
        pairs += is_neighbour ? 1 : 0;
      }
    }
  }
  EXPECT_GT(pairs, 0u);  // the finger chains' joints share tiles
  // Every pixel of every capsule's bounds lies in exactly one tile, which lists the capsule.
  for (std::size_t i = 0; i < capsules.size(); ++i) {
    const cv::Rect r = body_bounds_px(k, p_RightEye, std::span<const Capsule>(&capsules[i], 1), 1);
    ASSERT_FALSE(r.empty());
    for (int y = r.y; y < r.br().y; y += 3)
      for (int x = r.x; x < r.br().x; x += 3) {
        const int t = tile_of(tiles, {x, y});
        ASSERT_GE(t, 0) << "capsule " << i << " pixel " << x << "," << y;
        const auto& tile = tiles.tiles[static_cast<std::size_t>(t)];
        const auto first = tiles.list.begin() + tile[2];
        EXPECT_TRUE(std::any_of(first, first + (tile[3] & 255),
                                [&](const auto& e) { return e[0] == static_cast<int>(i); }));
      }
  }
}

TEST(BodyTiles, ATileWithMoreThanItsShareSplitsDownToAPixelWhereTheNearestAreKept) {
  const Intrinsics k = kinect_v1_intrinsics(640, 480).scaled(320, 240);
  // 40 balls one behind the other on the optical axis: every pixel they cover sees all of them.
  std::vector<Capsule> capsules;
  for (int i = 0; i < 40; ++i) {
    const glm::dvec3 c(0.0, 0.0, 0.3 + 0.01 * (39 - i));  // listed farthest first
    capsules.push_back({c, c, 0.004, {180, 200, 230}, true, -1.0});
  }
  const auto neighbours = blend_neighbours(capsules);
  BodyTiles tiles;
  bin_body_tiles(k, glm::dvec3(0.0), capsules, neighbours, 16, tiles);
  EXPECT_GT(tiles.left_out, 0u);
  const int centre = tile_of(tiles, {static_cast<int>(k.cx), static_cast<int>(k.cy)});
  ASSERT_GE(centre, 0);
  const auto& tile = tiles.tiles[static_cast<std::size_t>(centre)];
  EXPECT_EQ(tile[3] >> 8, 1);  // split down to a pixel
  ASSERT_EQ(tile[3] & 255, kMaxTileEntries);
  // The nearest 32 (the last 32 given), nearest first; no neighbours among separate balls.
  for (int e = 0; e < kMaxTileEntries; ++e) {
    const auto& entry = tiles.list[static_cast<std::size_t>(tile[2] + e)];
    EXPECT_EQ(entry[0], 39 - e);
    EXPECT_EQ(entry[1], 0);
  }
  for (const auto& t : tiles.tiles) EXPECT_LE(t[3] & 255, kMaxTileEntries);
}

}  // namespace
}  // namespace telex::local
