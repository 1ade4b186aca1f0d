// SPDX-License-Identifier: MIT
// Parses source spec strings and dispatches to the concrete sources.
#include <fmt/format.h>

#include <algorithm>
#include <stdexcept>

#include "source_impl.h"
#include "telex/remote/sources.h"

namespace telex::remote {

namespace {
constexpr std::string_view kDepthForms =
    "openni[:URI] | freenect[:INDEX] | oni:PATH[,loop][,realtime|fast] | "
    "files:PATTERN[,units=mm|tum|kinect-disparity][,fps=F][,loop] | "
    "bag:FILE[,topic=T][,info=T][,colour=T][,loop][,rate=R|fast] | "
    "synthetic[:SCENE][,animate][,noise=on|off]";
constexpr std::string_view kStereoForms =
    "v4l2:/dev/videoL,/dev/videoR[,size=WxH][,format=yuyv|mjpeg] | "
    "files:LEFT_PATTERN,RIGHT_PATTERN[,fps=F][,loop] | "
    "bag:FILE,colour=T[,loop][,rate=R|fast] | synthetic[:SCENE][,animate]";
}  // namespace

std::int64_t steady_now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

SourceSpec parse_source_spec(std::string_view spec) {
  if (spec.empty()) throw std::invalid_argument("source spec is empty");
  SourceSpec out;
  const auto colon = spec.find(':');
  const auto comma = spec.find(',');
  std::string_view rest;
  if (colon != std::string_view::npos && (comma == std::string_view::npos || colon < comma)) {
    out.kind = std::string(spec.substr(0, colon));
    rest = spec.substr(colon + 1);
    const auto first_comma = rest.find(',');
    out.arg = std::string(rest.substr(0, first_comma));
    rest =
        first_comma == std::string_view::npos ? std::string_view{} : rest.substr(first_comma + 1);
  } else {
    out.kind = std::string(spec.substr(0, comma));
    rest = comma == std::string_view::npos ? std::string_view{} : spec.substr(comma + 1);
  }
  if (out.kind.empty())
    throw std::invalid_argument(fmt::format("source spec '{}' has no kind before ':'", spec));
  while (!rest.empty()) {
    const auto next = rest.find(',');
    const std::string_view token = rest.substr(0, next);
    rest = next == std::string_view::npos ? std::string_view{} : rest.substr(next + 1);
    if (token.empty())
      throw std::invalid_argument(fmt::format("source spec '{}' has an empty option", spec));
    const auto eq = token.find('=');
    if (eq == std::string_view::npos) {
      out.flags.emplace_back(token);
      out.options[std::string(token)] = "";
    } else {
      if (eq == 0)
        throw std::invalid_argument(
            fmt::format("source spec '{}': option '{}' has no name", spec, token));
      out.options[std::string(token.substr(0, eq))] = std::string(token.substr(eq + 1));
    }
  }
  return out;
}

namespace detail {
void require_options(const SourceSpec& spec, std::initializer_list<std::string_view> allowed) {
  for (const auto& [key, value] : spec.options) {
    if (std::find(allowed.begin(), allowed.end(), key) == allowed.end()) {
      std::string list;
      for (auto a : allowed) list += fmt::format("{}{}", list.empty() ? "" : ", ", a);
      throw std::invalid_argument(fmt::format("source '{}': unknown option '{}' (valid: {})",
                                              spec.kind, key, list.empty() ? "none" : list));
    }
  }
}
}  // namespace detail

std::unique_ptr<DepthSource> make_depth_source(std::string_view spec_text,
                                               const SourceOptions& options) {
  const SourceSpec spec = parse_source_spec(spec_text);
  if (spec.kind == "openni") return detail::make_openni_source(spec, options);
  if (spec.kind == "freenect") return detail::make_freenect_source(spec, options);
  if (spec.kind == "oni") return detail::make_oni_source(spec, options);
  if (spec.kind == "files") return detail::make_files_depth_source(spec, options);
  if (spec.kind == "bag") return detail::make_bag_depth_source(spec, options);
  if (spec.kind == "synthetic") return detail::make_synthetic_depth_source(spec, options);
  throw std::invalid_argument(fmt::format("unknown depth source '{}' in '{}'; valid: {}", spec.kind,
                                          spec_text, kDepthForms));
}

std::unique_ptr<StereoSource> make_stereo_source(std::string_view spec_text,
                                                 const SourceOptions& options) {
  const SourceSpec spec = parse_source_spec(spec_text);
  if (spec.kind == "v4l2") return detail::make_v4l2_stereo_source(spec, options);
  if (spec.kind == "files") return detail::make_files_stereo_source(spec, options);
  if (spec.kind == "bag") return detail::make_bag_colour_source(spec, options);
  if (spec.kind == "synthetic") return detail::make_synthetic_stereo_source(spec, options);
  throw std::invalid_argument(fmt::format("unknown stereo source '{}' in '{}'; valid: {}",
                                          spec.kind, spec_text, kStereoForms));
}

std::unique_ptr<StereoSource> make_eye_source(std::string_view depth_spec,
                                              std::string_view stereo_spec,
                                              const SourceOptions& options) {
  if (!stereo_spec.empty()) return make_stereo_source(stereo_spec, options);
  if (const auto spec = parse_source_spec(depth_spec); spec.kind == "bag" && spec.has("colour"))
    return make_stereo_source(depth_spec, options);
  return nullptr;
}

}  // namespace telex::remote
