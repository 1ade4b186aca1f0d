// SPDX-License-Identifier: MIT
// Smoke test of `telex bench --quick`: the CSV holds finite numbers, the plots exist, and the
// region-of-interest chain gives the same forces as the full frame.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "process.h"
#include "telex/local/record/recorder.h"
#include "test_support.h"

namespace {

namespace fs = std::filesystem;

struct Csv {
  std::vector<std::string> header;
  std::vector<std::map<std::string, std::string>> rows;
};

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> out;
  std::stringstream ss(line);
  std::string cell;
  while (std::getline(ss, cell, ',')) out.push_back(cell);
  if (!line.empty() && line.back() == ',') out.push_back("");
  return out;
}

Csv read_csv(const fs::path& file) {
  Csv csv;
  std::ifstream is(file);
  std::string line;
  if (!std::getline(is, line)) return csv;
  csv.header = split(line);
  while (std::getline(is, line)) {
    const auto cells = split(line);
    std::map<std::string, std::string> row;
    for (std::size_t i = 0; i < csv.header.size() && i < cells.size(); ++i)
      row[csv.header[i]] = cells[i];
    csv.rows.push_back(row);
  }
  return csv;
}

double number(const std::map<std::string, std::string>& row, const std::string& key) {
  const auto it = row.find(key);
  if (it == row.end() || it->second.empty()) return std::nan("");
  return std::stod(it->second);
}

const std::map<std::string, std::string>* find(const Csv& csv, const std::string& config,
                                               const std::string& dataset) {
  for (const auto& r : csv.rows)
    if (r.at("config") == config && r.at("dataset") == dataset) return &r;
  return nullptr;
}

const std::vector<std::string> kMetrics = {
    "depth_rmse_mm",      "fill_rate",     "range_ok",        "normal_err_mean_deg",
    "normal_err_p95_deg", "force_err_rel", "bytes_per_frame", "fill_ms",
    "encode_ms",          "decode_ms",     "surface_ms",      "total_ms"};

fs::path run_quick(const std::string& name, const std::string& extra) {
  const fs::path out = ::telex::test::scratch_dir("bench_" + name);
  fs::remove_all(out);
  const std::string cmd = telex::test::built_binary("telex").string() + " bench --quick --out " +
                          out.string() + " " + extra + " > " + (out.string() + ".log") + " 2>&1";
  EXPECT_EQ(std::system(cmd.c_str()), 0) << cmd;
  return out;
}

TEST(BenchTool, QuickRunWritesFiniteCsvMarkdownAndPlots) {
  const fs::path out = run_quick("synthetic", "--real ''");
  const Csv csv = read_csv(out / "bench.csv");
  ASSERT_FALSE(csv.header.empty());
  ASSERT_GE(csv.rows.size(), 10u);
  for (const auto& row : csv.rows) {
    EXPECT_NE(row.at("dataset"), "real_desk") << "no real frames were given";
    for (const auto& m : kMetrics) {
      const double v = number(row, m);
      EXPECT_TRUE(std::isfinite(v)) << row.at("config") << " " << row.at("dataset") << " " << m;
      EXPECT_GE(v, 0.0) << m;
    }
    EXPECT_LE(number(row, "normal_err_p95_deg"), 180.0);
    EXPECT_LE(number(row, "fill_rate"), 1.0);
  }

  // Ground-truth checks that a broken chain would fail: filling closes holes, and the ROI
  // surface is bit-identical to the full frame inside the fingertip window, so the scripted
  // press and stroke feel the same forces.
  const auto* def = find(csv, "default", "synthetic");
  const auto* nofill = find(csv, "fill_off", "synthetic");
  const auto* roi = find(csv, "roi", "synthetic");
  ASSERT_TRUE(def && nofill && roi);
  EXPECT_GT(number(*def, "fill_rate"), number(*nofill, "fill_rate"));
  EXPECT_GT(number(*def, "fill_rate"), 0.9);
  EXPECT_NEAR(number(*roi, "force_err_rel"), number(*def, "force_err_rel"), 1e-6);
  EXPECT_LT(number(*roi, "pixels_processed"), number(*def, "pixels_processed"));
  // The default chain renders the press within a few per cent of the ideal surface's force.
  EXPECT_LT(number(*def, "force_err_rel"), 0.2);
  EXPECT_LT(number(*def, "normal_err_mean_deg"), 20.0);

  std::ifstream md(out / "bench.md");
  std::stringstream text;
  text << md.rdbuf();
  // The baseline is named for what it is, and the daemons' defaults are marked and explained.
  EXPECT_NE(text.str().find("| default **(baseline)**"), std::string::npos);
  EXPECT_NE(text.str().find("| kinfu_r6_roi_fill_station **(daemons' defaults)**"),
            std::string::npos);
  EXPECT_NE(text.str().find("`default` is the grid's baseline"), std::string::npos);
  EXPECT_NE(text.str().find("Static against moving"), std::string::npos);
  for (const char* png : {"normal_error_vs_ms.png", "force_error_vs_ms.png", "depth_rmse_vs_ms.png",
                          "bytes_vs_encode_ms.png"}) {
    const cv::Mat img = cv::imread((out / png).string());
    EXPECT_FALSE(img.empty()) << png;
    EXPECT_GT(img.cols, 400) << png;
  }
  fs::remove_all(out);
}

// The interleaved timing's rows build what they name: the full frame builds every pixel, the
// region of interest only the fingertip's window. Work is counted in pixels, never timed.
TEST(BenchTool, InterleavedFullFrameBuildDoesMoreWorkThanTheRoiBuild) {
  const fs::path out = ::telex::test::scratch_dir("bench_interleaved");
  telex::test::Process p({telex::test::built_binary("telex").string(), "bench", "--quick", "--json",
                          "--config", "roi", "--real", "", "--out", out.string()},
                         out / "stdout.txt", out / "stderr.txt");
  ASSERT_EQ(p.wait(std::chrono::minutes(5)), 0) << p.stderr_text();
  const auto j = nlohmann::json::parse(p.stdout_text(), nullptr, false);
  ASSERT_TRUE(j.is_object() && j.contains("roi_interleaved")) << p.stdout_text();
  const auto& t = j["roi_interleaved"];
  ASSERT_TRUE(t.contains("full_pixels") && t.contains("roi_pixels")) << t.dump();
  const auto full = t["full_pixels"].get<std::size_t>();
  const auto roi = t["roi_pixels"].get<std::size_t>();
  EXPECT_EQ(full, 640u * 480u) << "the full-frame row does not build the whole frame";
  EXPECT_GT(roi, 0u);
  EXPECT_EQ(roi, t["window_px"].get<std::size_t>());
  EXPECT_GT(full, 10 * roi);
}

// The real desk frames, and the same frames as a recorded session (telex-local --record's
// format, written here by its recorder): the session's rows are the desk's, number for number.
TEST(BenchTool, QuickRunOnRealDeskFramesAndARecordedSessionReportsFillRate) {
  TELEX_REQUIRE_REAL_DATA();
  const fs::path desk = telex::test::real_data_dir() / "desk";
  const fs::path session =
      ::telex::test::scratch_dir("bench_desk") / "telex_bench_desk_session.bag";
  {
    telex::local::RecorderConfig rc;
    rc.path = session.string();
    rc.monotonic_to_bag_ns = 1'700'000'000'000'000'000;
    telex::local::SessionRecorder recorder(rc);
    for (int i = 0; i < 3; ++i) {
      const cv::Mat depth = cv::imread(
          (desk / ("desk_" + std::to_string(i) + "_depth_mm.png")).string(), cv::IMREAD_UNCHANGED);
      ASSERT_EQ(depth.type(), CV_16UC1);
      // The bench's intrinsics and spacing for the desk frames (250 ms apart).
      ASSERT_TRUE(recorder.add_surface(
          {static_cast<std::uint64_t>(i + 1), 1'000'000'000 + i * 250'000'000LL,
           1'000'000'000 + i * 250'000'000LL, depth,
           telex::Intrinsics{525.0, 525.0, 320.0, 240.0, 640, 480}, ""}));
    }
    ASSERT_EQ(recorder.finish().surfaces, 3u);
  }
  const fs::path out =
      run_quick("real", "--real " + desk.string() + " --session " + session.string());
  const Csv csv = read_csv(out / "bench.csv");
  for (const char* config : {"default", "fill_off", "roi"}) {
    const auto* d = find(csv, config, "real_desk");
    const auto* s = find(csv, config, "session:telex_bench_desk_session");
    ASSERT_TRUE(d && s) << config;
    for (const char* m : {"fill_rate", "range_ok", "bytes_per_frame"})
      EXPECT_EQ(number(*s, m), number(*d, m)) << config << " " << m;
  }
  std::ifstream md(out / "bench.md");
  std::stringstream text;
  text << md.rdbuf();
  EXPECT_NE(text.str().find("| session:telex_bench_desk_session | default |"), std::string::npos);
  const auto* real = find(csv, "default", "real_desk");
  ASSERT_NE(real, nullptr);
  EXPECT_GT(number(*real, "fill_rate"), 0.5);
  EXPECT_LE(number(*real, "fill_rate"), 1.0);
  EXPECT_GT(number(*real, "range_ok"), 0.5);
  EXPECT_TRUE(std::isfinite(number(*real, "total_ms")));
  EXPECT_TRUE(std::isnan(number(*real, "depth_rmse_mm"))) << "real frames have no ground truth";
  fs::remove_all(out);
}

}  // namespace
