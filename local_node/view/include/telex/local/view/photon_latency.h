// SPDX-License-Identifier: MIT
// Latency a person notices: motion to photon (the body or head sample a view frame drew, to that
// frame handed to the display) and capture to photon (the eyes' video it drew, to the same moment).
#pragma once

#include <cstddef>
#include <cstdint>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

namespace telex::local {

// What one view frame drew, stamped where it came from.
struct PhotonStamps {
  // When the body (or head) pose drawn was sampled, CLOCK_MONOTONIC ns (HandState::motion_ns);
  // 0: no pose drawn, or a tracker that does not know.
  std::int64_t motion_ns = 0;
  // When the eyes' pair drawn was captured, on the remote's clock (EyePair::capture_ns); 0: none.
  std::int64_t capture_ns_remote = 0;
};

// The samples of one run, fed by whichever thread hands frames to the display (the view thread
// for PNGs and OpenXR, the main thread for a window) and read by the main thread.
class PhotonLatency {
 public:
  // A frame handed to the display at `photon_ns` (CLOCK_MONOTONIC). `clock_offset_ns` is the
  // remote's clock less this one (the heartbeat's estimate): it takes the photon time to the
  // remote's clock, where the capture time is.
  void record(const PhotonStamps& s, std::int64_t photon_ns, std::int64_t clock_offset_ns);

  struct Figures {
    std::uint64_t samples = 0;
    double median_ms = 0, p99_ms = 0;
  };
  Figures motion() const;   // over the run
  Figures capture() const;  // over the run
  // The medians of the newest kRecent samples, for the status line; none before the first.
  struct Recent {
    std::optional<double> motion_ms, capture_ms;
  };
  Recent recent() const;

  static constexpr std::size_t kRecent = 64;
  static constexpr std::size_t kMaxSamples = std::size_t{1} << 20;  // a run's, then not kept

 private:
  struct Series {
    std::vector<double> all_ms;     // at most kMaxSamples
    std::vector<double> recent_ms;  // a ring of at most kRecent
    std::size_t next = 0;           // where the ring writes next once full
    void add(double ms);
    Figures figures() const;
    std::optional<double> recent_median() const;
  };
  mutable std::mutex mu_;
  Series motion_, capture_;  // guarded by mu_
};

// The status line's part: " | to photon: motion 23 ms, video 61 ms" with what is known; empty
// before either. `to_png`: the frames went to PNG files (--view png), which the view writes once
// a status line, not to a display: " | to the PNGs: ...", so it is not read as a display's.
std::string photon_status(const PhotonLatency::Recent& r, bool to_png = false);

}  // namespace telex::local
