// SPDX-License-Identifier: MIT
// What is connected, for `telex devices`: USB devices through libusb, hidraw devices through
// hidapi and serial ports from /dev, each matched against the devices this project drives (by
// USB vendor and product id: the built-in table, plus ids a lab adds for its own controllers).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace telex::devices {

// A device this project knows by its USB ids. No product id: any product of the vendor.
struct KnownDevice {
  std::uint16_t vendor_id = 0;
  std::optional<std::uint16_t> product_id;
  std::string name;  // e.g. "Kinect for Xbox 360 camera"
  std::string use;   // how to use it, e.g. "--source freenect" or "--glove 5dt-usb"
};

// The built-in table (sources cited in docs/HARDWARE.md "Finding devices").
const std::vector<KnownDevice>& known_devices();

// "VID:PID=NAME" (hex ids, e.g. "16c0:05df=Gravity Grabber controller"): a lab's own device.
// Throws std::invalid_argument naming the text and the form.
KnownDevice parse_known_device(std::string_view text);

// The first entry of `extra` then of the built-in table that matches; exact products before
// vendor-wide entries.
std::optional<KnownDevice> identify(std::uint16_t vendor_id, std::uint16_t product_id,
                                    const std::vector<KnownDevice>& extra = {});

struct UsbDevice {
  int bus = 0, address = 0;
  std::uint16_t vendor_id = 0, product_id = 0;
  std::optional<KnownDevice> known;
};

struct UsbScan {
  bool available = false;  // libusb could open the USB bus
  std::string error;       // why not (e.g. no /dev/bus/usb in a container)
  std::vector<UsbDevice> devices;
};

UsbScan scan_usb(const std::vector<KnownDevice>& extra = {});

struct HidDevice {
  std::string path;  // /dev/hidrawN
  std::uint16_t vendor_id = 0, product_id = 0;
  std::string manufacturer, product, serial;
  std::optional<KnownDevice> known;
};

std::vector<HidDevice> scan_hid(const std::vector<KnownDevice>& extra = {});

// Serial ports a 5DT serial glove or a microcontroller could be on: ttyUSB*, ttyACM*, and the
// stable names under serial/by-id (as links) in `dev_dir`.
std::vector<std::string> scan_serial(const std::string& dev_dir = "/dev");

}  // namespace telex::devices
