// SPDX-License-Identifier: MIT
// `telex devices [--json] [--usb-id VID:PID=NAME]...`: what is connected. USB devices through
// libusb (matched against the sensors, gloves and controllers this project drives), OpenNI2's
// device list, V4L2 cameras with their formats, hidraw devices and serial ports. Nothing connected
// is an answer, not an error: it says so and exits 0.
#include <fmt/format.h>

#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "command.h"
#include "telex/devices/devices.h"
#include "telex/remote/sources.h"

namespace telex::tool {
namespace {

struct DevicesArgs {
  bool json = false;
  std::vector<std::string> usb_ids;
};

nlohmann::json known_json(const std::optional<devices::KnownDevice>& k) {
  if (!k) return nullptr;
  return {{"name", k->name}, {"use", k->use}};
}

std::string hex4(std::uint16_t v) { return fmt::format("{:04x}", v); }

int run_devices(const DevicesArgs& a) {
  std::vector<devices::KnownDevice> extra;
  for (const auto& t : a.usb_ids) {
    try {
      extra.push_back(devices::parse_known_device(t));
    } catch (const std::invalid_argument& e) {
      std::cerr << "telex devices: --usb-id: " << e.what() << "\n";
      return 2;
    }
  }
  const auto usb = devices::scan_usb(extra);
  const auto hid = devices::scan_hid(extra);
  const auto serial = devices::scan_serial();
  const auto v4l2 = remote::list_v4l2_devices();
  std::vector<remote::OpenNiDeviceInfo> openni;
  std::string openni_error;
  try {
    openni = remote::list_openni_devices();
  } catch (const std::exception& e) {
    openni_error = e.what();
  }
  // OpenNI2's Dummy driver is software: listed, but not something connected.
  std::size_t hardware = usb.devices.size() + hid.size() + serial.size() + v4l2.size();
  for (const auto& d : openni) hardware += d.uri != "Dummy";
  std::size_t known = 0;
  for (const auto& d : usb.devices) known += d.known.has_value();

  if (a.json) {
    nlohmann::json j;
    j["usb"] = {
        {"available", usb.available}, {"error", usb.error}, {"devices", nlohmann::json::array()}};
    for (const auto& d : usb.devices)
      j["usb"]["devices"].push_back({{"bus", d.bus},
                                     {"address", d.address},
                                     {"vendor_id", hex4(d.vendor_id)},
                                     {"product_id", hex4(d.product_id)},
                                     {"known", known_json(d.known)}});
    j["openni"] = {{"error", openni_error}, {"devices", nlohmann::json::array()}};
    for (const auto& d : openni)
      j["openni"]["devices"].push_back({{"uri", d.uri},
                                        {"vendor", d.vendor},
                                        {"name", d.name},
                                        {"vendor_id", hex4(d.usb_vendor_id)},
                                        {"product_id", hex4(d.usb_product_id)}});
    j["v4l2"] = nlohmann::json::array();
    for (const auto& d : v4l2)
      j["v4l2"].push_back({{"path", d.path},
                           {"card", d.card},
                           {"driver", d.driver},
                           {"bus", d.bus},
                           {"capture", d.capture},
                           {"formats", d.formats},
                           {"error", d.error}});
    j["hid"] = nlohmann::json::array();
    for (const auto& d : hid)
      j["hid"].push_back({{"path", d.path},
                          {"vendor_id", hex4(d.vendor_id)},
                          {"product_id", hex4(d.product_id)},
                          {"manufacturer", d.manufacturer},
                          {"product", d.product},
                          {"serial", d.serial},
                          {"known", known_json(d.known)}});
    j["serial"] = serial;
    j["connected"] = hardware;
    j["known"] = known;
    std::cout << j.dump() << "\n";
    return 0;
  }

  if (usb.available) {
    std::cout << fmt::format("USB (libusb): {} devices\n", usb.devices.size());
    for (const auto& d : usb.devices)
      std::cout << fmt::format("  bus {:03d} address {:03d}  {}:{}{}\n", d.bus, d.address,
                               hex4(d.vendor_id), hex4(d.product_id),
                               d.known ? "  " + d.known->name + "  (" + d.known->use + ")" : "");
  } else {
    std::cout << "USB: not visible: " << usb.error << "\n";
  }
  if (!openni_error.empty()) std::cout << "OpenNI2: " << openni_error << "\n";
  for (const auto& d : openni)
    std::cout << fmt::format("OpenNI2: '{}' ({} {}){}\n", d.uri, d.vendor, d.name,
                             d.uri == "Dummy" ? "  (software test device: --source openni:Dummy)"
                                              : "  (--source openni:" + d.uri + ")");
  for (const auto& d : v4l2) {
    if (!d.error.empty()) {
      std::cout << fmt::format("V4L2: {}: {}\n", d.path, d.error);
      continue;
    }
    std::cout << fmt::format("V4L2: {} '{}' ({}, {}){}\n", d.path, d.card, d.driver, d.bus,
                             d.capture ? "" : "  (no video capture)");
    for (const auto& f : d.formats) std::cout << "  " << f << "\n";
  }
  for (const auto& d : hid)
    std::cout << fmt::format("HID: {} {}:{} '{} {}'{}\n", d.path, hex4(d.vendor_id),
                             hex4(d.product_id), d.manufacturer, d.product,
                             d.known ? "  " + d.known->name + "  (" + d.known->use + ")" : "");
  for (const auto& s : serial) std::cout << "Serial: " << s << "\n";
  if (hardware == 0)
    std::cout << "Nothing connected: no USB, video, HID or serial device found.\n";
  else
    std::cout << fmt::format("{} device(s) found, {} of them driven by this project.\n", hardware,
                             known);
  return 0;
}

const RegisterCommand kRegister{
    "devices", "list connected sensors, cameras, gloves, displays and serial ports",
    [](cli::CommandLine& app) -> std::function<int()> {
      auto a = std::make_shared<DevicesArgs>();
      app.add_flag("--json", a->json, "print one JSON object");
      app.add_option("--usb-id", a->usb_ids,
                     "VID:PID=NAME (hex): a lab's own device to recognise, repeatable");
      return [a] { return run_devices(*a); };
    }};

}  // namespace
}  // namespace telex::tool
