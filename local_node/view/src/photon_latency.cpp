// SPDX-License-Identifier: MIT
// Motion to photon and capture to photon: the samples and their percentiles.
#include "telex/local/view/photon_latency.h"

#include <fmt/format.h>

#include "telex/base/periodic.h"

namespace telex::local {

void PhotonLatency::Series::add(double ms) {
  if (all_ms.size() < kMaxSamples) all_ms.push_back(ms);
  if (recent_ms.size() < kRecent) {
    recent_ms.push_back(ms);
    return;
  }
  recent_ms[next] = ms;
  next = (next + 1) % kRecent;
}

PhotonLatency::Figures PhotonLatency::Series::figures() const {
  if (all_ms.empty()) return {};
  return {all_ms.size(), percentile(all_ms, 0.5), percentile(all_ms, 0.99)};
}

std::optional<double> PhotonLatency::Series::recent_median() const {
  if (recent_ms.empty()) return std::nullopt;
  return percentile(recent_ms, 0.5);
}

void PhotonLatency::record(const PhotonStamps& s, std::int64_t photon_ns,
                           std::int64_t clock_offset_ns) {
  std::lock_guard lock(mu_);
  if (s.motion_ns != 0) motion_.add(static_cast<double>(photon_ns - s.motion_ns) / 1e6);
  if (s.capture_ns_remote != 0)
    capture_.add(static_cast<double>(photon_ns + clock_offset_ns - s.capture_ns_remote) / 1e6);
}

PhotonLatency::Figures PhotonLatency::motion() const {
  std::lock_guard lock(mu_);
  return motion_.figures();
}

PhotonLatency::Figures PhotonLatency::capture() const {
  std::lock_guard lock(mu_);
  return capture_.figures();
}

PhotonLatency::Recent PhotonLatency::recent() const {
  std::lock_guard lock(mu_);
  return {motion_.recent_median(), capture_.recent_median()};
}

std::string photon_status(const PhotonLatency::Recent& r, bool to_png) {
  if (!r.motion_ms && !r.capture_ms) return {};
  std::string text = to_png ? " | to the PNGs:" : " | to photon:";
  if (r.motion_ms) text += fmt::format(" motion {:.0f} ms", *r.motion_ms);
  if (r.motion_ms && r.capture_ms) text += ",";
  if (r.capture_ms) text += fmt::format(" video {:.0f} ms", *r.capture_ms);
  return text;
}

}  // namespace telex::local
