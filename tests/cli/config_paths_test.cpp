// SPDX-License-Identifier: MIT
// Paths in a --config file are relative to that file's folder, not to the working directory (a
// daemon started by systemd runs in /): a keyed pair started from another folder finds its key,
// a missing file is named with the config file and the path searched, and a rig named there is
// read (it was ignored).
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "daemons.h"
#include "process.h"
#include "test_support.h"

namespace telex {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

// `binary` with `args`, started in `cwd` (a shell changes into it first).
test::Process start_in(const fs::path& cwd, const std::string& binary,
                       const std::vector<std::string>& args, const fs::path& out_dir,
                       const std::string& name) {
  std::string command = "cd '" + cwd.string() + "' && exec '" + test::built_binary(binary).string();
  command += "'";
  for (const auto& a : args) command += " '" + a + "'";
  return test::Process({"/bin/sh", "-c", command}, out_dir / (name + ".out"),
                       out_dir / (name + ".err"));
}

// A folder `cfg` for the config files and an empty `elsewhere` the daemons start in.
struct Layout {
  explicit Layout(const std::string& name) : dir(test::scratch_dir(name)) {
    fs::create_directories(cfg);
    fs::create_directories(elsewhere);
  }
  void write(const std::string& file, const std::string& text) const {
    std::ofstream(cfg / file) << text;
  }
  fs::path dir;
  fs::path cfg = dir / "cfg", elsewhere = dir / "elsewhere";
};

TEST(ConfigPaths, AKeyBesideTheConfigIsFoundFromAnotherWorkingDirectory) {
  const Layout l("key_beside_config");
  {
    std::ofstream key(l.cfg / "telex.key", std::ios::binary);
    for (int i = 0; i < 32; ++i) key.put(static_cast<char>(i * 7 + 3));
  }
  fs::permissions(l.cfg / "telex.key", fs::perms::owner_read | fs::perms::owner_write);
  const std::uint16_t port = test::free_port();
  const std::string listen = "127.0.0.1:" + std::to_string(port);
  l.write("remote.toml", "psk = \"telex.key\"\nlisten = \"" + listen +
                             "\"\nsource = \"synthetic:plane\"\nduration = 20\n");
  // The display's CSV is a path inside a spec: it lands beside the config too.
  l.write("local.toml", "psk = \"telex.key\"\nconnect = \"" + listen +
                            "\"\nhaptics = \"sim:display.csv\"\nlog-forces = \"forces.csv\"\n"
                            "duration = 3\njson-summary = true\n");
  test::Process remote =
      start_in(l.elsewhere, "telex-remote", {"--config", "../cfg/remote.toml"}, l.dir, "remote");
  test::Process local =
      start_in(l.elsewhere, "telex-local", {"--config", "../cfg/local.toml"}, l.dir, "local");
  const auto rc = local.wait(60s);
  ASSERT_EQ(rc.value_or(-1), 0) << local.stderr_text() << remote.stderr_text();
  EXPECT_NE(remote.stderr_text().find("TLS 1.3 with --psk"), std::string::npos)
      << remote.stderr_text();
  EXPECT_GT(test::summary_of(local).value("surfaces", 0), 0) << local.stdout_text();
  EXPECT_TRUE(fs::exists(l.cfg / "forces.csv"));
  EXPECT_TRUE(fs::exists(l.cfg / "display.csv"));
  EXPECT_FALSE(fs::exists(l.elsewhere / "forces.csv"));
  // The log says which file each path resolved to.
  EXPECT_NE(local.stderr_text().find("psk=" + (l.cfg / "telex.key").string()), std::string::npos)
      << local.stderr_text();
}

TEST(ConfigPaths, AMissingFileIsNamedWithTheConfigFileAndThePathSearched) {
  const Layout l("missing_beside_config");
  l.write("psk.toml", "psk = \"absent.key\"\n");
  l.write("rig.toml", "rig = \"absent-rig.json\"\n");
  for (const char* daemon : {"telex-remote", "telex-local"}) {
    for (const auto& [file, missing] :
         {std::pair<std::string, std::string>{"psk.toml", "absent.key"},
          {"rig.toml", "absent-rig.json"}}) {
      // Had the file been ignored, the run would end at once, listening or connecting nowhere.
      const std::string where = daemon == std::string("telex-remote") ? "--listen" : "--connect";
      const std::string port =
          daemon == std::string("telex-remote") ? "127.0.0.1:0" : "127.0.0.1:1";
      test::Process p =
          start_in(l.elsewhere, daemon,
                   {"--config", "../cfg/" + file, where, port, "--duration", "0.5"}, l.dir, "run");
      const auto rc = p.wait(30s);
      const std::string err = p.stderr_text();
      EXPECT_EQ(rc.value_or(-1), 2) << daemon << " " << file << ": " << err;
      EXPECT_NE(err.find((l.cfg / missing).string()), std::string::npos)
          << daemon << " " << file << ": " << err;
      EXPECT_NE(err.find("in ../cfg/" + file + ")"), std::string::npos)
          << daemon << " " << file << ": " << err;
    }
  }
}

TEST(ConfigPaths, ARigNamedInTheConfigIsRead) {
  const Layout l("rig_in_config");
  l.write("lab.json", "{}");
  l.write("lab.toml", "rig = \"lab.json\"\nduration = 0.5\nlisten = \"127.0.0.1:0\"\n");
  test::Process p =
      start_in(l.elsewhere, "telex-remote", {"--config", "../cfg/lab.toml"}, l.dir, "remote");
  ASSERT_EQ(p.wait(30s).value_or(-1), 0) << p.stderr_text();
  EXPECT_NE(p.stderr_text().find("rig " + (l.cfg / "lab.json").string() + ":"), std::string::npos)
      << p.stderr_text();
}

}  // namespace
}  // namespace telex
