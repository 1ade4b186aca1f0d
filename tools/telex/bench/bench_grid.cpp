// SPDX-License-Identifier: MIT
// `telex bench`: the grid of configurations and how each maps onto the shipping chain's options.
#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "bench.h"
#include "telex/common/stage_clock.h"

namespace telex::tool::bench {

double median(std::vector<double> v) {
  v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return !std::isfinite(x); }), v.end());
  if (v.empty()) return kNaN;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  if (v.size() % 2 == 1) return *mid;
  return 0.5 * (*mid + *std::max_element(v.begin(), mid));
}

double mean_finite(const std::vector<double>& v) {
  double sum = 0.0;
  std::size_t n = 0;
  for (double x : v)
    if (std::isfinite(x)) {
      sum += x;
      ++n;
    }
  return n ? sum / static_cast<double>(n) : kNaN;
}

const std::vector<std::string> kGroups = {"default", "resolution", "fill", "temporal", "bilateral",
                                          "normals", "codec",      "roi",  "combo"};

int group_index(const std::string& g) {
  const auto it = std::find(kGroups.begin(), kGroups.end(), g);
  return static_cast<int>(it - kGroups.begin());
}

namespace {

// The row named as the daemons' defaults builds the surface as telex-local does with no flags
// (telex-remote sends unfilled depth unless run with --fill).
void demand_daemons_default(const std::vector<Config>& grid) {
  const auto it = std::find_if(grid.begin(), grid.end(),
                               [](const Config& c) { return c.name == kDaemonsDefault; });
  if (it == grid.end())
    throw std::logic_error("the grid has no row " + std::string(kDaemonsDefault));
  const local::SurfaceOptions row = surface_options(*it), station;
  if (row.roi != station.roi || row.fill_here != station.fill_here ||
      row.bilateral != station.bilateral ||
      row.bilateral_options.radius_px != station.bilateral_options.radius_px ||
      row.normal_options.smooth_radius_px != station.normal_options.smooth_radius_px || it->fill)
    throw std::logic_error(std::string(kDaemonsDefault) +
                           " no longer builds the surface as telex-local's defaults do");
}

}  // namespace

std::vector<Config> make_grid(bool quick) {
  std::vector<Config> out;
  const Config base{.name = "default", .group = "default"};
  auto add = [&](const std::string& group, const std::string& name, auto mutate, bool in_quick) {
    if (quick && !in_quick) return;
    Config c = base;
    c.group = group;
    c.name = name;
    mutate(c);
    out.push_back(c);
  };
  add(
      "default", "default", [](Config&) {}, true);
  add(
      "resolution", "res160", [](Config& c) { c.width = 160, c.height = 120; }, true);
  add(
      "resolution", "res320", [](Config& c) { c.width = 320, c.height = 240; }, false);
  add(
      "fill", "fill_off", [](Config& c) { c.fill = false; }, true);
  for (int w : {3, 7, 9})
    add(
        "fill", "fill_w" + std::to_string(w), [w](Config& c) { c.fill_options.window_px = w; },
        w == 9);
  for (int b : {5, 10, 40})
    add(
        "fill", "fill_bin" + std::to_string(b), [b](Config& c) { c.fill_options.bin_mm = b; },
        false);
  add(
      "temporal", "temporal_off", [](Config& c) { c.temporal = false; }, true);
  add(
      "bilateral", "bil_off", [](Config& c) { c.bilateral = false; }, true);
  for (int r : {1, 3, 6})
    add(
        "bilateral", "bil_r" + std::to_string(r),
        [r](Config& c) { c.bilateral_options.radius_px = r; }, r == 6);
  for (double sd : {10.0, 60.0})
    add(
        "bilateral", "bil_sd" + std::to_string(static_cast<int>(sd)),
        [sd](Config& c) { c.bilateral_options.sigma_depth_mm = sd; }, false);
  add(
      "bilateral", "bil_ss1.5", [](Config& c) { c.bilateral_options.sigma_space_px = 1.5; }, false);
  add(
      "bilateral", "bil_noise3",
      [](Config& c) { c.bilateral_options.sigma_from_noise_model = true; }, false);
  for (int k : {0, 1})
    add(
        "normals", "n_smooth" + std::to_string(k),
        [k](Config& c) { c.normal_options.smooth_radius_px = k; }, k == 0);
  add(
      "normals", "n_plain", [](Config& c) { c.normal_method = NormalMethod::Plain; }, true);
  for (int lv : {1, 6, 9})
    add(
        "codec", "zip" + std::to_string(lv), [lv](Config& c) { c.zip_level = lv; }, lv == 6);
  add(
      "codec", "fast", [](Config& c) { c.codec = proto::Codec::Fast; }, true);
  add(
      "codec", "raw", [](Config& c) { c.codec = proto::Codec::Raw; }, true);
  add(
      "roi", "roi", [](Config& c) { c.roi = true; }, true);
  add(
      "roi", "roi320", [](Config& c) { c.roi = true, c.width = 320, c.height = 240; }, false);
  add(
      "roi", "roi160", [](Config& c) { c.roi = true, c.width = 160, c.height = 120; }, true);
  add(
      "combo", "cheap320",
      [](Config& c) {
        c.width = 320, c.height = 240, c.bilateral = false, c.codec = proto::Codec::Fast;
        c.normal_options.smooth_radius_px = 1;
      },
      false);
  add(
      "combo", "kinfu_r6_roi", [](Config& c) { c.bilateral_options.radius_px = 6, c.roi = true; },
      false);
  add(
      "combo", "smooth1_r1",
      [](Config& c) { c.bilateral_options.radius_px = 1, c.normal_options.smooth_radius_px = 1; },
      false);
  // Where to fill (issue 16): the remote sends the depth unfilled and the station fills it.
  add(
      "fill", "fill_station", [](Config& c) { c.fill = false, c.station_fill = true; }, false);
  add(
      "combo", "kinfu_r6_roi_fill_off",
      [](Config& c) { c.bilateral_options.radius_px = 6, c.roi = true, c.fill = false; }, false);
  add(
      "combo", kDaemonsDefault,
      [](Config& c) {
        c.bilateral_options.radius_px = 6, c.roi = true, c.fill = false, c.station_fill = true;
      },
      true);
  demand_daemons_default(out);
  return out;
}

std::vector<Config> select_configs(std::vector<Config> grid,
                                   const std::vector<std::string>& names) {
  if (names.empty()) return grid;
  std::vector<Config> out;
  for (const auto& n : names) {
    const auto it =
        std::find_if(grid.begin(), grid.end(), [&](const Config& c) { return c.name == n; });
    if (it == grid.end()) {
      std::string valid;
      for (const auto& c : grid) valid += (valid.empty() ? "" : ", ") + c.name;
      throw std::invalid_argument("telex bench: --config: no configuration '" + n +
                                  "' in this grid (valid: " + valid + ")");
    }
    out.push_back(*it);
  }
  return out;
}

std::string describe(const Config& c) {
  std::ostringstream os;
  os << c.width << 'x' << c.height << (c.fill && c.temporal ? " T" : " -")
     << ' ';  // temporal fill runs only after a spatial fill, as in telex-remote
  if (c.fill)
    os << "w" << c.fill_options.window_px << "/b" << c.fill_options.bin_mm;
  else
    os << "nofill";
  os << ' ';
  if (!c.bilateral)
    os << "nobil";
  else if (c.bilateral_options.sigma_from_noise_model)
    os << "r" << c.bilateral_options.radius_px << "/3sz";
  else
    os << "r" << c.bilateral_options.radius_px << "/" << c.bilateral_options.sigma_space_px << "/"
       << c.bilateral_options.sigma_depth_mm;
  os << ' '
     << (c.normal_method == NormalMethod::Plain
             ? std::string("plain")
             : "k" + std::to_string(c.normal_options.smooth_radius_px));
  os << ' ' << proto::codec_name(c.codec);
  if (c.codec == proto::Codec::Zip) os << c.zip_level;
  if (c.roi) os << " ROI";
  if (c.station_fill) os << " fill@station";
  return os.str();
}

remote::PipelineConfig remote_config(const Config& c) {
  remote::PipelineConfig p;
  p.fill = c.fill;
  p.hole_fill = c.fill_options;
  p.temporal_fill = c.temporal;
  p.temporal = c.temporal_options;
  p.tile_width = c.width / 8;
  p.tile_height = c.height / 8;
  p.codec = c.codec;
  p.zip_level = c.zip_level;
  p.clock_ms = thread_cpu_ms;
  return p;
}

local::SurfaceOptions surface_options(const Config& c) {
  local::SurfaceOptions so;
  so.bilateral = c.bilateral;
  so.bilateral_options = c.bilateral_options;
  so.normal_options = c.normal_options;
  so.roi = c.roi;
  so.fill_here = c.station_fill;
  so.fill_options = c.fill_options;
  so.clock_ms = thread_cpu_ms;
  return so;
}

}  // namespace telex::tool::bench
