// SPDX-License-Identifier: MIT
// The head's limits, the --head spec, the driver factory, `none`, and the udp datagram's bytes.
#include "telex/remote/head.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "head_impl.h"
#include "telex/base/byte_cursor.h"

namespace telex::remote {

const char* head_joint_name(std::size_t joint) {
  static constexpr const char* kNames[kHeadJoints] = {"yaw", "pitch", "roll"};
  return joint < kHeadJoints ? kNames[joint] : "?";
}

void HeadLimits::validate() const {
  for (std::size_t j = 0; j < kHeadJoints; ++j) {
    const HeadJointLimits& l = joint[j];
    const std::string name = std::string("head ") + head_joint_name(j);
    if (!std::isfinite(l.min_rad) || !std::isfinite(l.max_rad) ||
        !std::isfinite(l.max_rate_rad_s) || !std::isfinite(l.max_accel_rad_s2))
      throw std::invalid_argument(name + ": limits must be finite numbers");
    if (!(l.min_rad < l.max_rad))
      throw std::invalid_argument(name + ": min_rad " + std::to_string(l.min_rad) +
                                  " must be below max_rad " + std::to_string(l.max_rad));
    if (l.min_rad < -std::numbers::pi || l.max_rad > std::numbers::pi)
      throw std::invalid_argument(name + ": limits " + std::to_string(l.min_rad) + ".." +
                                  std::to_string(l.max_rad) +
                                  " rad leave one servo turn (-pi..pi)");
    if (!(l.max_rate_rad_s > 0))
      throw std::invalid_argument(name + ": max_rate_rad_s " + std::to_string(l.max_rate_rad_s) +
                                  " must be above 0");
    if (!(l.max_accel_rad_s2 > 0))
      throw std::invalid_argument(name + ": max_accel_rad_s2 " +
                                  std::to_string(l.max_accel_rad_s2) + " must be above 0");
  }
}

std::size_t clamp_to_limits(HeadAngles& angles_rad, const HeadLimits& limits) {
  std::size_t clamped = 0;
  for (std::size_t j = 0; j < kHeadJoints; ++j) {
    const double v = std::clamp(angles_rad[j], limits.joint[j].min_rad, limits.joint[j].max_rad);
    if (v != angles_rad[j]) ++clamped;
    angles_rad[j] = v;
  }
  return clamped;
}

namespace {

std::vector<std::string> split(std::string_view text, char sep) {
  std::vector<std::string> out;
  std::size_t start = 0;
  while (true) {
    const std::size_t at = text.find(sep, start);
    out.emplace_back(text.substr(start, at == std::string_view::npos ? at : at - start));
    if (at == std::string_view::npos) return out;
    start = at + 1;
  }
}

std::optional<long long> to_integer(std::string_view s) {
  long long v = 0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (s.empty() || ec != std::errc() || end != s.data() + s.size()) return std::nullopt;
  return v;
}

std::optional<double> to_number(const std::string& s) {
  try {
    std::size_t used = 0;
    const double v = std::stod(s, &used);
    if (used != s.size() || !std::isfinite(v)) return std::nullopt;
    return v;
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

}  // namespace

HeadSpec parse_head_spec(std::string_view text) {
  const std::string spec(text);
  const auto bad = [&](const std::string& why) {
    return std::invalid_argument("--head '" + spec + "': " + why +
                                 " (valid: " + std::string(kHeadSpecForms) + ")");
  };
  const std::size_t kind_end = std::min(text.find(':'), text.find(','));
  const std::string kind(text.substr(0, kind_end));
  const bool has_arg = kind_end != std::string_view::npos && text[kind_end] == ':';
  const std::string_view rest =
      kind_end == std::string_view::npos ? std::string_view{} : text.substr(kind_end + 1);
  HeadSpec s;
  if (kind == "none") {
    if (kind_end != std::string_view::npos) throw bad("'none' takes nothing after it");
    s.kind = HeadSpec::Kind::None;
    return s;
  }
  if (kind == "sim") {
    if (has_arg) throw bad("'sim' takes no ':' argument, only ',tau_ms=MS'");
    s.kind = HeadSpec::Kind::Sim;
    if (kind_end == std::string_view::npos) return s;
    for (const std::string& token : split(rest, ',')) {
      if (token.rfind("tau_ms=", 0) != 0) throw bad("unknown sim option '" + token + "'");
      const auto ms = to_number(token.substr(7));
      if (!ms || *ms <= 0 || *ms > 10000)
        throw bad("tau_ms '" + token.substr(7) + "' is not a time constant in (0, 10000] ms");
      s.sim_tau_s = *ms / 1000.0;
    }
    return s;
  }
  if (kind == "dynamixel") {
    if (!has_arg) throw bad("dynamixel needs the serial port: dynamixel:/dev/ttyUSB0");
    s.kind = HeadSpec::Kind::Dynamixel;
    const std::vector<std::string> tokens = split(rest, ',');
    s.device = tokens[0];
    if (s.device.empty()) throw bad("the serial port is empty");
    std::vector<long long> ids;
    bool in_ids = false, ids_given = false;
    for (std::size_t i = 1; i < tokens.size(); ++i) {
      const std::string& t = tokens[i];
      if (t.rfind("ids=", 0) == 0) {
        if (ids_given) throw bad("ids= is given twice");
        ids_given = in_ids = true;
        const auto id = to_integer(std::string_view(t).substr(4));
        if (!id) throw bad("servo id '" + t.substr(4) + "' is not a number");
        ids.push_back(*id);
      } else if (in_ids && to_integer(t)) {
        ids.push_back(*to_integer(t));
      } else if (t.rfind("baud=", 0) == 0) {
        in_ids = false;
        const auto baud = to_integer(std::string_view(t).substr(5));
        if (!baud || std::find(kDynamixelBauds.begin(), kDynamixelBauds.end(), *baud) ==
                         kDynamixelBauds.end()) {
          std::string valid;
          for (const int b : kDynamixelBauds)
            valid += (valid.empty() ? "" : ", ") + std::to_string(b);
          throw bad("baud '" + t.substr(5) + "' is not one of " + valid);
        }
        s.baud = static_cast<int>(*baud);
      } else {
        throw bad("unknown dynamixel option '" + t + "'");
      }
    }
    if (ids_given) {
      if (ids.size() != kHeadJoints)
        throw bad("ids= needs three servo ids (yaw, pitch, roll), got " +
                  std::to_string(ids.size()));
      for (std::size_t j = 0; j < kHeadJoints; ++j) {
        if (ids[j] < 0 || ids[j] > 252)
          throw bad("servo id " + std::to_string(ids[j]) + " is outside 0..252");
        for (std::size_t k = 0; k < j; ++k)
          if (ids[k] == ids[j]) throw bad("servo id " + std::to_string(ids[j]) + " is given twice");
        s.ids[j] = static_cast<std::uint8_t>(ids[j]);
      }
    }
    return s;
  }
  if (kind == "udp") {
    if (!has_arg) throw bad("udp needs the head controller's address: udp:HOST:PORT");
    s.kind = HeadSpec::Kind::Udp;
    if (rest.find(',') != std::string_view::npos) throw bad("udp takes no options");
    const std::size_t colon = rest.rfind(':');
    if (colon == std::string_view::npos || colon == 0) throw bad("udp needs HOST:PORT");
    s.host = std::string(rest.substr(0, colon));
    if (s.host.size() > 2 && s.host.front() == '[' && s.host.back() == ']')
      s.host = s.host.substr(1, s.host.size() - 2);  // [::1]
    const auto port = to_integer(rest.substr(colon + 1));
    if (!port || *port < 1 || *port > 65535)
      throw bad("port '" + std::string(rest.substr(colon + 1)) + "' is not 1..65535");
    s.port = static_cast<std::uint16_t>(*port);
    return s;
  }
  throw bad("unknown head kind '" + kind + "'");
}

namespace {

// --head none: no head. Commands go nowhere; measured() is never valid, so the station keeps
// using the operator's own head pose.
class NoHead final : public HeadDriver {
 public:
  void command(const HeadAngles&, std::int64_t) override {}
  HeadPose measured(std::int64_t now_ns) override {
    ++stats_.reads;
    HeadPose p;
    p.time_ns = now_ns;
    return p;
  }
  std::string name() const override { return "none"; }
  HeadStats stats() const override { return stats_; }

 private:
  HeadStats stats_;
};

}  // namespace

namespace detail {
std::unique_ptr<HeadDriver> make_no_head() { return std::make_unique<NoHead>(); }
}  // namespace detail

std::unique_ptr<HeadDriver> make_head_driver(std::string_view spec, const HeadLimits& limits) {
  const HeadSpec s = parse_head_spec(spec);
  limits.validate();
  switch (s.kind) {
    case HeadSpec::Kind::None:
      return detail::make_no_head();
    case HeadSpec::Kind::Sim:
      return detail::make_sim_head(s, limits);
    case HeadSpec::Kind::Dynamixel:
      return detail::make_dynamixel_head(s, limits);
    case HeadSpec::Kind::Udp:
      return detail::make_udp_head(s, limits);
  }
  throw std::invalid_argument("--head: unknown kind");
}

std::vector<std::uint8_t> encode_head_datagram(const HeadDatagram& d) {
  std::vector<std::uint8_t> out;
  out.reserve(kHeadDatagramBytes);
  ByteWriter w(out);
  w.u32(kHeadDatagramMagic);
  w.u32(d.sequence);
  w.put(d.time_ns);
  for (const double a : d.joint_rad) w.f64(a);
  return out;
}

std::optional<HeadDatagram> decode_head_datagram(std::span<const std::uint8_t> bytes) {
  if (bytes.size() != kHeadDatagramBytes) return std::nullopt;
  ByteReader r(bytes);
  if (r.u32() != kHeadDatagramMagic) return std::nullopt;
  HeadDatagram d;
  d.sequence = r.u32();
  d.time_ns = r.read<std::int64_t>();
  for (double& a : d.joint_rad) {
    a = r.f64();
    if (!std::isfinite(a)) return std::nullopt;
  }
  return r.ok() ? std::optional<HeadDatagram>(d) : std::nullopt;
}

HeadLimits head_limits_from(const RobotHead& head) {
  HeadLimits l;
  for (std::size_t j = 0; j < kHeadJoints; ++j)
    l.joint[j] = {head.joints[j].min_rad, head.joints[j].max_rad, head.joints[j].max_rate_rad_s,
                  head.joints[j].max_accel_rad_s2};
  return l;
}

}  // namespace telex::remote
