// SPDX-License-Identifier: MIT
// `telex bench`: error against run time of the depth-to-force chain over a grid of configurations.
// The chain is the daemons' own code (bench_chain.cpp); this file runs it and writes the report.
#include <algorithm>
#include <cstdlib>
#include <iostream>
#include <map>
#include <memory>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "bench.h"
#include "command.h"
#include "telex/common/depth_io.h"
#include "telex/local/record/recorder.h"

namespace telex::tool {
namespace {

using namespace bench;

struct Options {
  bool quick = false;
  bool json = false;
  std::string out = "bench_out";
  std::string real;
  std::vector<std::string> sessions;
  std::vector<std::string> configs;
};

std::vector<cv::Mat1w> load_real(const std::string& dir, std::string& note) {
  std::vector<cv::Mat1w> frames;
  if (dir.empty()) {
    note = "skipped: no --real directory given";
    return frames;
  }
  for (int i = 0; i < 3; ++i) {
    const fs::path file = fs::path(dir) / ("desk_" + std::to_string(i) + "_depth_mm.png");
    if (!fs::exists(file)) {
      note = "skipped: " + file.string() + " not found";
      return {};
    }
    frames.push_back(load_depth(file, DepthUnits::Millimetres).depth_mm);
  }
  note = std::to_string(frames.size()) + " frames from " + dir +
         ", scaled with nearest neighbour to each resolution";
  return frames;
}

// Every configuration of the full grid (--quick runs a subset of them).
std::vector<std::string> config_names() {
  std::vector<std::string> names;
  for (const auto& c : make_grid(false)) names.push_back(c.name);
  return names;
}

// What the grid runs on: synthetic scenes, the real desk frames and recorded sessions.
struct Datasets {
  std::vector<std::string> scenes;
  int seeds = 0;
  int frames_per_seq = 0;
  std::vector<cv::Mat1w> real;
  std::string real_note;
  // Recorded sessions (telex-local --record): their depth as received, frames spread evenly.
  std::vector<std::pair<std::string, std::vector<local::RecordedSurface>>> sessions;
};

Datasets load_datasets(const Options& o) {
  Datasets d;
  d.scenes = o.quick ? std::vector<std::string>{"tilted", "box"}
                     : std::vector<std::string>{"plane", "tilted", "sphere", "box", "desk"};
  d.seeds = o.quick ? 1 : 3;
  d.frames_per_seq = o.quick ? 2 : 4;
  d.real = load_real(o.real, d.real_note);
  if (!o.json) std::cerr << "telex bench: real desk frames " << d.real_note << "\n";
  for (const auto& path : o.sessions) {
    d.sessions.emplace_back("session:" + fs::path(path).stem().string(),
                            local::read_session_depth(path, o.quick ? 4 : 12));
    if (!o.json)
      std::cerr << "telex bench: " << d.sessions.back().first << ": "
                << d.sessions.back().second.size() << " frames from " << path << "\n";
  }
  return d;
}

// The grid's resolutions, in the order they first appear.
std::vector<std::pair<int, int>> resolutions_of(const std::vector<Config>& grid) {
  std::vector<std::pair<int, int>> resolutions;
  for (const auto& c : grid)
    if (std::find(resolutions.begin(), resolutions.end(), std::pair{c.width, c.height}) ==
        resolutions.end())
      resolutions.emplace_back(c.width, c.height);
  return resolutions;
}

using Sequences = std::vector<std::pair<std::string, std::vector<Frame>>>;

// Each synthetic scene rendered at w x h, one sequence per sensor seed.
void add_synthetic(const Datasets& d, int w, int h, Sequences& sequences) {
  const Intrinsics k = kinect_v1_intrinsics(w, h);
  for (const auto& name : d.scenes) {
    const synth::Scene scene = synth::Scene::named(name);
    for (int seed = 1; seed <= d.seeds; ++seed) {
      synth::SensorModel sensor;
      sensor.seed = static_cast<std::uint64_t>(seed);
      synth::Renderer renderer(k, sensor);
      std::vector<Frame> seq;
      for (int i = 0; i < d.frames_per_seq; ++i)
        seq.push_back(synthetic_frame(
            renderer.render(scene.at_time(i / kFrameRateHz), static_cast<std::uint64_t>(i)),
            static_cast<std::uint32_t>(i)));
      sequences.emplace_back(name, std::move(seq));
    }
  }
}

// The real desk frames and the recorded sessions, scaled with nearest neighbour to w x h.
void add_real(const Datasets& d, int w, int h, Sequences& sequences) {
  if (!d.real.empty()) {
    const Intrinsics real_k = Intrinsics{525.0, 525.0, 320.0, 240.0, 640, 480}.scaled(w, h);
    std::vector<Frame> seq;
    for (std::size_t i = 0; i < d.real.size(); ++i) {
      cv::Mat1w m;
      cv::resize(d.real[i], m, cv::Size(w, h), 0, 0, cv::INTER_NEAREST);
      // The README gives about 0.25 s between the recorded frames.
      seq.push_back(real_frame(m, real_k, static_cast<std::uint32_t>(i), 250.0 * i));
    }
    sequences.emplace_back("real_desk", std::move(seq));
  }
  for (const auto& [name, frames] : d.sessions) {
    std::vector<Frame> seq;
    for (std::size_t i = 0; i < frames.size(); ++i) {
      cv::Mat1w m;
      cv::resize(frames[i].depth_mm, m, cv::Size(w, h), 0, 0, cv::INTER_NEAREST);
      seq.push_back(real_frame(m, frames[i].intrinsics.scaled(w, h), static_cast<std::uint32_t>(i),
                               static_cast<double>(frames[i].built_ns - frames[0].built_ns) / 1e6));
    }
    sequences.emplace_back(name, std::move(seq));
  }
}

// samples[config index][dataset]
using Samples = std::vector<std::map<std::string, std::vector<Sample>>>;

// Every configuration over every sequence at its resolution.
Samples run_grid(const std::vector<Config>& grid, const Datasets& d, bool quiet) {
  Samples samples(grid.size());
  for (const auto& [w, h] : resolutions_of(grid)) {
    Sequences sequences;
    add_synthetic(d, w, h, sequences);
    add_real(d, w, h, sequences);
    for (std::size_t ci = 0; ci < grid.size(); ++ci) {
      const Config& c = grid[ci];
      if (c.width != w || c.height != h) continue;
      if (!quiet) std::cerr << "  " << c.name << " (" << describe(c) << ")\n";
      local::SurfacePool pool;
      for (const auto& [name, seq] : sequences) {
        ChainState state(c);
        for (const auto& f : seq) samples[ci][name].push_back(run_chain(c, f, state, pool));
      }
    }
  }
  return samples;
}

// Per configuration: the synthetic scenes pooled, each scene, the real desk, each session.
std::vector<Row> aggregate_rows(const std::vector<Config>& grid, const Datasets& d,
                                Samples& samples) {
  std::vector<Row> rows;
  for (std::size_t ci = 0; ci < grid.size(); ++ci) {
    std::vector<Sample> pooled;
    for (const auto& name : d.scenes)
      pooled.insert(pooled.end(), samples[ci][name].begin(), samples[ci][name].end());
    rows.push_back(aggregate(grid[ci], "synthetic", pooled));
    for (const auto& name : d.scenes) rows.push_back(aggregate(grid[ci], name, samples[ci][name]));
    if (samples[ci].count("real_desk"))
      rows.push_back(aggregate(grid[ci], "real_desk", samples[ci]["real_desk"]));
    for (const auto& [name, frames] : d.sessions)
      if (samples[ci].count(name)) rows.push_back(aggregate(grid[ci], name, samples[ci][name]));
  }
  return rows;
}

// Synthetic rows have ground truth for every metric: a non-finite one is a bug in the chain.
void demand_finite(const std::vector<Row>& rows) {
  for (const auto& r : rows)
    if (r.dataset != "real_desk" && r.dataset.rfind("session:", 0) != 0)
      for (int m : {kDepthRmse, kNormalMean, kForceErr, kTotalMs, kBytes})
        if (!std::isfinite(r.value[m]))
          throw std::logic_error("config " + r.config->name + " on " + r.dataset + ": " +
                                 kMetricNames[m] + " is not finite");
}

// The hole count that decides whether a fill pass is needed, against the fill itself: on a
// hole-free plane, the sensor model's plane and desk, and the first real desk frame.
std::vector<SkipRow> fill_skip_rows(bool quick, const std::vector<cv::Mat1w>& real) {
  std::vector<SkipRow> skip;
  const int reps = quick ? 5 : 21;
  const Intrinsics k = kinect_v1_intrinsics();
  skip.push_back(measure_fill_skip(
      "plane, ideal sensor (no holes)",
      synth::render(synth::Scene::named("plane"), k, synth::SensorModel::ideal()).depth.depth_mm,
      reps));
  skip.push_back(measure_fill_skip(
      "plane, sensor model",
      synth::render(synth::Scene::named("plane"), k, synth::SensorModel{}).depth.depth_mm, reps));
  skip.push_back(measure_fill_skip(
      "desk, sensor model",
      synth::render(synth::Scene::named("desk"), k, synth::SensorModel{}).depth.depth_mm, reps));
  if (!real.empty()) skip.push_back(measure_fill_skip("real desk_0", real[0], reps));
  return skip;
}

void write_results(const fs::path& out_dir, const Results& res, bool json) {
  write_csv(out_dir / "bench.csv", res.rows);
  write_markdown(out_dir / "bench.md", res);
  write_plots(out_dir, res.rows);
  if (json)
    std::cout << results_json(res, out_dir).dump(2) << "\n";
  else
    print_summary(res, out_dir);
}

int run(const Options& o) {
  cv::setNumThreads(1);
  const fs::path out_dir(o.out);
  fs::create_directories(out_dir);
  std::vector<Config> grid;
  try {
    grid = select_configs(make_grid(o.quick), o.configs);
  } catch (const std::invalid_argument& e) {
    std::cerr << e.what() << "\n";
    return 2;  // a bad flag
  }
  const Datasets d = load_datasets(o);
  Samples samples = run_grid(grid, d, o.json);

  Results res;
  res.rows = aggregate_rows(grid, d, samples);
  demand_finite(res.rows);
  res.roi = roi_rows(res.rows);
  res.roi_timing = measure_roi_timing(o.quick);
  res.stream = run_stream(o.quick ? 6 : 30, {{0.0, 2}, {3.0, 1}, {5.0, 1}, {3.0, 2}, {5.0, 2}});
  res.skip = fill_skip_rows(o.quick, d.real);
  res.quick = o.quick;
  res.real_note = d.real_note;
  write_results(out_dir, res, o.json);
  return 0;
}

const RegisterCommand kRegister{
    "bench",
    "error against run time of the depth chain over a grid of configurations (CSV, Markdown, "
    "PNG plots)",
    [](cli::CommandLine& app) {
      auto o = std::make_shared<Options>();
      if (const char* env = std::getenv("TELEX_REAL_DESK_DIR")) o->real = env;
      app.add_flag("--quick", o->quick, "small grid for CI smoke runs (under two minutes)");
      app.add_option("--out", o->out, "output directory for bench.csv, bench.md and the plots")
          ->capture_default_str();
      app.add_flag("--json", o->json, "print the results as one JSON object on stdout");
      app.add_option("--real", o->real,
                     "directory with desk_{0,1,2}_depth_mm.png (default: $TELEX_REAL_DESK_DIR); "
                     "skipped with a note when absent");
      app.add_option("--config", o->configs,
                     "only these configurations of the grid (names as in bench.csv); repeatable")
          ->delimiter(',')
          ->check(cli::IsMember(config_names()));
      app.add_option("--session", o->sessions,
                     "a recorded session FILE.bag (telex-local --record) whose depth joins the "
                     "real-frame rows; repeatable")
          ->check(cli::ExistingFile());
      return [o]() { return run(*o); };
    }};

}  // namespace
}  // namespace telex::tool
