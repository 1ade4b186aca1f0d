// SPDX-License-Identifier: MIT
// The eyes' codec (common/video): H.264 of both eyes side by side against MJPEG pairs at
// 2x1280x720, 30 Hz, on the real desk colour frames (upscaled, panned as a moving head sees them)
// and on a moving synthetic scene. Per case: bits per second, encode and decode time per pair
// (medians), PSNR and SSIM against the source. Goals: <= 4 Mbit/s with SSIM >= 0.95, and
// encode + decode <= 12 ms per pair on this 2-core machine.
//   video_bench [--desk=DIR] [--noise=SIGMA] [google benchmark flags]
// DIR defaults to $TELEX_SHARED_DIR/data/real/desk, else ../shared/data/real/desk.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "telex/video/eye_decoder.h"
#include "telex/video/eye_encoder.h"
#include "telex/video/quality.h"

namespace telex::video {
namespace {

constexpr int kPairs = 150;  // 5 s at 30 Hz
constexpr double kRateHz = 30.0;
constexpr int kSsimEvery = 5;  // SSIM costs more than the codec: every fifth pair
const cv::Size kEye(1280, 720);

std::string g_desk_dir;
double g_noise = 2.0;
std::vector<cv::Mat3b> g_desk;  // the desk colour frames upscaled to 1600x1200

struct Result {
  double mbit_s, enc_ms, dec_ms, total_ms, total_p90_ms, cpu_ms, psnr, ssim_mean, ssim_min, max_kb;
};
std::map<std::string, Result> g_results;

bool load_desk() {
  for (int i = 0;; ++i) {
    const auto path =
        std::filesystem::path(g_desk_dir) / ("desk_" + std::to_string(i) + "_rgb.png");
    if (!std::filesystem::exists(path)) break;
    cv::Mat3b img = cv::imread(path.string(), cv::IMREAD_COLOR);
    if (img.empty()) break;
    cv::resize(img, img, cv::Size(1600, 1200), 0, 0, cv::INTER_CUBIC);
    g_desk.push_back(img);
  }
  return !g_desk.empty();
}

void add_noise(int index, cv::Mat3b& eye, int which) {
  if (g_noise <= 0.0) return;
  cv::RNG rng(0xd35c + 2 * static_cast<std::uint64_t>(index) + which);
  cv::Mat3s grain(eye.size()), sum;
  rng.fill(grain, cv::RNG::NORMAL, 0.0, g_noise);
  eye.convertTo(sum, CV_16SC3);
  sum += grain;
  sum.convertTo(eye, CV_8UC3);
}

// The head pans over the desk (a 4 s sweep left-right, 6 s up-down); each real frame shows for
// 1 s; the eyes look 40 px apart. Fresh sensor noise in every frame, as a camera's.
void desk_pair(int index, cv::Mat3b& left, cv::Mat3b& right) {
  const cv::Mat3b& img = g_desk[static_cast<std::size_t>(index / 30) % g_desk.size()];
  const double t = index / kRateHz;
  const int x = 160 + static_cast<int>(std::lround(110.0 * std::sin(2 * M_PI * t / 4.0)));
  const int y = 240 + static_cast<int>(std::lround(200.0 * std::sin(2 * M_PI * t / 6.0)));
  img(cv::Rect(x - 20, y, kEye.width, kEye.height)).copyTo(left);
  img(cv::Rect(x + 20, y, kEye.width, kEye.height)).copyTo(right);
  add_noise(index, left, 0);
  add_noise(index, right, 1);
}

double median(std::vector<double> v, double q = 0.5) {
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(q * static_cast<double>(v.size() - 1))];
}

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// CPU time of the whole process (the encoder's and decoder's worker threads included): what the
// pair costs whatever else the shared machine runs.
double process_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

void BM_EyeCodec(benchmark::State& state, const std::string& name, bool desk,
                 EncoderConfig config) {
  if (desk && g_desk.empty()) {
    state.SkipWithError(
        ("desk frames not found in " + g_desk_dir + " (give --desk=DIR): desk case skipped")
            .c_str());
    return;
  }
  config.eye_width_px = kEye.width;
  config.eye_height_px = kEye.height;
  config.frame_rate_hz = kRateHz;
  auto enc = EyeEncoder::create(config);
  EyeDecoder dec;
  DecodedPair out;
  std::vector<std::uint8_t> bytes;
  std::vector<double> enc_ms, dec_ms, total_ms, cpu_ms, ssims;
  double psnr_sum = 0.0, bits = 0.0, max_kb = 0.0;
  cv::Mat3b left, right;
  int index = 0;
  for (auto _ : state) {
    state.PauseTiming();
    if (desk)
      desk_pair(index, left, right);
    else
      render_moving_eyes(index, kEye, g_noise, left, right);
    state.ResumeTiming();
    const double cpu0 = process_cpu_ms();
    const auto t0 = std::chrono::steady_clock::now();
    const EncodeStatus es = enc->encode(left, right, static_cast<std::uint32_t>(index), 0, bytes);
    const double e_ms = ms_since(t0);
    const auto t1 = std::chrono::steady_clock::now();
    const DecodeStatus ds = dec.decode(bytes, out);
    const double d_ms = ms_since(t1);
    const double c_ms = process_cpu_ms() - cpu0;
    state.SetIterationTime((e_ms + d_ms) / 1000.0);
    state.PauseTiming();
    if (es != EncodeStatus::Ok || ds != DecodeStatus::Ok) {
      state.SkipWithError(("pair " + std::to_string(index) + ": encode " +
                           std::string(encode_status_name(es)) + ", decode " +
                           std::string(decode_status_name(ds)))
                              .c_str());
      break;
    }
    enc_ms.push_back(e_ms);
    dec_ms.push_back(d_ms);
    total_ms.push_back(e_ms + d_ms);
    cpu_ms.push_back(c_ms);
    bits += 8.0 * static_cast<double>(bytes.size());
    max_kb = std::max(max_kb, static_cast<double>(bytes.size()) / 1000.0);
    psnr_sum += 0.5 * (psnr_db(left, out.left_bgr) + psnr_db(right, out.right_bgr));
    if (index % kSsimEvery == 0)
      ssims.push_back(0.5 * (ssim(left, out.left_bgr) + ssim(right, out.right_bgr)));
    ++index;
    state.ResumeTiming();
  }
  if (enc_ms.empty()) return;
  const auto n = static_cast<double>(enc_ms.size());
  Result r{bits / (n / kRateHz) / 1e6,
           median(enc_ms),
           median(dec_ms),
           median(total_ms),
           median(total_ms, 0.9),
           median(cpu_ms),
           psnr_sum / n,
           0.0,
           *std::min_element(ssims.begin(), ssims.end()),
           max_kb};
  for (double s : ssims) r.ssim_mean += s / static_cast<double>(ssims.size());
  state.counters["Mbit_s"] = r.mbit_s;
  state.counters["enc_ms_p50"] = r.enc_ms;
  state.counters["dec_ms_p50"] = r.dec_ms;
  state.counters["total_ms_p50"] = r.total_ms;
  state.counters["cpu_ms_p50"] = r.cpu_ms;
  state.counters["psnr_db"] = r.psnr;
  state.counters["ssim"] = r.ssim_mean;
  state.counters["ssim_min"] = r.ssim_min;
  state.counters["max_kB"] = r.max_kb;
  g_results[name] = r;
}

void register_cases() {
  struct Case {
    std::string name;
    EncoderConfig config;
  };
  std::vector<Case> cases;
  for (const char* preset : {"ultrafast", "superfast", "veryfast"})
    for (const std::int64_t mbit : {3, 4}) {
      if (std::string(preset) == "veryfast" && mbit == 4) continue;  // slowest: one rate shows it
      EncoderConfig c;
      c.encoder = "libx264";
      c.preset = preset;
      c.bitrate_bps = mbit * 1'000'000;
      cases.push_back({std::string(preset) + "_" + std::to_string(mbit) + "M", c});
    }
  EncoderConfig mjpeg;
  mjpeg.encoder = "mjpeg";
  cases.push_back({"q80", mjpeg});
  for (const bool desk : {true, false})
    for (const Case& c : cases) {
      const std::string name = std::string("BM_EyeCodec/") + (desk ? "desk/" : "synthetic/") +
                               (c.config.encoder == "mjpeg" ? "mjpeg_" : "h264_") + c.name;
      benchmark::RegisterBenchmark(name.c_str(), BM_EyeCodec, name, desk, c.config)
          ->Iterations(kPairs)
          ->UseManualTime()
          ->Unit(benchmark::kMillisecond);
    }
}

void print_table() {
  if (g_results.empty()) return;
  std::printf(
      "\n| case | Mbit/s | encode ms p50 | decode ms p50 | enc+dec ms p50 | enc+dec ms p90 | "
      "enc+dec CPU ms p50 | PSNR dB | SSIM mean | SSIM min | largest pair kB | goals |\n"
      "|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const auto& [name, r] : g_results) {
    const bool rate_ok = r.mbit_s <= 4.0 && r.ssim_mean >= 0.95;
    const bool time_ok = r.total_ms <= 12.0;
    const bool cpu_ok = r.cpu_ms <= 12.0;
    std::printf(
        "| %s | %.2f | %.2f | %.2f | %.2f | %.2f | %.2f | %.1f | %.3f | %.3f | %.0f | %s, %s%s |\n",
        name.c_str() + std::strlen("BM_EyeCodec/"), r.mbit_s, r.enc_ms, r.dec_ms, r.total_ms,
        r.total_p90_ms, r.cpu_ms, r.psnr, r.ssim_mean, r.ssim_min, r.max_kb,
        rate_ok ? "rate met" : "rate NOT met", time_ok ? "time met" : "time NOT met",
        time_ok || !cpu_ok ? "" : " (CPU met)");
  }
}

}  // namespace
}  // namespace telex::video

int main(int argc, char** argv) {
  using namespace telex::video;
  std::vector<char*> rest;
  for (int i = 0; i < argc; ++i) {
    if (std::strncmp(argv[i], "--desk=", 7) == 0) {
      g_desk_dir = argv[i] + 7;
    } else if (std::strncmp(argv[i], "--noise=", 8) == 0) {
      char* end = nullptr;
      g_noise = std::strtod(argv[i] + 8, &end);
      if (end == argv[i] + 8 || *end != '\0' || g_noise < 0.0 || g_noise > 50.0) {
        std::fprintf(stderr, "video_bench: --noise=%s is not a sigma in 0..50\n", argv[i] + 8);
        return 2;
      }
    } else {
      rest.push_back(argv[i]);
    }
  }
  if (g_desk_dir.empty()) {
    const char* shared = std::getenv("TELEX_SHARED_DIR");
    g_desk_dir = shared ? std::string(shared) + "/data/real/desk" : "../shared/data/real/desk";
  }
  if (!load_desk())
    std::fprintf(stderr, "video_bench: no desk_N_rgb.png in %s: the desk cases are skipped\n",
                 g_desk_dir.c_str());
  register_cases();
  int n = static_cast<int>(rest.size());
  benchmark::Initialize(&n, rest.data());
  if (benchmark::ReportUnrecognizedArguments(n, rest.data())) return 2;
  benchmark::RunSpecifiedBenchmarks();
  print_table();
  benchmark::Shutdown();
  return 0;
}
