// SPDX-License-Identifier: MIT
// Both daemons as processes over loopback: scripted press and stroke against the synthetic plane,
// the forces checked from telex-local's CSV log, and the operator view's PNG.
#include <gtest/gtest.h>
#include <signal.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <string>
#include <string_view>

#include "daemons.h"
#include "process.h"
#include "telex/video/frame_counter.h"
#include "test_support.h"

namespace telex::test {
namespace {

using namespace std::chrono_literals;

struct ForceRow {
  double t = 0, pressure = 0, shear = 0, fx = 0, x = 0, y = 0, z = 0;
  bool contact = false;
  std::string finger;
};

std::vector<ForceRow> read_forces(const std::filesystem::path& csv) {
  std::vector<ForceRow> rows;
  const CsvFile table = read_csv_file(csv);
  EXPECT_EQ(table.header.rfind("time_s,finger,pressure_N,shear_N,contact", 0), 0u) << table.header;
  for (const auto& f : table.rows) {
    if (f.size() < 13) continue;
    ForceRow r;
    r.t = std::stod(f[0]);
    r.finger = f[1];
    r.pressure = std::stod(f[2]);
    r.shear = std::stod(f[3]);
    r.contact = f[4] == "1";
    r.fx = std::stod(f[5]);
    r.x = std::stod(f[10]);
    r.y = std::stod(f[11]);
    r.z = std::stod(f[12]);
    rows.push_back(r);
  }
  return rows;
}

// Capture-to-force latency on the synthetic plane as docs/BENCHMARKS.md reports it ("Operator
// station", idle machine: full-frame surfaces median 18.05 ms / p99 21.45 ms over all surfaces,
// ROI first in contact median 1.85 ms / p99 4.65 ms), with room for a loaded 2-core machine: the
// loaded rounds there reach 4-9x the idle median. A bound that a stalled stage (a frame held a
// second, a surface built twice over) breaks, not "under a second".
struct LatencyBound {
  const char* what;
  const char* median_key;
  double median_ms;
  const char* p99_key;
  double p99_ms;
};
constexpr LatencyBound kFullFrameLatency{"full-frame surfaces", "latency_median_ms", 8 * 18.05,
                                         "latency_p99_ms", 12 * 21.45};
// 15x: a loaded CI check reached 19.65 ms (10.6x) with ctest -j2 beside another test run; a
// stalled stage gives hundreds of milliseconds.
constexpr LatencyBound kRoiPartsLatency{"ROI part, in contact", "contact_latency_median_ms",
                                        15 * 1.85, "contact_latency_p99_ms", 25 * 4.65};

void expect_latency_within_bench(const nlohmann::json& j, const LatencyBound& b) {
  const double median = j[b.median_key].get<double>(), p99 = j[b.p99_key].get<double>();
  EXPECT_GT(median, 0.0) << b.what;
  EXPECT_LE(median, b.median_ms * kSanitizerSlowdown) << b.what << ": median " << median << " ms";
  EXPECT_LE(p99, b.p99_ms * kSanitizerSlowdown) << b.what << ": p99 " << p99 << " ms";
}

// The summary's keys, nested objects as a.b, sorted (arrays and values are leaves).
std::vector<std::string> flat_keys(const nlohmann::json& j, const std::string& prefix = "") {
  std::vector<std::string> out;
  for (const auto& [k, v] : j.items()) {
    if (v.is_object()) {
      const auto inner = flat_keys(v, prefix + k + ".");
      out.insert(out.end(), inner.begin(), inner.end());
    } else {
      out.push_back(prefix + k);
    }
  }
  std::sort(out.begin(), out.end());
  return out;
}

TEST(Loopback, PressOnPlaneGivesHookeForceAndNothingBeforeOrAfter) {
  const auto dir = scratch_dir("loopback_press");
  RemoteProcess remote(dir, {"--source", "synthetic:plane"});
  Process local(local_args(remote.port, dir,
                           {"--hand", "script:press", "--stiffness", "500", "--max-force", "10",
                            "--duration", "7.5"}),
                dir / "local.out", dir / "local.err");
  const auto rc = local.wait(30s);
  ASSERT_TRUE(rc.has_value()) << "telex-local did not finish";
  ASSERT_EQ(*rc, 0) << local.stderr_text() << remote.proc.stderr_text();
  const auto rows = read_forces(dir / "forces.csv");
  // The log covers the whole run; the loop's rate is checked on the summary below.
  ASSERT_GT(rows.size(), 1000u);
  ASSERT_GT(rows.back().t - rows.front().t, 6.5);
  double peak = 0;
  std::size_t first_contact = rows.size(), last_contact = 0;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    if (rows[i].finger != "index") continue;
    peak = std::max(peak, rows[i].pressure);
    if (rows[i].contact) {
      first_contact = std::min(first_contact, i);
      last_contact = i;
    }
  }
  ASSERT_LT(first_contact, rows.size()) << "never touched the plane";
  EXPECT_NEAR(peak, 5.0, 0.5) << "k 500 N/m x 10 mm";
  for (std::size_t i = 0; i < first_contact; ++i) EXPECT_EQ(rows[i].pressure, 0.0) << rows[i].t;
  // After release the force has rate-limited down to zero and stays there.
  ASSERT_LT(last_contact + 200, rows.size()) << "the press did not release within the run";
  for (std::size_t i = last_contact + 100; i < rows.size(); ++i)
    EXPECT_EQ(rows[i].pressure, 0.0) << rows[i].t;
  const auto j = summary_of(local);
  ASSERT_TRUE(j.is_object()) << local.stdout_text();
  EXPECT_EQ(haptic_rate_problem(j, 7.5), "");
  EXPECT_EQ(path_scheduling_problem(j, /*realtime=*/true), "");
  // 30 Hz for the ~6.5 s after the first surface, less what a loaded machine skips.
  EXPECT_GT(j["surfaces"].get<int>(), 100 / kSanitizerSlowdown);
  // The press touched the plane, so the surfaces of its contact were first rendered in contact:
  // 30 Hz over the contact's span (about 1.1 s, so ~33), less what a loaded machine skips.
  const double contact_s = rows[last_contact].t - rows[first_contact].t;
  EXPECT_GT(j["contact_latency_samples"].get<double>(), 0.6 * 30.0 * contact_s / kSanitizerSlowdown)
      << "contact for " << contact_s << " s";
  expect_latency_within_bench(j, kFullFrameLatency);
  // The stream's mean rate is what arrived over the run's span.
  ASSERT_GT(j["bytes_in"].get<double>(), 0.0);
  EXPECT_NEAR(j["stream_mbit_per_s"].get<double>(),
              j["bytes_in"].get<double>() * 8e-6 / j["haptic_span_s"].get<double>(), 1e-9);
  // Tests and tools read these keys: a change to how the summary is declared keeps every one
  // (the list was taken from e374442's station; a key added on purpose is added to it).
  const auto want = read_text(std::filesystem::path(TELEX_SOURCE_DIR) /
                              "tests/integration/station_summary_keys.txt");
  std::string have;
  for (const auto& k : flat_keys(j)) have += k + "\n";
  EXPECT_EQ(have, want);
}

// ROI first end to end: with --roi the remote sends each frame's fingertip tiles as an ROI part
// that the station publishes at once; the press gives the same Hooke force as the full frame.
// With --no-frame-parts the same remote sends every frame in one part.
TEST(Loopback, RoiFramePartsGiveTheSamePress) {
  for (const bool parts : {true, false}) {
    const auto dir = scratch_dir(parts ? "loopback_roi_parts" : "loopback_roi_one_part");
    RemoteProcess remote(dir, {"--source", "synthetic:plane"});
    std::vector<std::string> extra{"--hand", "script:press", "--stiffness", "500",  "--max-force",
                                   "10",     "--duration",   "7.5",         "--roi"};
    if (!parts) extra.push_back("--no-frame-parts");
    Process local(local_args(remote.port, dir, extra), dir / "local.out", dir / "local.err");
    const auto rc = local.wait(30s);
    ASSERT_TRUE(rc.has_value()) << "telex-local did not finish";
    ASSERT_EQ(*rc, 0) << local.stderr_text() << remote.proc.stderr_text();
    double peak = 0;
    for (const auto& r : read_forces(dir / "forces.csv"))
      if (r.finger == "index") peak = std::max(peak, r.pressure);
    EXPECT_NEAR(peak, 5.0, 0.5) << "k 500 N/m x 10 mm, parts " << parts;
    const auto j = summary_of(local);
    ASSERT_TRUE(j.is_object()) << local.stdout_text();
    EXPECT_EQ(haptic_rate_problem(j, 7.5), "") << parts;
    EXPECT_GT(j["frames"].get<int>(), 100 / kSanitizerSlowdown) << parts;
    expect_latency_within_bench(j, parts ? kRoiPartsLatency : kFullFrameLatency);
    // The status line's surface rate counts frames, as the 30 fps source does: a frame built
    // twice (its ROI part, then its rest) is one frame.
    const std::string err = local.stderr_text();
    double max_fps = 0.0;
    int lines = 0;
    for (std::size_t at = err.find("surface "); at != std::string::npos;
         at = err.find("surface ", at + 8)) {
      char* end = nullptr;
      const double fps = std::strtod(err.c_str() + at + 8, &end);
      if (end != err.c_str() + at + 8 && std::string_view(end).starts_with(" fps")) {
        max_fps = std::max(max_fps, fps);
        ++lines;
      }
    }
    EXPECT_GE(lines, 3) << err;
    // 30 fps with room for a late status tick or a bunched frame; counting the ROI part and the
    // rest of every 2nd frame as two would read about 45.
    EXPECT_LE(max_fps, 38.0) << "parts " << parts << ": the rate counts builds, not frames";
    if (parts) {
      // Frames whose rest was due (every 2nd, key frames) came in two parts.
      EXPECT_GT(j["roi_parts"].get<int>(), 0);
      EXPECT_LE(j["roi_parts"].get<int>(), j["frames"].get<int>());
    } else {
      EXPECT_EQ(j["roi_parts"].get<int>(), 0);
    }
  }
}

TEST(Loopback, StrokeShearOpposesSliding) {
  const auto dir = scratch_dir("loopback_stroke");
  RemoteProcess remote(dir, {"--source", "synthetic:plane", "--transport", "tcp"});
  Process local(local_args(remote.port, dir,
                           {"--hand", "script:stroke", "--stiffness", "500", "--max-force", "10",
                            "--transport", "tcp", "--duration", "9.5"}),
                dir / "local.out", dir / "local.err");
  const auto rc = local.wait(30s);
  ASSERT_TRUE(rc.has_value());
  ASSERT_EQ(*rc, 0) << local.stderr_text();
  EXPECT_EQ(haptic_rate_problem(summary_of(local), 9.5), "");
  const auto rows = read_forces(dir / "forces.csv");
  int opposing = 0, agreeing = 0, axis_opposing = 0;
  for (std::size_t i = 10; i < rows.size(); ++i) {
    const auto& r = rows[i];
    const auto& p = rows[i - 10];
    if (r.finger != "index" || p.finger != "index" || !r.contact) continue;
    const double vx = (r.x - p.x) / (r.t - p.t);
    if (std::abs(vx) < 0.03 || std::abs(r.fx) < 0.05) continue;  // sliding, with friction
    (vx * r.fx < 0 ? opposing : agreeing)++;
    // The finger axis has a +x component, so the along-axis shear has the sign of fx.
    axis_opposing += (vx * r.shear < 0);
  }
  ASSERT_GT(opposing + agreeing, 500) << "too few sliding samples";
  EXPECT_GT(opposing, 20 * agreeing) << opposing << " vs " << agreeing;
  EXPECT_GT(axis_opposing, (opposing + agreeing) * 9 / 10);
}

TEST(Loopback, ViewPngShowsHandAndForceArrow) {
  const auto dir = scratch_dir("loopback_view");
  RemoteProcess remote(dir, {"--source", "synthetic:plane"});
  Process local(local_args(remote.port, dir,
                           {"--hand", "script:press", "--stiffness", "500", "--duration", "7",
                            "--view", "png:" + (dir / "view").string(), "--view-at", "3.6"}),
                dir / "local.out", dir / "local.err");
  ASSERT_EQ(local.wait(30s).value_or(-1), 0) << local.stderr_text();
  // --view-at 3.6: half way through the press's 1 s hold, whenever the run's seconds fall (the
  // script approaches the plane 0.3 m away at 0.1 m/s, so it is 10 mm in from 3.1 s to 4.1 s).
  const cv::Mat img = cv::imread((dir / "view" / "view.png").string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(img.empty()) << local.stderr_text();
  // The fingertip is drawn in the contact colour at the image centre and the force arrow in its own
  // colour (operator_view.cpp); neither colour occurs in the background.
  const cv::Vec3b contact(40, 40, 255), arrow(0, 200, 255);
  int contact_px = 0, arrow_px = 0;
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) {
      const auto c = img.at<cv::Vec3b>(y, x);
      contact_px += (c == contact);
      arrow_px += (c == arrow);
    }
  EXPECT_GT(contact_px, 30);
  EXPECT_GT(arrow_px, 30);
  EXPECT_EQ(img.at<cv::Vec3b>(img.rows / 2, img.cols / 2), contact);
}

// A remote with a head stamps each eye pair with its joints at the pair's capture (PROTOCOL.md
// 2.7): the station's summary counts the pairs that came with one, here all it decoded whole but
// any captured before the head loop's first reading.
TEST(Loopback, EyePairsFromARemoteWithAHeadCarryItsPose) {
  const auto dir = scratch_dir("loopback_pair_pose");
  RemoteProcess remote(dir, {"--source", "synthetic:plane", "--size", "160x120", "--stereo",
                             "synthetic:plane", "--head", "sim"});
  Process local(local_args(remote.port, dir,
                           {"--hand", "script:press", "--repeat", "--duration", "3", "--view",
                            "png:" + (dir / "view").string()}),
                dir / "local.out", dir / "local.err");
  ASSERT_EQ(local.wait(40s).value_or(-1), 0) << local.stderr_text();
  const auto j = summary_of(local);
  const int decoded = j["video_pairs_decoded"].get<int>();
  const int posed = j["video_pairs_with_head_pose"].get<int>();
  std::printf("eye pairs: %d decoded whole, %d with the head's pose\n", decoded, posed);
  EXPECT_GT(decoded, 10) << j.dump();
  EXPECT_GE(posed, decoded - 2) << j.dump();
  EXPECT_LE(posed, decoded) << j.dump();
}

TEST(Loopback, StereoViewShowsBothEyesVideoAndTheArmWhileDepthKeepsFlowing) {
  const auto dir = scratch_dir("loopback_stereo_view");
  // The synthetic stereo source: both eyes' renders of the plane at 30 fps over UDP with the depth.
  RemoteProcess remote(dir, {"--source", "synthetic:plane", "--stereo", "synthetic:plane"});
  const double seconds = 5.0;
  Process local(local_args(remote.port, dir,
                           {"--hand", "script:press", "--repeat", "--duration",
                            std::to_string(seconds), "--view", "png:" + (dir / "view").string()}),
                dir / "local.out", dir / "local.err");
  ASSERT_EQ(local.wait(40s).value_or(-1), 0) << local.stderr_text();
  // Video must not starve the depth: its datagrams once carried their own frame ids and the
  // reassembler dropped the depth as stale (one surface in 5 s).
  const auto j = summary_of(local);
  EXPECT_GT(j["surfaces"].get<int>(), 60) << j.dump();
  // The eyes came as H.264 pairs (the default --video-codec) and decoded whole at the source's
  // size; the view showed some; both streams' rates are reported apart.
  EXPECT_GT(j["video_pairs_decoded"].get<int>(), 30) << j.dump();
  EXPECT_EQ(j["video_decode_errors"].get<int>(), 0) << j.dump();
  EXPECT_EQ(j["video_eye_width_px"].get<int>(), 640) << j.dump();
  EXPECT_EQ(j["video_eye_height_px"].get<int>(), 480) << j.dump();
  EXPECT_GT(j["video_pairs_shown"].get<int>(), 0) << j.dump();
  EXPECT_EQ(j["video_pairs_with_head_pose"].get<int>(), 0) << j.dump();  // the remote has no head
  EXPECT_GT(j["video_mbit_s"].get<double>(), 0.0) << j.dump();
  EXPECT_GT(j["depth_mbit_s"].get<double>(), 0.0) << j.dump();
  EXPECT_TRUE(j.contains("shown_frame_age_ms_p99")) << j.dump();
  EXPECT_TRUE(j.contains("video_plis_sent")) << j.dump();
  // Glass to glass: the synthetic eyes' frame counter, read from the video each frame drew, is the
  // id of the pair drawn, every time, and its age is positive.
  EXPECT_GT(j["glass_to_glass_samples"].get<int>(), 0) << j.dump();
  EXPECT_EQ(j["glass_to_glass_mismatched"].get<int>(), 0) << j.dump();
  EXPECT_GT(j["glass_to_glass_ms_median"].get<double>(), 0.0) << j.dump();
  // Latency a person notices: every stereo frame drew the scripted body (stamped at its haptic
  // poll), those with a pair drew its capture; both to the PNGs written.
  const auto m2p = j["motion_to_photon_samples"].get<int>();
  const auto c2p = j["capture_to_photon_samples"].get<int>();
  EXPECT_GT(m2p, 0) << j.dump();
  EXPECT_GT(c2p, 0) << j.dump();
  EXPECT_LE(c2p, m2p) << j.dump();
  for (const char* what : {"motion_to_photon", "capture_to_photon"}) {
    const double median = j[std::string(what) + "_ms_median"].get<double>();
    EXPECT_GT(median, 0.0) << what << " " << j.dump();
    EXPECT_GE(j[std::string(what) + "_ms_p99"].get<double>(), median) << what;
  }
  const cv::Mat left = cv::imread((dir / "view" / "left.png").string(), cv::IMREAD_COLOR);
  const cv::Mat right = cv::imread((dir / "view" / "right.png").string(), cv::IMREAD_COLOR);
  const cv::Mat sbs = cv::imread((dir / "view" / "sbs.png").string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(left.empty() || right.empty() || sbs.empty()) << local.stderr_text();
  EXPECT_EQ(left.size(), cv::Size(640, 480));
  EXPECT_EQ(sbs.size(), cv::Size(1280, 480));
  for (const cv::Mat* eye : {&left, &right}) {
    // The eye's video (the plane's shaded render, light grey), not the no-video fallback (64).
    const cv::Vec3b bg = eye->at<cv::Vec3b>(200, 40);
    EXPECT_GT(bg[0], 100) << bg;
    // The arm and hand: skin-shaded pixels (red above blue).
    int skin = 0;
    for (int y = 0; y < eye->rows; ++y)
      for (int x = 0; x < eye->cols; ++x) {
        const auto c = eye->at<cv::Vec3b>(y, x);
        skin += c[2] > c[0] + 30;
      }
    EXPECT_GT(skin, 3000);
    // The counter the synthetic eyes stamp top left is measured (glass to glass, above) but not
    // shown: the corner holds the plane again, no black and white cells, and reads as nothing.
    const cv::Rect corner = video::frame_counter_rect(eye->size());
    cv::Scalar mean, spread;
    cv::meanStdDev((*eye)(corner), mean, spread);
    EXPECT_LT(spread[1], 12.0) << "the frame counter's cells are in the picture";
    EXPECT_FALSE(video::read_frame_counter(*eye));
  }
  EXPECT_EQ(local.stderr_text().find("one eye's video only"), std::string::npos);
}

}  // namespace
}  // namespace telex::test

namespace telex::test {
namespace {

TEST(Loopback, NatNetSimulatorDrivesTheFingertips) {
  const auto dir = scratch_dir("loopback_natnet");
  RemoteProcess remote(dir, {"--source", "synthetic:plane"});
  const std::uint16_t cmd_port = free_port();
  Process sim({built_binary("telex-sim-natnet").string(), "--command-port",
               std::to_string(cmd_port), "--duration", "20", "--natnet-version", "4.1"},
              dir / "sim.out", dir / "sim.err");
  Process local(local_args(remote.port, dir,
                           {"--hand", "natnet:127.0.0.1,unicast", "--natnet-cmd-port",
                            std::to_string(cmd_port), "--log-tracking",
                            (dir / "tracking.csv").string(), "--duration", "4"}),
                dir / "local.out", dir / "local.err");
  ASSERT_EQ(local.wait(30s).value_or(-1), 0) << local.stderr_text();
  sim.signal(SIGINT);
  // Every rigid body as reported: head 1, hand 2, shoulder 3, tracked.
  const CsvFile table = read_csv_file(dir / "tracking.csv");
  EXPECT_EQ(table.header, "time_s,body_id,x_m,y_m,z_m,qx,qy,qz,qw,valid");
  std::map<int, int> valid_rows;
  for (const auto& f : table.rows) {
    ASSERT_EQ(f.size(), 10u) << testing::PrintToString(f);
    if (f[9] == "1") valid_rows[std::stoi(f[1])]++;
  }
  for (int id : {1, 2, 3}) EXPECT_GT(valid_rows[id], 100) << "body " << id;
  // The index fingertip follows the simulated hand: it moves in depth by several centimetres.
  const auto rows = read_forces(dir / "forces.csv");
  double zmin = 1e9, zmax = -1e9;
  for (const auto& r : rows)
    if (r.finger == "index") {
      zmin = std::min(zmin, r.z);
      zmax = std::max(zmax, r.z);
    }
  EXPECT_GT(zmax - zmin, 0.05);
}

}  // namespace
}  // namespace telex::test

namespace telex::test {
namespace {

TEST(LocalFlags, WindowViewWithoutDisplaySaysWhatToDo) {
  const auto dir = scratch_dir("local_window_no_display");
  unsetenv("DISPLAY");
  unsetenv("WAYLAND_DISPLAY");
  Process local({built_binary("telex-local").string(), "--view", "window"}, dir / "out",
                dir / "err");
  ASSERT_EQ(local.wait(10s).value_or(-1), 2);
  EXPECT_NE(local.stderr_text().find("--view png:DIR"), std::string::npos) << local.stderr_text();
}

// The station's status line says whether the eyes arrive: a remote with no eye source reads
// "eyes off" on both sides (the remote tells the station it has no --stereo), not only a grey
// background in the view; no status line ends in a bare separator.
TEST(Loopback, TheStatusLineSaysWhetherTheEyesArrive) {
  for (const bool eyes : {true, false}) {
    const auto dir = scratch_dir(eyes ? "status_eyes" : "status_no_eyes");
    std::vector<std::string> remote_args{"--source", "synthetic:plane"};
    if (eyes) remote_args.insert(remote_args.end(), {"--stereo", "synthetic:plane"});
    RemoteProcess remote(dir, remote_args);
    Process local(local_args(remote.port, dir,
                             {"--hand", "script:press", "--duration", "3.5", "--view",
                              "png:" + (dir / "view").string()}),
                  dir / "local.out", dir / "local.err");
    const auto rc = local.wait(30s);
    ASSERT_TRUE(rc.has_value()) << "telex-local did not finish";
    ASSERT_EQ(*rc, 0) << local.stderr_text();
    const std::string err = local.stderr_text();
    if (eyes) {
      EXPECT_NE(err.find(" pairs/s"), std::string::npos) << err;
    } else {
      EXPECT_NE(err.find("eyes off (the remote runs without --stereo)"), std::string::npos) << err;
      EXPECT_EQ(err.find(" pairs/s"), std::string::npos) << err;
    }
    EXPECT_EQ(err.find(" |\n"), std::string::npos) << "a line ends in a bare separator:\n" << err;
  }
}

// A files source that plays once: when it has ended the remote says so and the station's status
// line says it, instead of "surface 0.0 fps | latency 0.0 ms | streaming" for as long as it runs;
// the same for the eyes.
TEST(Loopback, TheStationSaysWhenTheRemotesSourcesEnded) {
  TELEX_REQUIRE_REAL_DATA();
  const auto desk = real_data_dir() / "desk";
  const auto dir = scratch_dir("sources_ended");
  RemoteProcess remote(
      dir,
      {"--source", "files:" + (desk / "desk_0_depth_mm.png").string(), "--stereo",
       "files:" + (desk / "desk_0_rgb.png").string() + "," + (desk / "desk_0_rgb.png").string()});
  Process local(local_args(remote.port, dir,
                           {"--hand", "script:press", "--duration", "7", "--view",
                            "png:" + (dir / "view").string()}),
                dir / "local.out", dir / "local.err");
  const auto rc = local.wait(90s);
  ASSERT_TRUE(rc.has_value()) << "telex-local did not finish";
  const std::string err = local.stderr_text();
  EXPECT_NE(err.find("the remote's depth source ended: the last surface stays"), std::string::npos)
      << err;
  EXPECT_NE(err.find("eyes ended (the remote's --stereo source played to its end)"),
            std::string::npos)
      << err;
}

}  // namespace
}  // namespace telex::test
