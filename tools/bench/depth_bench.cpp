// SPDX-License-Identifier: MIT
// Depth kernels against their OpenCV peers on one 640x480 frame, one thread, with ratios at the
// end.
//
//   depth_bench [--frame=DEPTH_MM.png] [--benchmark_min_time=0.2 ...]
// Frame: --frame, else $TELEX_SHARED_DIR/data/real/desk/desk_0_depth_mm.png, else the synthetic
// desk scene.
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <map>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/rgbd.hpp>
#include <set>
#include <string>
#include <vector>

#include "telex/common/bilateral.h"
#include "telex/common/depth_image.h"
#include "telex/common/hole_fill.h"
#include "telex/common/normals.h"
#include "telex/common/registration.h"
#include "telex/common/synthetic.h"
#include "telex/haptics/haptic_surface.h"

namespace {

struct Frames {
  std::string source;
  telex::Intrinsics intrinsics;
  cv::Mat1w raw_mm;       // as loaded, with holes
  cv::Mat1w filled_mm;    // after the default hole fill: what the bilateral and normals see
  cv::Mat1f filled_mm_f;  // the same in float mm for cv::bilateralFilter
  cv::Mat1f filled_m;     // metres for the normal kernels
  cv::Mat points;         // back-projected points for RgbdNormals
};

Frames& frames() {
  static Frames f;
  return f;
}

cv::Mat camera_matrix(const telex::Intrinsics& k) {
  return (cv::Mat_<float>(3, 3) << k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1);
}

void prepare(Frames& f) {
  f.filled_mm = telex::fill_holes_mode(f.raw_mm).depth_mm;
  f.filled_mm.convertTo(f.filled_mm_f, CV_32F);
  f.filled_m = telex::depth_m_from_mm(f.filled_mm);
  cv::rgbd::depthTo3d(f.filled_m, camera_matrix(f.intrinsics), f.points);
}

void load_frames(const std::string& path) {
  Frames& f = frames();
  f.raw_mm = cv::imread(path, cv::IMREAD_ANYDEPTH);
  if (f.raw_mm.empty() || f.raw_mm.type() != CV_16UC1) {
    std::cerr << "depth_bench: cannot read a 16-bit depth PNG from " << path << "\n";
    std::exit(1);
  }
  f.source = path;
  // The shared desk frames' intrinsics (README beside them).
  f.intrinsics = telex::Intrinsics{525.0, 525.0, 320.0, 240.0, f.raw_mm.cols, f.raw_mm.rows};
  prepare(f);
}

// Without the real frames: the synthetic desk with the Kinect-v1 sensor model (fixed seed).
void synthetic_frames() {
  Frames& f = frames();
  const auto r = telex::synth::render(telex::synth::Scene::named("desk"),
                                      telex::kinect_v1_intrinsics(), telex::synth::SensorModel{});
  f.raw_mm = r.depth.depth_mm;
  f.intrinsics = r.depth.intrinsics;
  f.source = "synthetic desk (no real frame given)";
  prepare(f);
}

void BM_FillMode_1pass_5x5(benchmark::State& state) {
  telex::HoleFillOptions o;
  o.max_passes = 1;
  cv::Mat1w out;
  for (auto _ : state) {
    auto r = telex::fill_holes_mode_into(frames().raw_mm, out, o);
    benchmark::DoNotOptimize(r.holes_out);
  }
}
void BM_FillMode_default_16pass_5x5(benchmark::State& state) {
  cv::Mat1w out;
  for (auto _ : state) {
    auto r = telex::fill_holes_mode_into(frames().raw_mm, out, {});
    benchmark::DoNotOptimize(r.holes_out);
  }
}
void BM_CvMedianBlur_5x5_16U(benchmark::State& state) {
  cv::Mat out;
  for (auto _ : state) {
    cv::medianBlur(frames().raw_mm, out, 5);
    benchmark::DoNotOptimize(out.data);
  }
}

telex::BilateralOptions bilateral_options(int d) {
  telex::BilateralOptions o;
  o.radius_px = d / 2;
  o.sigma_space_px = 4.5;
  o.sigma_depth_mm = 30.0;
  return o;
}
void BM_Bilateral(benchmark::State& state) {
  const auto o = bilateral_options(static_cast<int>(state.range(0)));
  cv::Mat1f out;
  for (auto _ : state) {
    telex::bilateral_filter_depth(frames().filled_mm, out, o);
    benchmark::DoNotOptimize(out.data);
  }
}
void BM_BilateralNoiseSigma(benchmark::State& state) {
  auto o = bilateral_options(static_cast<int>(state.range(0)));
  o.sigma_from_noise_model = true;
  cv::Mat1f out;
  for (auto _ : state) {
    telex::bilateral_filter_depth(frames().filled_mm, out, o);
    benchmark::DoNotOptimize(out.data);
  }
}
void BM_CvBilateral32F(benchmark::State& state) {
  const int d = static_cast<int>(state.range(0));
  cv::Mat out;
  for (auto _ : state) {
    cv::bilateralFilter(frames().filled_mm_f, out, d, 30.0, 4.5);
    benchmark::DoNotOptimize(out.data);
  }
}

void BM_Normals(benchmark::State& state) {
  cv::Mat3f out;
  for (auto _ : state) {
    telex::compute_normals(frames().filled_m, frames().intrinsics, out);
    benchmark::DoNotOptimize(out.data);
  }
}
void BM_CvRgbdNormalsFALS_w5(benchmark::State& state) {
  const Frames& f = frames();
  cv::rgbd::RgbdNormals fals(f.filled_m.rows, f.filled_m.cols, CV_32F, camera_matrix(f.intrinsics),
                             5, cv::rgbd::RgbdNormals::RGBD_NORMALS_METHOD_FALS);
  cv::Mat out;
  fals(f.points, out);  // the first call builds FALS's per-pixel tables; not part of a frame's cost
  for (auto _ : state) {
    fals(f.points, out);
    benchmark::DoNotOptimize(out.data);
  }
}
void BM_CvDepthTo3d(benchmark::State& state) {
  const Frames& f = frames();
  cv::Mat pts;
  for (auto _ : state) {
    cv::rgbd::depthTo3d(f.filled_m, camera_matrix(f.intrinsics), pts);
    benchmark::DoNotOptimize(pts.data);
  }
}

// The stereo view's left eye, every frame it draws: the depth (registered to the right eye) seen
// from 6.5 cm to its left, and the strips behind edges filled (StereoView::prepare_depth). The
// argument: 0 by the full reprojection (the view before), 1 along the rows (the view now).
void BM_LeftEyeDepth(benchmark::State& state) {
  const Frames& f = frames();
  const telex::RigidTransform X_LeftRight{glm::dmat3(1.0), glm::dvec3(0.065, 0.0, 0.0)};
  cv::Mat1w left;
  for (auto _ : state) {
    if (state.range(0) == 0)
      left =
          telex::reproject_depth({f.filled_mm, f.intrinsics}, f.intrinsics, X_LeftRight).depth_mm;
    else
      telex::shift_depth_along_rows(f.filled_mm, f.intrinsics.fx, 0.065, left);
    telex::fill_disocclusions(left, f.intrinsics.fx, 0.065);
    benchmark::DoNotOptimize(left.data);
  }
}

BENCHMARK(BM_FillMode_1pass_5x5)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_FillMode_default_16pass_5x5)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_CvMedianBlur_5x5_16U)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Bilateral)->Arg(5)->Arg(13)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_BilateralNoiseSigma)->Arg(5)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_CvBilateral32F)->Arg(5)->Arg(13)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_Normals)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_CvRgbdNormalsFALS_w5)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_CvDepthTo3d)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_LeftEyeDepth)->ArgName("rows")->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// Console output plus the per-iteration times, for the ratio summary. The verdict uses CPU time:
// on a shared machine real time also counts waits for a core, which hit ours and the peer
// unequally; the real-time ratio is printed beside it.
class RatioReporter : public benchmark::ConsoleReporter {
 public:
  RatioReporter() : ConsoleReporter(OO_Tabular) {}
  void ReportRuns(const std::vector<Run>& runs) override {
    ConsoleReporter::ReportRuns(runs);
    // With --benchmark_repetitions the medians are used, else the single run.
    for (const Run& r : runs) {
      if (r.error_occurred) continue;
      const bool median = r.run_type == Run::RT_Aggregate && r.aggregate_name == "median";
      if (r.run_type != Run::RT_Iteration && !median) continue;
      if (r.run_type == Run::RT_Iteration && medians_.count(r.run_name.str())) continue;
      if (median) medians_.insert(r.run_name.str());
      ms_[r.run_name.str()] = {r.GetAdjustedCPUTime(), r.GetAdjustedRealTime()};
    }
  }
  void print_ratios() const {
    std::cout << "\nratios ours / peer, CPU time (real time), goal in brackets, on "
              << frames().source << "\n";
    ratio("fill 1 pass 5x5 / medianBlur 5x5", "BM_FillMode_1pass_5x5", "BM_CvMedianBlur_5x5_16U",
          1.0);
    ratio("fill 16 passes 5x5 / medianBlur 5x5", "BM_FillMode_default_16pass_5x5",
          "BM_CvMedianBlur_5x5_16U", 1.0);
    ratio("bilateral d=5 / cv::bilateralFilter d=5", "BM_Bilateral/5", "BM_CvBilateral32F/5", 0.5);
    ratio("bilateral d=13 / cv::bilateralFilter d=13", "BM_Bilateral/13", "BM_CvBilateral32F/13",
          0.5);
    ratio("normals / RgbdNormals FALS w5", "BM_Normals", "BM_CvRgbdNormalsFALS_w5", 0.25);
  }

 private:
  void ratio(const char* label, const std::string& ours, const std::string& peer,
             double goal) const {
    const auto a = ms_.find(ours), b = ms_.find(peer);
    if (a == ms_.end() || b == ms_.end()) return;  // filtered out by --benchmark_filter
    const double q = a->second.first / b->second.first;
    const double q_real = a->second.second / b->second.second;
    std::cout << "  " << label << ": " << q << " (" << q_real << ") [<= " << goal << "] "
              << (q <= goal ? "met" : "NOT met") << "\n";
  }
  std::map<std::string, std::pair<double, double>> ms_;  // name -> {CPU ms, real ms}
  std::set<std::string> medians_;
};

}  // namespace

int main(int argc, char** argv) {
  std::string frame;
  std::vector<char*> rest;
  for (int i = 0; i < argc; ++i) {
    if (std::strncmp(argv[i], "--frame=", 8) == 0) {
      frame = argv[i] + 8;
    } else {
      rest.push_back(argv[i]);
    }
  }
  if (frame.empty()) {
    if (const char* shared = std::getenv("TELEX_SHARED_DIR")) {
      const auto p = std::filesystem::path(shared) / "data/real/desk/desk_0_depth_mm.png";
      if (std::filesystem::exists(p)) frame = p.string();
    }
  }
  cv::setNumThreads(1);
  if (frame.empty()) {
    synthetic_frames();
  } else {
    load_frames(frame);
  }
  int n = static_cast<int>(rest.size());
  benchmark::Initialize(&n, rest.data());
  if (benchmark::ReportUnrecognizedArguments(n, rest.data())) return 2;
  RatioReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  reporter.print_ratios();
  benchmark::Shutdown();
  return 0;
}
