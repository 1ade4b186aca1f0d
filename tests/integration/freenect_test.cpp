// SPDX-License-Identifier: MIT
// The Kinect v1 source (`--source freenect`) under Debian's `fakenect` replay wrapper, on a
// recording this test writes in fakenect-record's layout from the synthetic renderer's disparity:
// every frame `telex capture` saves equals the same dump loaded as `--units kinect-disparity`.
// A broken recording is named line by line instead of fakenect's own exit(1).
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "process.h"
#include "telex/common/depth_io.h"
#include "telex/common/synthetic.h"
#include "telex/remote/sources.h"
#include "test_support.h"

namespace telex::test {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

constexpr const char* kFakenect = "/usr/bin/fakenect";

// The telex tool, run under Debian's fakenect wrapper (tools/setup.sh installs libfreenect-bin).
#define TELEX_REQUIRE_FAKENECT()                                      \
  TELEX_REQUIRE_BINARIES("telex");                                    \
  TELEX_SKIP_UNLESS(fs::exists(kFakenect),                            \
                    "Debian's fakenect (package libfreenect-bin) is " \
                    "missing")

// fakenect-record's dump_depth: "P5 640 480 65535\n" then the 11-bit samples as the host wrote
// them (little-endian here); INDEX.txt names each file as TYPE-SECONDS-TIMESTAMP.EXT.
struct Recording {
  fs::path dir;
  std::vector<fs::path> depth;
};

Recording write_recording(const fs::path& dir, int frames) {
  fs::create_directories(dir);
  Recording rec{dir, {}};
  std::ofstream index(dir / "INDEX.txt");
  const synth::Scene scene = synth::Scene::named("moving");
  const Intrinsics intr = kinect_v1_intrinsics(640, 480);
  const double t0 = 1294783212.0;
  for (int i = 0; i < frames; ++i) {
    const double t = i / 30.0;
    const synth::Rendered r =
        synth::render(scene.at_time(t), intr, synth::SensorModel{}, static_cast<std::uint64_t>(i));
    const cv::Mat1w disparity = mm_to_kinect_disparity(r.depth.depth_mm);
    char name[64];
    std::snprintf(name, sizeof name, "d-%f-%u.pgm", t0 + t,
                  1000u + 1000u * static_cast<unsigned>(i));
    std::ofstream f(dir / name, std::ios::binary);
    f << "P5 640 480 65535\n";
    f.write(reinterpret_cast<const char*>(disparity.data),
            static_cast<std::streamsize>(disparity.total() * 2));
    index << name << "\n";
    rec.depth.push_back(dir / name);
    if (i == 1) {  // an rgb frame and an accelerometer sample between depth frames: skipped
      std::snprintf(name, sizeof name, "r-%f-%u.ppm", t0 + t + 0.001, 1500u);
      std::ofstream rgb(dir / name, std::ios::binary);
      rgb << "P6 640 480 255\n" << std::string(640 * 480 * 3, '\x40');
      index << name << "\n";
      std::snprintf(name, sizeof name, "a-%f-%u.dump", t0 + t + 0.002, 1600u);
      // sizeof(freenect_raw_tilt_state) in libfreenect 0.5: 3 x int16, int8, an enum.
      std::ofstream(dir / name, std::ios::binary) << std::string(12, '\0');
      index << name << "\n";
    }
  }
  return rec;
}

// A recording of the Kinect's IR video mode in fakenect's layout: depth dumps as above, each
// followed by an IR dump "P5 640 488 255" (8-bit) or "P5 640 488 1023" (10-bit, host-order u16),
// padded to the 921600 bytes fakenect 0.5 copies from every video dump. Each IR frame is a ramp
// that differs per frame, so the captured images can be matched to the dumps.
struct IrRecording {
  fs::path dir;
  std::vector<cv::Mat> ir;  // 640x488, as dumped
};

IrRecording write_ir_recording(const fs::path& dir, int frames, int bits) {
  const Recording depth = write_recording(dir, frames);
  IrRecording rec{dir, {}};
  std::ofstream index(dir / "INDEX.txt", std::ios::trunc);
  for (int i = 0; i < frames; ++i) {
    index << depth.depth[static_cast<std::size_t>(i)].filename().string() << "\n";
    cv::Mat img(488, 640, bits == 8 ? CV_8UC1 : CV_16UC1);
    const int top = bits == 8 ? 255 : 1023;
    for (int r = 0; r < img.rows; ++r)
      for (int c = 0; c < img.cols; ++c) {
        const int v = (r * 3 + c * 5 + i * 37) % (top + 1);
        if (bits == 8)
          img.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(v);
        else
          img.at<std::uint16_t>(r, c) = static_cast<std::uint16_t>(v);
      }
    char name[64];
    std::snprintf(name, sizeof name, "r-%f-%u.pgm", 1294783212.0 + i / 30.0 + 0.001,
                  1500u + 1000u * static_cast<unsigned>(i));
    std::ofstream f(dir / name, std::ios::binary);
    f << (bits == 8 ? "P5 640 488 255\n" : "P5 640 488 1023\n");
    const auto bytes = static_cast<std::streamsize>(img.total() * img.elemSize());
    f.write(reinterpret_cast<const char*>(img.data), bytes);
    f << std::string(static_cast<std::size_t>(640 * 480 * 3 - bytes), '\0');
    index << name << "\n";
    rec.ir.push_back(img);
  }
  return rec;
}

struct FakenectRun {
  int rc = -1;
  std::string out, err;
};

FakenectRun capture_under_fakenect(const fs::path& recording, const fs::path& out, int frames,
                                   const std::string& name, std::vector<std::string> extra = {}) {
  std::vector<std::string> argv{
      kFakenect,  recording.string(), built_binary("telex").string(), "capture", "--source",
      "freenect", "--frames",         std::to_string(frames),         "--out",   out.string(),
      "--json"};
  argv.insert(argv.end(), extra.begin(), extra.end());
  Process p(argv, out.parent_path() / (name + ".out"), out.parent_path() / (name + ".err"));
  const auto rc = p.wait(60s);
  EXPECT_TRUE(rc.has_value()) << "telex capture under fakenect did not finish";
  return {rc.value_or(-1), p.stdout_text(), p.stderr_text()};
}

TEST(Freenect, FakenectReplayEqualsTheDumpLoadedAsKinectDisparity) {
  TELEX_REQUIRE_FAKENECT();
  const auto dir = scratch_dir("freenect_replay");
  const Recording rec = write_recording(dir / "rec", 8);
  const auto out = dir / "out";
  const FakenectRun r = capture_under_fakenect(rec.dir, out, 5, "run");
  ASSERT_EQ(r.rc, 0) << r.err << r.out;
  std::ifstream is(out / "capture.json");
  const auto j = nlohmann::json::parse(is);
  ASSERT_EQ(j["files"].size(), 5u);
  EXPECT_NE(j["source"].get<std::string>().find("fakenect"), std::string::npos) << j["source"];
  // Each saved frame is one of the dumps, bit for bit, in recording order (a slow reader may
  // lose a frame to the source's bounded queue, never reorder or alter one).
  std::vector<cv::Mat1w> expected;
  for (const auto& d : rec.depth)
    expected.push_back(load_depth(d, DepthUnits::KinectDisparity, kinect_v1_intrinsics()).depth_mm);
  int last = -1;
  for (const auto& f : j["files"]) {
    const cv::Mat got =
        cv::imread((out / f["file"].get<std::string>()).string(), cv::IMREAD_UNCHANGED);
    ASSERT_EQ(got.type(), CV_16UC1);
    int match = -1;
    for (int k = last + 1; k < static_cast<int>(expected.size()) && match < 0; ++k)
      if (cv::norm(got, expected[static_cast<std::size_t>(k)], cv::NORM_INF) == 0) match = k;
    ASSERT_GE(match, 0) << f["file"] << " equals no later dump of the recording";
    EXPECT_GT(cv::countNonZero(got), 640 * 480 / 2) << "the scene is mostly surface";
    last = match;
  }
}

// `telex capture --ir` under fakenect: every IR image written is 640x480 (the depth's rows of the
// 640x488 IR frame), of the bit depth asked, and equals its dump's rows 4..483 in recording order.
TEST(Freenect, IrFramesAreWrittenAtTheDepthsSizeAndTheirBitDepth) {
  TELEX_REQUIRE_FAKENECT();
  for (const int bits : {10, 8}) {
    SCOPED_TRACE(bits);
    const auto dir = scratch_dir("freenect_ir_" + std::to_string(bits));
    const IrRecording rec = write_ir_recording(dir / "rec", 8, bits);
    const auto out = dir / "out";
    const FakenectRun r =
        capture_under_fakenect(rec.dir, out, 4, "run", {"--ir", "--ir-bits", std::to_string(bits)});
    ASSERT_EQ(r.rc, 0) << r.err << r.out;
    std::ifstream is(out / "capture.json");
    const auto j = nlohmann::json::parse(is);
    EXPECT_EQ(j["ir_frames"], 4);
    EXPECT_NE(j["ir_projector"].get<std::string>().find("on (libfreenect cannot switch"),
              std::string::npos)
        << j["ir_projector"];
    ASSERT_EQ(j["files"].size(), 4u);
    int last = -1;
    for (const auto& f : j["files"]) {
      ASSERT_TRUE(f.contains("ir")) << f;
      EXPECT_EQ(f["ir_bits"], bits);
      const cv::Mat got =
          cv::imread((out / f["ir"].get<std::string>()).string(), cv::IMREAD_UNCHANGED);
      ASSERT_EQ(got.type(), bits == 8 ? CV_8UC1 : CV_16UC1) << f["ir"];
      ASSERT_EQ(got.cols, 640);
      ASSERT_EQ(got.rows, 480);
      double top = 0;
      cv::minMaxLoc(got, nullptr, &top);
      EXPECT_LE(top, bits == 8 ? 255 : 1023);
      int match = -1;
      for (int k = last + 1; k < static_cast<int>(rec.ir.size()) && match < 0; ++k)
        if (cv::norm(got, rec.ir[static_cast<std::size_t>(k)].rowRange(4, 484), cv::NORM_INF) == 0)
          match = k;
      ASSERT_GE(match, 0) << f["ir"] << " equals no later IR dump's rows 4..483";
      last = match;
    }
  }
}

// An IR capture of a recording without IR video (fakenect-record's RGB), or of the other bit
// depth, is named before anything is replayed; a source without an IR camera is a usage error.
TEST(Freenect, AnIrCaptureWithoutIrVideoIsNamed) {
  TELEX_REQUIRE_FAKENECT();
  const auto dir = scratch_dir("freenect_ir_none");
  const Recording rgb = write_recording(dir / "rgb", 3);
  FakenectRun r = capture_under_fakenect(rgb.dir, dir / "out_rgb", 2, "rgb", {"--ir"});
  EXPECT_EQ(r.rc, 1);
  EXPECT_NE(r.err.find("holds no IR video (1 rgb dumps"), std::string::npos) << r.err;
  const IrRecording eight = write_ir_recording(dir / "eight", 3, 8);
  r = capture_under_fakenect(eight.dir, dir / "out_eight", 2, "eight", {"--ir"});
  EXPECT_EQ(r.rc, 1);
  EXPECT_NE(r.err.find("--ir 10-bit, but the fakenect recording"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("holds IR 8-bit video"), std::string::npos) << r.err;

  Process p({built_binary("telex").string(), "capture", "--source", "synthetic:plane", "--ir",
             "--out", (dir / "out_synthetic").string()},
            dir / "synthetic.out", dir / "synthetic.err");
  const auto rc = p.wait(60s);
  ASSERT_TRUE(rc.has_value());
  EXPECT_EQ(*rc, 2);
  EXPECT_NE(p.stderr_text().find("--ir: source synthetic"), std::string::npos) << p.stderr_text();
  EXPECT_NE(p.stderr_text().find("has no IR camera"), std::string::npos) << p.stderr_text();
}

TEST(Freenect, ABrokenRecordingIsNamedNotExitedOn) {
  TELEX_REQUIRE_FAKENECT();
  const auto dir = scratch_dir("freenect_broken");
  const Recording rec = write_recording(dir / "rec", 3);
  {
    std::ofstream index(rec.dir / "INDEX.txt", std::ios::app);
    index << "d-1294783299.000000-9000.pgm\n";  // names a file that is not there
  }
  const FakenectRun r = capture_under_fakenect(rec.dir, dir / "out", 2, "run");
  EXPECT_NE(r.rc, 0);
  EXPECT_NE(r.err.find("INDEX.txt line 6"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("d-1294783299.000000-9000.pgm"), std::string::npos) << r.err;
  EXPECT_EQ(r.out.find("Cannot open file"), std::string::npos) << "fakenect's exit(1) was reached";
}

// Without fakenect the source asks libfreenect for a real sensor; this machine has none.
TEST(Freenect, NoKinectIsAClearError) {
  TELEX_REQUIRE_BINARIES("telex");
  const auto dir = scratch_dir("freenect_none");
  Process p({built_binary("telex").string(), "capture", "--source", "freenect:3", "--frames", "1",
             "--out", (dir / "out").string()},
            dir / "run.out", dir / "run.err");
  const auto rc = p.wait(60s);
  ASSERT_TRUE(rc.has_value());
  EXPECT_NE(*rc, 0);
  const std::string err = p.stderr_text();
  EXPECT_NE(err.find("freenect"), std::string::npos) << err;
  EXPECT_TRUE(err.find("no Kinect v1 at index 3") != std::string::npos ||
              err.find("could not initialise") != std::string::npos)
      << err;
}

struct BadCase {
  const char* name;
  std::function<void(const fs::path&)> damage;
  const char* expect;
};

TEST(Freenect, EveryKindOfDamageIsNamed) {
  const auto base = scratch_dir("freenect_damage");
  const std::vector<BadCase> cases = {
      {"no_index", [](const fs::path& d) { fs::remove(d / "INDEX.txt"); }, "no INDEX.txt"},
      {"garbage_line",
       [](const fs::path& d) { std::ofstream(d / "INDEX.txt", std::ios::app) << "hello\n"; },
       "line 6 ('hello'): not TYPE-SECONDS-TIMESTAMP.EXT"},
      {"unknown_type",
       [](const fs::path& d) {
         std::ofstream(d / "x-1.5-3.bin", std::ios::binary) << "x";
         std::ofstream(d / "INDEX.txt", std::ios::app) << "x-1.5-3.bin\n";
       },
       "type 'x' is none of d (depth)"},
      {"short_dump",
       [](const fs::path& d) {
         std::ofstream(d / "d-2.0-7.pgm", std::ios::binary) << "P5 640 480 65535\n"
                                                            << "abc";
         std::ofstream(d / "INDEX.txt", std::ios::app) << "d-2.0-7.pgm\n";
       },
       "a depth frame needs 614417"},
      {"wrong_header",
       [](const fs::path& d) {
         std::ofstream(d / "d-2.0-8.pgm", std::ios::binary) << "P5\n640 480\n65535\n"
                                                            << std::string(640 * 480 * 2, '\0');
         std::ofstream(d / "INDEX.txt", std::ios::app) << "d-2.0-8.pgm\n";
       },
       "is not fakenect's 'P5 640 480 65535'"},
      {"only_rgb", [](const fs::path& d) { std::ofstream(d / "INDEX.txt", std::ios::trunc) << ""; },
       "lists no depth frame"},
  };
  for (const auto& c : cases) {
    const Recording rec = write_recording(base / c.name, 3);
    EXPECT_NO_THROW(remote::check_fakenect_recording(rec.dir)) << c.name;
    c.damage(rec.dir);
    try {
      remote::check_fakenect_recording(rec.dir);
      ADD_FAILURE() << c.name << ": accepted";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(c.expect), std::string::npos)
          << c.name << ": " << e.what();
    }
  }
  const auto ok = remote::check_fakenect_recording(write_recording(base / "ok", 3).dir);
  EXPECT_EQ(ok.depth_files.size(), 3u);
  EXPECT_EQ(ok.rgb, 1);
  EXPECT_EQ(ok.accelerometer, 1);
}

}  // namespace
}  // namespace telex::test
