// SPDX-License-Identifier: MIT
// Arm segment lengths from a T-pose and glove sensor ranges from a flat hand and a fist.
#include "telex/calib/operator.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <stdexcept>
#include <string_view>

#include "csv_cells.h"

namespace telex::calib {
namespace {

using detail::split_csv;
using detail::to_double;

constexpr double kDeg = 180.0 / 3.14159265358979323846;

// "{}" and "{:.Nf}" placeholders, in order (the calib library does not link fmt).
void append_formatted(std::ostringstream& os, std::string_view f) { os << f; }

template <typename T, typename... Rest>
void append_formatted(std::ostringstream& os, std::string_view f, const T& v, const Rest&... rest) {
  const auto open = f.find('{');
  const auto close = f.find('}', open);
  os << f.substr(0, open);
  const std::string_view spec = f.substr(open + 1, close - open - 1);
  if (spec.size() == 4 && spec[0] == ':' && spec[1] == '.' && spec[3] == 'f')
    os << std::fixed << std::setprecision(spec[2] - '0') << v << std::defaultfloat;
  else
    os << v;
  append_formatted(os, f.substr(close + 1), rest...);
}

template <typename... Args>
std::string format(std::string_view f, const Args&... args) {
  std::ostringstream os;
  append_formatted(os, f, args...);
  return os.str();
}

// Linear interpolation between order statistics (numpy's default); `v` not empty.
double percentile(std::vector<double> v, double pct) {
  std::sort(v.begin(), v.end());
  const double pos = std::clamp(pct, 0.0, 100.0) / 100.0 * static_cast<double>(v.size() - 1);
  const auto lo = static_cast<std::size_t>(std::floor(pos));
  const std::size_t hi = std::min(lo + 1, v.size() - 1);
  return v[lo] + (pos - static_cast<double>(lo)) * (v[hi] - v[lo]);
}

double angle_rad(const glm::dvec3& a, const glm::dvec3& b) {
  const double c = glm::dot(a, b) / (glm::length(a) * glm::length(b));
  return std::acos(std::clamp(c, -1.0, 1.0));
}

}  // namespace

std::vector<TrackingFrame> load_tracking_csv(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("tracking CSV " + path.string() + ": cannot open");
  auto fail = [&](int line_no, const std::string& what) {
    return std::runtime_error(format("tracking CSV {} line {}: {}", path.string(), line_no, what));
  };
  std::vector<TrackingFrame> frames;
  std::string line;
  int line_no = 0;
  int valid_col = -1;
  std::size_t columns = 0;
  bool header = false;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.empty() || line == "\r" || line[0] == '#') continue;
    const auto cells = split_csv(line);
    if (!header) {
      // Both recorders' headers: time_s,body_id then x_m.. (station) or x.. (NatNet recording).
      if (cells.size() < 5 || cells[0] != "time_s" || cells[1] != "body_id" ||
          (cells[2] != "x_m" && cells[2] != "x"))
        throw fail(line_no,
                   "expected a header time_s,body_id,x_m,y_m,z_m,... (--log-tracking) or "
                   "time_s,body_id,x,y,z,... (a NatNet recording)");
      for (std::size_t i = 0; i < cells.size(); ++i)
        if (cells[i] == "valid") valid_col = static_cast<int>(i);
      columns = cells.size();
      header = true;
      continue;
    }
    if (cells.size() != columns)
      throw fail(line_no, format("{} columns, the header has {}", cells.size(), columns));
    double t = 0, id = 0, x = 0, y = 0, z = 0;
    if (!to_double(cells[0], t) || !to_double(cells[1], id) || !to_double(cells[2], x) ||
        !to_double(cells[3], y) || !to_double(cells[4], z) || id != std::floor(id))
      throw fail(line_no, "time_s, body_id (an integer), x, y, z must be numbers");
    if (valid_col >= 0) {
      double v = 0;
      if (!to_double(cells[static_cast<std::size_t>(valid_col)], v))
        throw fail(line_no, "valid must be 0 or 1");
      if (v == 0.0) continue;
    }
    if (!frames.empty() && t < frames.back().t_s) throw fail(line_no, "time_s goes backward");
    if (frames.empty() || t != frames.back().t_s) frames.push_back({t, {}});
    frames.back().p_World_m[static_cast<int>(id)] = {x, y, z};
  }
  if (!header) throw std::runtime_error("tracking CSV " + path.string() + ": empty");
  return frames;
}

ArmCalibration calibrate_arm(const std::vector<TrackingFrame>& frames, const ArmBodies& bodies,
                             const std::string& side, const BodyCalibOptions& o) {
  if (bodies.shoulder < 0 || bodies.wrist < 0)
    throw std::invalid_argument(side + " arm: needs a shoulder and a wrist body id");
  const bool elbow = bodies.elbow >= 0;
  const bool line = bodies.other_shoulder >= 0;
  std::vector<double> reach, upper, fore, bend, off_line;
  for (const TrackingFrame& f : frames) {
    const auto s = f.p_World_m.find(bodies.shoulder);
    const auto w = f.p_World_m.find(bodies.wrist);
    if (s == f.p_World_m.end() || w == f.p_World_m.end()) continue;
    const glm::dvec3 p_s = s->second, p_w = w->second;
    glm::dvec3 p_e{0.0};
    if (elbow) {
      const auto e = f.p_World_m.find(bodies.elbow);
      if (e == f.p_World_m.end()) continue;
      p_e = e->second;
    }
    if (line) {
      const auto o2 = f.p_World_m.find(bodies.other_shoulder);
      if (o2 == f.p_World_m.end()) continue;
      off_line.push_back(angle_rad(p_w - p_s, p_s - o2->second));
    }
    reach.push_back(glm::length(p_w - p_s));
    if (elbow) {
      upper.push_back(glm::length(p_e - p_s));
      fore.push_back(glm::length(p_w - p_e));
      bend.push_back(3.14159265358979323846 - angle_rad(p_s - p_e, p_w - p_e));
    }
  }
  const std::string needed =
      format("shoulder {}, wrist {}{}{}", bodies.shoulder, bodies.wrist,
             elbow ? format(", elbow {}", bodies.elbow) : "",
             line ? format(", other shoulder {}", bodies.other_shoulder) : "");
  if (static_cast<int>(reach.size()) < o.min_samples)
    throw CalibrationError(format(
        "{} arm: only {} of {} frames have every body valid ({}); at least {} are needed (is "
        "every body tracked? check the body ids)",
        side, reach.size(), frames.size(), needed, o.min_samples));
  ArmCalibration a;
  a.side = side;
  a.samples = static_cast<int>(reach.size());
  a.reach_m = percentile(reach, 50.0);
  a.spread_m = percentile(reach, 90.0) - percentile(reach, 10.0);
  if (a.spread_m > o.max_spread_m)
    throw CalibrationError(format(
        "{} arm: the shoulder-to-wrist distance spreads {:.1f} mm over the capture (10th-90th "
        "percentile; at most {:.1f} mm): hold the T-pose still with the arm straight",
        side, a.spread_m * 1e3, o.max_spread_m * 1e3));
  if (elbow) {
    const double b = percentile(bend, 50.0);
    if (b > o.max_elbow_bend_rad)
      throw CalibrationError(
          format("{} arm: the elbow is bent {:.1f} deg (median; at most {:.1f}): straighten "
                 "the arm in the T-pose",
                 side, b * kDeg, o.max_elbow_bend_rad * kDeg));
  }
  if (line) {
    const double off = percentile(off_line, 50.0);
    if (off > o.max_off_line_rad)
      throw CalibrationError(format(
          "{} arm: the wrist is {:.1f} deg off the shoulder line (median; at most {:.1f}): in a "
          "T-pose the straight arm continues the line through both shoulders",
          side, off * kDeg, o.max_off_line_rad * kDeg));
  }
  if (elbow) {
    a.from_elbow = true;
    a.upper_arm_m = percentile(upper, 50.0);
    a.forearm_m = percentile(fore, 50.0);
  } else {
    a.upper_arm_m = a.reach_m * kUpperArmFraction;
    a.forearm_m = a.reach_m - a.upper_arm_m;
  }
  return a;
}

GloveCapture load_glove_csv(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("glove CSV " + path.string() + ": cannot open");
  GloveCapture c;
  std::string line;
  int line_no = 0;
  bool first = true;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.empty() || line == "\r" || line[0] == '#') continue;
    const auto cells = split_csv(line);
    double t = 0;
    if (first && !to_double(cells[0], t)) {  // a header
      first = false;
      continue;
    }
    first = false;
    const int n = static_cast<int>(cells.size()) - 1;
    if (c.sensor_count == 0) {
      if (n != 5 && n != 14)
        throw std::runtime_error(
            format("glove CSV {} line {}: time_s and 5 or 14 sensor values expected, got {} values",
                   path.string(), line_no, n));
      c.sensor_count = n;
    } else if (n != c.sensor_count) {
      throw std::runtime_error(format("glove CSV {} line {}: {} sensor values, earlier rows {}",
                                      path.string(), line_no, n, c.sensor_count));
    }
    std::array<double, 14> row{};
    for (int i = 0; i <= n; ++i) {
      double v = 0;
      if (!to_double(cells[static_cast<std::size_t>(i)], v))
        throw std::runtime_error(format("glove CSV {} line {}: column {} '{}' is not a number",
                                        path.string(), line_no, i + 1,
                                        cells[static_cast<std::size_t>(i)]));
      if (i > 0) row[static_cast<std::size_t>(i - 1)] = v;
    }
    c.rows.push_back(row);
  }
  if (c.rows.empty()) throw std::runtime_error("glove CSV " + path.string() + ": no rows");
  return c;
}

std::string glove_sensor_name(int sensor_count, int index) {
  static const char* kFingers[5] = {"thumb", "index", "middle", "ring", "little"};
  if (sensor_count == 5) return kFingers[index];
  const int f = index / 3;
  switch (index % 3) {
    case 0:
      return format("{} near knuckle", kFingers[f]);
    case 1:
      return format("{} far knuckle", kFingers[f]);
    default:
      return format("{}-{} abduction", kFingers[f], kFingers[f + 1]);
  }
}

bool glove_sensor_used(int sensor_count, int index) { return sensor_count == 5 || index % 3 != 2; }

GloveCalibResult calibrate_glove(const GloveCapture& flat, const GloveCapture& fist,
                                 const GloveCalibOptions& o) {
  if (flat.sensor_count != fist.sensor_count)
    throw CalibrationError(format("the flat hand has {} sensors but the fist {}", flat.sensor_count,
                                  fist.sensor_count));
  for (const auto& [c, what] : {std::pair{&flat, "flat hand"}, std::pair{&fist, "fist"}})
    if (static_cast<int>(c->rows.size()) < o.min_samples)
      throw CalibrationError(format("the {} has {} reports; at least {} are needed", what,
                                    c->rows.size(), o.min_samples));
  const int n = flat.sensor_count;
  GloveCalibResult r;
  std::vector<std::string> bad;
  for (int i = 0; i < n; ++i) {
    std::vector<double> f0, f1;
    for (const auto& row : flat.rows) f0.push_back(row[static_cast<std::size_t>(i)]);
    for (const auto& row : fist.rows) f1.push_back(row[static_cast<std::size_t>(i)]);
    const double lo = percentile(f0, o.low_percentile);
    const double hi = percentile(f1, o.high_percentile);
    const double min_range = o.min_range_fraction * o.full_scale;
    if (hi - lo >= min_range) {
      r.range.min.push_back(lo);
      r.range.max.push_back(hi);
    } else if (!glove_sensor_used(n, i)) {
      r.range.min.push_back(0.0);
      r.range.max.push_back(o.full_scale);
      r.full_range_sensors.push_back(i);
    } else {
      bad.push_back(
          format("sensor {} ({}): flat {:.3f}, fist {:.3f}", i, glove_sensor_name(n, i), lo, hi));
    }
  }
  if (!bad.empty()) {
    std::string list;
    for (const auto& b : bad) list += (list.empty() ? "" : "; ") + b;
    throw CalibrationError(format(
        "{} sensor{} moved less than {:.0f} % of full scale between the flat hand and the fist "
        "(unplugged, or the finger not bent?): {}",
        bad.size(), bad.size() == 1 ? "" : "s", o.min_range_fraction * 100.0, list));
  }
  return r;
}

}  // namespace telex::calib
