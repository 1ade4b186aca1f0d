// SPDX-License-Identifier: MIT
// Every shell block that README.md and docs/*.md mark with `<!-- doc-test: seconds=S [press=N] -->`
// runs as written (issue 50): in a scratch folder with `build` and `tools` linked in, the docs'
// port 7300 swapped for a free one, bounded by S seconds; it must exit 0, and with press=N the
// station's peak pressure must reach N newtons. Blocks that need hardware carry no mark.
#include <gtest/gtest.h>
#include <signal.h>

#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "process.h"
#include "test_support.h"

namespace telex::test {
namespace {

using namespace std::chrono_literals;

struct DocBlock {
  std::string file;  // relative to the source tree
  int line = 0;      // of the mark
  double seconds = 60;
  double press_N = 0;  // 0: no force asked for
  std::string text;
};

std::vector<DocBlock> marked_blocks() {
  const std::filesystem::path src = TELEX_SOURCE_DIR;
  std::vector<std::filesystem::path> files{src / "README.md"};
  for (const auto& e : std::filesystem::directory_iterator(src / "docs"))
    if (e.path().extension() == ".md") files.push_back(e.path());
  std::sort(files.begin() + 1, files.end());
  const std::regex mark(R"(^<!-- doc-test:(.*)-->\s*$)");
  std::vector<DocBlock> out;
  for (const auto& f : files) {
    std::ifstream in(f);
    std::string line;
    int n = 0;
    while (std::getline(in, line)) {
      ++n;
      std::smatch m;
      if (!std::regex_match(line, m, mark)) continue;
      DocBlock b;
      b.file = std::filesystem::relative(f, src).string();
      b.line = n;
      std::istringstream words(m[1].str());
      for (std::string w; words >> w;) {
        if (w.rfind("seconds=", 0) == 0) b.seconds = std::stod(w.substr(8));
        if (w.rfind("press=", 0) == 0) b.press_N = std::stod(w.substr(6));
      }
      std::getline(in, line);
      ++n;
      if (line.rfind("```", 0) != 0) {
        b.text = "";  // a mark not followed by a block: the test says so
        out.push_back(b);
        continue;
      }
      while (std::getline(in, line) && line.rfind("```", 0) != 0) {
        ++n;
        b.text += line + "\n";
      }
      ++n;
      out.push_back(b);
    }
  }
  return out;
}

std::string replace_all(std::string s, const std::string& from, const std::string& to) {
  for (auto at = s.find(from); at != std::string::npos; at = s.find(from, at + to.size()))
    s.replace(at, from.size(), to);
  return s;
}

class DocCommands : public ::testing::TestWithParam<DocBlock> {};

TEST_P(DocCommands, RunsAsWrittenAndTouches) {
  const DocBlock& b = GetParam();
  ASSERT_FALSE(b.text.empty()) << b.file << ":" << b.line << ": a doc-test mark with no block";
  if (b.text.find("../shared") != std::string::npos) TELEX_REQUIRE_REAL_DATA();
  TELEX_REQUIRE_BINARIES("telex", "telex-remote", "telex-local");
  const auto dir = scratch_dir("doc_block");
  const std::filesystem::path build = built_binary("telex").parent_path().parent_path();
  std::filesystem::create_directory_symlink(build, dir / "build");
  std::filesystem::create_directory_symlink(std::filesystem::path(TELEX_SOURCE_DIR) / "tools",
                                            dir / "tools");
  std::string text = replace_all(b.text, ":7300", ":" + std::to_string(free_port()));
  text = replace_all(text, "../shared", TELEX_SHARED_DIR);
  {
    std::ofstream sh(dir / "block.sh");
    sh << "set -e\ncd " << dir.string() << "\n" << text;
  }
  Process p({"/bin/bash", (dir / "block.sh").string()}, dir / "out.txt", dir / "err.txt");
  const auto rc = p.wait(std::chrono::milliseconds(static_cast<long>(b.seconds * 1000)));
  const std::string said = p.stdout_text() + p.stderr_text();
  ASSERT_TRUE(rc.has_value()) << b.file << ":" << b.line << " still running after " << b.seconds
                              << " s\n"
                              << said;
  EXPECT_EQ(*rc, 0) << b.file << ":" << b.line << "\n" << text << "\n" << said;
  if (b.press_N > 0) {
    const std::regex peak(R"(peak pressure ([0-9.]+) N)");
    double most = -1;
    for (auto it = std::sregex_iterator(said.begin(), said.end(), peak);
         it != std::sregex_iterator(); ++it)
      most = std::max(most, std::stod((*it)[1].str()));
    EXPECT_GE(most, b.press_N) << b.file << ":" << b.line << ": the station's peak pressure\n"
                               << said;
    std::printf("%s:%d: peak pressure %.2f N (at least %.2f asked)\n", b.file.c_str(), b.line, most,
                b.press_N);
  }
}

std::string block_name(const ::testing::TestParamInfo<DocBlock>& info) {
  std::string s = info.param.file + "_" + std::to_string(info.param.line);
  for (char& c : s)
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  return s;
}

INSTANTIATE_TEST_SUITE_P(Marked, DocCommands, ::testing::ValuesIn(marked_blocks()), block_name);

// The marks themselves: the README's running example, the recording example and the calibration
// by hand are marked, so deleting a mark cannot silently drop a block from the suite.
TEST(DocCommandsMarks, TheExamplesAreMarked) {
  std::vector<std::string> where;
  for (const auto& b : marked_blocks()) where.push_back(b.file);
  for (const char* f : {"README.md", "docs/RECORDING.md", "docs/RIG.md"})
    EXPECT_NE(std::find(where.begin(), where.end(), f), where.end())
        << f << " has no doc-test mark";
}

}  // namespace
}  // namespace telex::test
