// SPDX-License-Identifier: MIT
// Parses source spec strings and dispatches to the concrete sources.
#include <fmt/format.h>

#include <algorithm>
#include <iterator>
#include <stdexcept>
#include <string>
#include <vector>

#include "source_impl.h"
#include "telex/remote/sources.h"

namespace telex::remote {

void DepthSource::enable_ir(const IrOptions&) {
  throw std::invalid_argument(fmt::format(
      "--ir: source {} has no IR camera; the IR images come from a live sensor: openni:URI "
      "(PrimeSense/OpenNI2) or freenect:N (Kinect v1, or a fakenect recording)",
      describe()));
}

ReadResult<IrFrame> DepthSource::read_ir(std::chrono::milliseconds) {
  ReadResult<IrFrame> r;
  r.status = ReadStatus::Error;
  r.error = fmt::format("source {} captures no IR images", describe());
  return r;
}

namespace {

// The registry: one row per scheme, in the order --help lists them (as libcamera registers its
// pipeline handlers). A spec is split by parse_source_spec; each factory checks its own options
// and throws std::invalid_argument naming the bad one.
using DepthFactory = std::unique_ptr<DepthSource> (*)(const SourceSpec&, const SourceOptions&);
using StereoFactory = std::unique_ptr<StereoSource> (*)(const SourceSpec&, const SourceOptions&);

struct DepthEntry {
  SourceScheme scheme;
  DepthFactory make;
};
struct StereoEntry {
  SourceScheme scheme;
  StereoFactory make;
};

const DepthEntry kDepthSources[] = {
    {{"openni", "openni[:URI]", "a PrimeSense/OpenNI2 sensor (URI from `telex devices`)"},
     detail::make_openni_source},
    {{"freenect", "freenect[:INDEX]", "Kinect v1 by libfreenect; under fakenect a recording"},
     detail::make_freenect_source},
    {{"oni", "oni:PATH[,loop][,realtime|fast]", "an OpenNI .oni recording"},
     detail::make_oni_source},
    {{"files", "files:PATTERN[,units=mm|tum|kinect-disparity][,fps=F][,loop]",
      "depth images; without loop they play once, from the first station's connection"},
     detail::make_files_depth_source},
    {{"bag", "bag:FILE[,topic=T][,info=T][,colour=T][,loop][,rate=R|fast]",
      "a ROS 1 bag, 16UC1 or 32FC1 (colour=T is the eye view); without loop it plays once, "
      "from the first station's connection"},
     detail::make_bag_depth_source},
    {{"synthetic", "synthetic[:SCENE][,animate][,noise=on|off]", "the synthetic renderer"},
     detail::make_synthetic_depth_source},
};

const StereoEntry kStereoSources[] = {
    {{"v4l2", "v4l2:/dev/videoL,/dev/videoR[,size=WxH][,format=yuyv|mjpeg]", "two USB cameras"},
     detail::make_v4l2_stereo_source},
    {{"files", "files:LEFT_PATTERN,RIGHT_PATTERN[,fps=F][,loop]",
      "image pairs; without loop they play once, when the first station asks for video"},
     detail::make_files_stereo_source},
    {{"bag", "bag:FILE,colour=T[,loop][,rate=R|fast]",
      "a bag's colour topic for both eyes; without loop it plays once, when the first station "
      "asks for video"},
     detail::make_bag_colour_source},
    {{"synthetic", "synthetic[:SCENE][,animate]", "the synthetic renderer"},
     detail::make_synthetic_stereo_source},
};

template <typename Entries>
std::string forms_of(const Entries& table) {
  std::string out;
  for (const auto& e : table) out += fmt::format("{}{}", out.empty() ? "" : " | ", e.scheme.form);
  return out;
}

template <typename Entries>
std::string help_of(const Entries& table) {
  std::string out;
  for (const auto& e : table)
    out += fmt::format("{}{}: {}", out.empty() ? "" : " | ", e.scheme.form, e.scheme.help);
  return out;
}

template <typename Entries>
const auto* find_scheme(const Entries& table, std::string_view name) {
  for (const auto& e : table)
    if (e.scheme.name == name) return &e;
  return static_cast<decltype(&table[0])>(nullptr);
}

template <typename Entries>
std::string names_of(const Entries& table) {
  std::string out;
  for (const auto& e : table) out += fmt::format("{}{}", out.empty() ? "" : ", ", e.scheme.name);
  return out;
}

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

std::vector<SourceScheme> depth_source_schemes() {
  std::vector<SourceScheme> out;
  for (const auto& e : kDepthSources) out.push_back(e.scheme);
  return out;
}

std::vector<SourceScheme> stereo_source_schemes() {
  std::vector<SourceScheme> out;
  for (const auto& e : kStereoSources) out.push_back(e.scheme);
  return out;
}

std::string depth_source_help() { return help_of(kDepthSources); }
std::string stereo_source_help() { return help_of(kStereoSources); }

std::unique_ptr<DepthSource> make_depth_source(std::string_view spec_text,
                                               const SourceOptions& options) {
  const SourceSpec spec = parse_source_spec(spec_text);
  if (const auto* e = find_scheme(kDepthSources, spec.kind)) return e->make(spec, options);
  throw std::invalid_argument(
      fmt::format("unknown depth source '{}' in '{}'; valid sources: {} ({})", spec.kind, spec_text,
                  names_of(kDepthSources), forms_of(kDepthSources)));
}

std::unique_ptr<StereoSource> make_stereo_source(std::string_view spec_text,
                                                 const SourceOptions& options) {
  const SourceSpec spec = parse_source_spec(spec_text);
  if (const auto* e = find_scheme(kStereoSources, spec.kind)) return e->make(spec, options);
  throw std::invalid_argument(
      fmt::format("unknown stereo source '{}' in '{}'; valid sources: {} ({})", spec.kind,
                  spec_text, names_of(kStereoSources), forms_of(kStereoSources)));
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
