// SPDX-License-Identifier: MIT
// The haptic displays by spec (display_registry.h).
#include "telex/local/displays/display_registry.h"

#include <stdexcept>

#include "sim_display.h"
#include "telex/local/displays/gravity_grabber.h"
#include "telex/local/displays/udp_sink.h"

namespace telex::local {

std::unique_ptr<HapticDisplay> make_display(const std::string& spec, const DisplayConfig& config) {
  const DisplaySpec d = parse_display_spec(spec, config);
  switch (d.kind) {
    case DisplaySpec::Kind::Sim:
      return open_sim_display(d.target, config.sim_ring_capacity);
    case DisplaySpec::Kind::GravityGrabber:
      return open_gravity_grabber(d.target, config.gravity_grabber_config_path,
                                  config.gravity_grabber);
    case DisplaySpec::Kind::Udp:
      return open_udp_sink(d.host, d.port);
  }
  throw std::logic_error("unreachable display kind");
}

}  // namespace telex::local
