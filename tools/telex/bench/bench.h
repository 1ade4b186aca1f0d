// SPDX-License-Identifier: MIT
// `telex bench` in parts: the grid of configurations (bench_grid.cpp), the chain each frame runs
// through, which is the shipping code (bench_chain.cpp), and the report (bench_report.cpp).
#pragma once

#include <array>
#include <filesystem>
#include <glm/vec3.hpp>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "telex/common/bilateral.h"
#include "telex/common/hole_fill.h"
#include "telex/common/normals.h"
#include "telex/common/synthetic.h"
#include "telex/common/temporal_fill.h"
#include "telex/haptics/haptic_surface.h"
#include "telex/local/link/surface_builder.h"
#include "telex/proto/depth_codec.h"
#include "telex/remote/pipeline.h"

namespace telex::tool::bench {

namespace fs = std::filesystem;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kFrameRateHz = 30.0;

double median(std::vector<double> v);
double mean_finite(const std::vector<double>& v);

// ---- configurations (bench_grid.cpp) ----

enum class NormalMethod { Smoothed, Plain };

struct Config {
  std::string name;
  std::string group;  // the factor this configuration varies from the default
  int width = 640, height = 480;
  bool temporal = true;
  TemporalFillOptions temporal_options{};
  bool fill = true;
  HoleFillOptions fill_options{};
  bool bilateral = true;
  BilateralOptions bilateral_options{};
  NormalMethod normal_method = NormalMethod::Smoothed;
  NormalOptions normal_options{};
  proto::Codec codec = proto::Codec::Zip;
  int zip_level = proto::kDefaultZipLevel;
  bool roi = false;
  bool station_fill = false;  // the station fills what arrived (SurfaceOptions::fill_here)
};

extern const std::vector<std::string> kGroups;
// The grid's row that runs as both daemons do with no flags (make_grid checks it against
// local::SurfaceOptions' defaults). The row named "default" is the grid's baseline instead.
inline constexpr const char* kDaemonsDefault = "kinfu_r6_roi_fill_station";
int group_index(const std::string& g);
// One factor at a time around the baseline row "default" (radius 2 over the whole frame, the remote
// filling: the shipping defaults before issue 16), plus a few combinations, kDaemonsDefault among
// them: a full Cartesian grid would be thousands of chains for little extra insight.
std::vector<Config> make_grid(bool quick);
// The grid's configurations named in `names` (all when empty); throws std::invalid_argument
// naming an unknown one.
std::vector<Config> select_configs(std::vector<Config> grid, const std::vector<std::string>& names);
std::string describe(const Config& c);
// The remote pipeline's configuration for `c`: telex-remote's defaults with c's fill, temporal
// fill, codec and an 8x8 tile grid, timed by the thread's CPU clock.
remote::PipelineConfig remote_config(const Config& c);
// The station's surface options for `c`, timed by the thread's CPU clock.
local::SurfaceOptions surface_options(const Config& c);

// ---- metrics ----

enum Metric {
  kDepthRmse,
  kFillRmse,
  kFillRate,
  kRangeOk,
  kNormalMean,
  kNormalP95,
  kForceErr,
  kBytes,
  kTemporalMs,
  kFillMs,
  kEncodeMs,
  kDecodeMs,
  kFilterMs,
  kNormalsMs,
  kSurfaceMs,
  kTotalMs,
  kPixels,
  kMetricCount
};
// Errors are averaged over frames, scenes and seeds; costs are medians.
// Errors are averaged over frames, scenes and seeds; costs are medians.
inline constexpr std::array<const char*, kMetricCount> kMetricNames = {
    "depth_rmse_mm", "fill_rmse_mm",        "fill_rate",
    "range_ok",      "normal_err_mean_deg", "normal_err_p95_deg",
    "force_err_rel", "bytes_per_frame",     "temporal_ms",
    "fill_ms",       "encode_ms",           "decode_ms",
    "filter_ms",     "normals_ms",          "surface_ms",
    "total_ms",      "pixels_processed"};
inline bool is_cost(int m) { return m >= kBytes; }
using Sample = std::array<double, kMetricCount>;

// ---- frames and the chain (bench_chain.cpp) ----

struct Script {
  std::vector<glm::dvec3> path_camera;  // one position per 1 kHz tick
  local::HandState hand;                // the fingertip where the press starts (for ROI windows)
};

// Approach from 1 cm in front of p0 along the free-side normal, press 5 mm in, stroke +-1.5 cm

struct Frame {
  cv::Mat1w depth_mm;
  cv::Mat1f true_depth_m;  // empty for real frames
  cv::Mat3f true_normals;
  Intrinsics intr;
  double time_ms = 0.0;
  std::uint32_t id = 0;
  Script script;
  std::vector<glm::dvec3> ideal_force;  // force against the surface built from ground truth
  bool has_truth() const { return !true_depth_m.empty(); }
};

Frame synthetic_frame(const synth::Rendered& r, std::uint32_t id);
Frame real_frame(const cv::Mat1w& depth_mm, const Intrinsics& intr, std::uint32_t id,
                 double time_ms);

// One configuration's chain over one sequence: the remote pipeline keeps its histories (temporal
// fill) from frame to frame, as in the daemon.
struct ChainState {
  explicit ChainState(const Config& c) : pipeline(remote_config(c)) {}
  remote::FramePipeline pipeline;
  cv::Mat1w received;
};

// One frame through the shipping chain: remote::FramePipeline (register, fill, temporal fill,
// stabilise, tile, encode; every tile sent, as in a key frame), proto's tile decoder, the
// station's build_surface, then the scripted fingertip through HapticModel. `pool` recycles the
// surface snapshots as the station's surface thread does.
Sample run_chain(const Config& c, const Frame& f, ChainState& st, local::SurfacePool& pool);

struct Row {
  const Config* config = nullptr;
  std::string dataset;  // a scene name, "synthetic" (all scenes pooled) or "real_desk"
  std::size_t frames = 0;
  Sample value{};
};
Row aggregate(const Config& c, const std::string& dataset, const std::vector<Sample>& samples);
const Row* find_row(const std::vector<Row>& rows, const std::string& config,
                    const std::string& dataset);

// Static against moving scenes: the remote pipeline with its stabiliser, changed tiles only.
struct StreamVariant {
  double k_sigma = 0.0;    // 0 = off (telex-remote's default)
  int confirm_frames = 2;  // telex-remote's default
};
std::string stream_name(const StreamVariant& s);
struct StreamRow {
  std::string scene;
  StreamVariant stab;
  double bytes_per_s = 0.0;
  double tiles_changed = 0.0;  // fraction of tiles sent per frame after the first
  double rmse_mm = 0.0;        // of the frames the receiver ends up with, against truth
  double stabilise_ms = 0.0;   // median per frame
  int frames = 0;
};
std::vector<StreamRow> run_stream(int frames, const std::vector<StreamVariant>& variants);

struct SkipRow {
  std::string what;
  double holes_frac = 0.0;
  double tiles_without_holes = 0.0;
  double count_holes_ms = 0.0;  // the check that decides whether a pass is needed
  double fill_ms = 0.0;
};
SkipRow measure_fill_skip(const std::string& what, const cv::Mat1w& depth, int repeats);

struct RoiTiming {
  double full_ms = kNaN, roi_ms = kNaN, none_ms = kNaN;
  double roi_snapshot_ms = kNaN;  // of roi_ms: taking the snapshot from the pool, clearing it
  int window_px = 0;
  std::size_t recycled = 0;
  // Pixels filtered and given normals per build (SurfaceBuildStats::pixels_processed).
  std::size_t full_pixels = 0, roi_pixels = 0;
  // The station's settings both rows ran with (telex-local's defaults).
  int bilateral_radius_px = 0;
  bool fill_here = false;
};
// telex-local's surface options with no flags, or with --full-frame; timed by the thread's CPU
// clock.
local::SurfaceOptions station_surface_options(bool full_frame);
// The station's per-frame surface work on one desk frame, interleaved (see bench_chain.cpp).
RoiTiming measure_roi_timing(bool quick);

// ---- the report (bench_report.cpp) ----

struct RoiRow {
  std::string full, roi;
  double full_ms, roi_ms, ratio, full_pixels, roi_pixels, full_force, roi_force;
  double full_kernel_ms, roi_kernel_ms;  // bilateral + normals only
  double kernel_ratio() const { return full_kernel_ms / roi_kernel_ms; }
};
std::vector<RoiRow> roi_rows(const std::vector<Row>& rows);

struct Results {
  std::vector<Row> rows;
  std::vector<RoiRow> roi;
  RoiTiming roi_timing;
  std::vector<StreamRow> stream;
  std::vector<SkipRow> skip;
  bool quick = false;
  std::string real_note;
};
void write_csv(const fs::path& file, const std::vector<Row>& rows);
void write_markdown(const fs::path& file, const Results& r);
void write_plots(const fs::path& dir, const std::vector<Row>& rows);
nlohmann::json results_json(const Results& r, const fs::path& out_dir);
void print_summary(const Results& r, const fs::path& out_dir);

}  // namespace telex::tool::bench
