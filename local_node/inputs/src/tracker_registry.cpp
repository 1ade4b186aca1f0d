// SPDX-License-Identifier: MIT
// The trackers by --hand spec (tracker_registry.h).
#include "telex/local/inputs/tracker_registry.h"

#include <algorithm>
#include <filesystem>
#include <stdexcept>

#include "device_trackers.h"
#include "telex/local/inputs/glove.h"
#include "telex/local/inputs/hand_script.h"
#include "telex/local/inputs/natnet_client.h"

namespace telex::local {

namespace {
const char* const kHandForms =
    "script:press|stroke|tap|FILE, natnet:SERVER_IP[,options], 5dt-usb[:HIDPATH], "
    "5dt-serial:DEV";
}  // namespace

void check_hand_spec(const std::string& spec) {
  if (spec.rfind("script:", 0) == 0) {
    const std::string what = spec.substr(7);
    const auto names = HandScript::builtin_names();
    if (std::find(names.begin(), names.end(), what) != names.end()) return;
    if (what.empty())
      throw std::invalid_argument("tracker spec 'script:' needs press, stroke, tap or a file");
    if (!std::filesystem::exists(what))
      throw std::invalid_argument("tracker spec '" + spec + "': no built-in script and no file " +
                                  what + " (built-in: press, stroke, tap)");
    return;
  }
  if (spec.rfind("natnet:", 0) == 0) {
    parse_natnet_spec(std::string_view(spec).substr(7), "tracker spec '" + spec + "'", {});
    return;
  }
  if (spec == "5dt-usb" || spec.rfind("5dt-usb:", 0) == 0 || spec.rfind("5dt-serial:", 0) == 0) {
    check_glove_spec(spec);
    return;
  }
  throw std::invalid_argument("tracker spec '" + spec + "' is not one of " + kHandForms);
}

std::unique_ptr<HandTracker> make_tracker(const std::string& spec, const TrackerConfig& config) {
  if (spec.rfind("script:", 0) == 0) {
    const std::string what = spec.substr(7);
    const auto names = HandScript::builtin_names();
    if (std::find(names.begin(), names.end(), what) != names.end())
      return std::make_unique<ScriptTracker>(HandScript::builtin(what, config.surface_depth_m),
                                             spec, config.repeat);
    if (what.empty())
      throw std::invalid_argument("tracker spec 'script:' needs press, stroke, tap or a file");
    return std::make_unique<ScriptTracker>(HandScript::load(what), spec, config.repeat);
  }
  if (spec.rfind("natnet:", 0) == 0) return make_natnet_tracker(spec, config);
  if (spec == "5dt-usb" || spec.rfind("5dt-usb:", 0) == 0 || spec.rfind("5dt-serial:", 0) == 0) {
    std::unique_ptr<GloveDevice> glove;
    try {
      glove =
          open_glove(spec, config.glove_calibration_path,
                     config.glove_range[index_of(config.use_left_hand ? Side::Left : Side::Right)]);
    } catch (const std::runtime_error& e) {
      // The hand can do without a glove: say how.
      throw std::runtime_error(std::string(e.what()) + " Without a glove: --hand script:press.");
    }
    return make_glove_tracker(std::move(glove), config);
  }
  throw std::invalid_argument("tracker spec '" + spec + "' is not one of " + kHandForms);
}

}  // namespace telex::local
