// SPDX-License-Identifier: MIT
// `telex devices`: the known-device table, a lab's own ids, the device scans on directories the
// test lays out, and the command on this machine (no device connected in CI: it says so, exit 0).
#include "telex/devices/devices.h"

#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "process.h"
#include "telex/remote/sources.h"
#include "test_support.h"

namespace telex::test {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

TEST(Devices, KnownIdsAreRecognisedAndALabsOwnComeFirst) {
  auto k = devices::identify(0x045e, 0x02ae);
  ASSERT_TRUE(k);
  EXPECT_EQ(k->name, "Kinect for Xbox 360 camera");
  k = devices::identify(0x1d27, 0x0601);  // any PrimeSense product
  ASSERT_TRUE(k);
  EXPECT_EQ(k->use, "--source openni");
  k = devices::identify(0x5d70, 0x0010);
  ASSERT_TRUE(k);
  EXPECT_EQ(k->name, "5DT Data Glove 5 Ultra (right, wired USB)");
  k = devices::identify(0x5d70, 0x0003);
  ASSERT_TRUE(k);
  EXPECT_EQ(k->name, "5DT Data Glove 14 Ultra (left, wireless port A)");
  k = devices::identify(0x5d70, 0x0017);
  ASSERT_TRUE(k);
  EXPECT_EQ(k->name, "5DT Data Glove 5 Ultra (left, wireless port B)");
  EXPECT_FALSE(devices::identify(0x5d70, 0x0004)) << "not a glove product id (VRPN lists none)";
  EXPECT_FALSE(devices::identify(0x8087, 0x0024));

  const auto gg = devices::parse_known_device("16C0:05dF=Gravity Grabber controller");
  EXPECT_EQ(gg.vendor_id, 0x16c0);
  EXPECT_EQ(gg.product_id, 0x05df);
  k = devices::identify(0x16c0, 0x05df, {gg});
  ASSERT_TRUE(k);
  EXPECT_EQ(k->name, "Gravity Grabber controller");
  // A lab's exact id wins over the built-in vendor-wide entry.
  k = devices::identify(0x1d27, 0x0600, {devices::parse_known_device("1d27:0600=rig depth")});
  EXPECT_EQ(k->name, "rig depth");

  for (const char* bad : {"16c0", "16c0:05df", "16c0:05df=", "1g:2=x", "12345:1=x", ":1=x"})
    EXPECT_THROW(devices::parse_known_device(bad), std::invalid_argument) << bad;
}

TEST(Devices, SerialPortsAndVideoNodesAreFoundInTheDirectoryGiven) {
  const auto dir = scratch_dir("devices_dev");
  fs::create_directories(dir / "serial/by-id");
  for (const char* n : {"ttyUSB0", "ttyACM1", "ttyS0", "video3", "null"})
    std::ofstream(dir / n) << "";
  fs::create_symlink(dir / "ttyUSB0", dir / "serial/by-id/usb-FTDI_FT232R-if00-port0");
  const auto ports = devices::scan_serial(dir.string());
  ASSERT_EQ(ports.size(), 3u);
  EXPECT_EQ(ports[0], (dir / "serial/by-id/usb-FTDI_FT232R-if00-port0").string());
  EXPECT_EQ(ports[1], (dir / "ttyACM1").string());
  EXPECT_EQ(ports[2], (dir / "ttyUSB0").string());

  // A node that is not a video device is listed with the reason, not skipped or fatal.
  const auto video = remote::list_v4l2_devices(dir.string());
  ASSERT_EQ(video.size(), 1u);
  EXPECT_EQ(video[0].path, (dir / "video3").string());
  EXPECT_NE(video[0].error.find("cannot open as a video device"), std::string::npos)
      << video[0].error;
  EXPECT_TRUE(devices::scan_serial((dir / "absent").string()).empty());
}

TEST(Devices, TheCommandListsWhatIsThereAndExitsZero) {
  TELEX_REQUIRE_BINARIES("telex");
  const auto dir = scratch_dir("devices_cmd");
  Process p({built_binary("telex").string(), "devices", "--json", "--usb-id", "16c0:05df=GG"},
            dir / "json.out", dir / "json.err");
  ASSERT_EQ(p.wait(60s).value_or(-1), 0) << p.stderr_text();
  const auto j = nlohmann::json::parse(p.stdout_text());
  for (const char* key : {"usb", "openni", "v4l2", "hid", "serial", "connected", "known"})
    EXPECT_TRUE(j.contains(key)) << key;
  // The JSON agrees with the scans made here.
  const auto usb = devices::scan_usb();
  EXPECT_EQ(j["usb"]["available"], usb.available);
  EXPECT_EQ(j["usb"]["devices"].size(), usb.devices.size());
  EXPECT_EQ(j["hid"].size(), devices::scan_hid().size());
  EXPECT_EQ(j["serial"].size(), devices::scan_serial().size());
  EXPECT_EQ(j["v4l2"].size(), remote::list_v4l2_devices().size());

  Process text({built_binary("telex").string(), "devices"}, dir / "text.out", dir / "text.err");
  ASSERT_EQ(text.wait(60s).value_or(-1), 0) << text.stderr_text();
  if (j["connected"] == 0)
    EXPECT_NE(text.stdout_text().find("Nothing connected"), std::string::npos)
        << text.stdout_text();
  else
    EXPECT_NE(text.stdout_text().find("device(s) found"), std::string::npos) << text.stdout_text();

  Process bad({built_binary("telex").string(), "devices", "--usb-id", "nope"}, dir / "bad.out",
              dir / "bad.err");
  EXPECT_EQ(bad.wait(60s).value_or(-1), 2);
  EXPECT_NE(bad.stderr_text().find("device id 'nope': expected VID:PID=NAME"), std::string::npos)
      << bad.stderr_text();
}

}  // namespace
}  // namespace telex::test
