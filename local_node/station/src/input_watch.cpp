// SPDX-License-Identifier: MIT
// The tracker's inputs watched for silence.
#include "input_watch.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

namespace telex::local {
namespace {

double seconds(std::int64_t ns) { return static_cast<double>(ns) / 1e9; }

}  // namespace

void InputWatch::update(std::int64_t now_ns, const std::vector<TrackerInput>& inputs) {
  if (watched_.size() != inputs.size()) {
    watched_.assign(inputs.size(), Watched{});
    for (std::size_t i = 0; i < inputs.size(); ++i) watched_[i] = {inputs[i], now_ns, false};
    return;
  }
  for (std::size_t i = 0; i < inputs.size(); ++i) {
    Watched& w = watched_[i];
    if (inputs[i].frames != w.input.frames) {
      if (w.silent)
        spdlog::info("{} again, after {:.0f} s without", inputs[i].what,
                     seconds(now_ns - w.since_ns));
      w.silent = false;
      w.since_ns = now_ns;
    } else if (!w.silent && now_ns - w.since_ns >= kSilentAfterNs) {
      w.silent = true;
      spdlog::warn("no {} for {:.0f} s{}: {}", inputs[i].what, seconds(now_ns - w.since_ns),
                   inputs[i].frames == 0 ? " (none since the start)" : "", inputs[i].check);
    }
    w.input = inputs[i];
  }
}

std::string InputWatch::status(std::int64_t now_ns) const {
  std::string text;
  for (const Watched& w : watched_)
    if (w.silent)
      text += fmt::format(" | no {} for {:.0f} s", w.input.what, seconds(now_ns - w.since_ns));
  return text;
}

std::string InputWatch::summary(std::int64_t now_ns) const {
  std::string text;
  for (const Watched& w : watched_) {
    if (!w.silent) continue;
    text += text.empty() ? "" : "; ";
    text += w.input.frames == 0
                ? fmt::format("no {} in the whole run: {}", w.input.what, w.input.check)
                : fmt::format("no {} for the last {:.0f} s of the run: {}", w.input.what,
                              seconds(now_ns - w.since_ns), w.input.check);
  }
  return text;
}

}  // namespace telex::local
