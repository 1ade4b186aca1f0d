// SPDX-License-Identifier: MIT
// hidapi's enumeration of the HID devices, shared by the displays that open a device by its USB ids
// and by `telex devices`.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace telex::local {

// One row of hidapi's enumeration (wide strings narrowed, non-ASCII as '?').
struct HidCandidate {
  std::string path;  // /dev/hidrawN
  std::uint16_t vendor_id = 0, product_id = 0;
  std::string serial, product, manufacturer;
};

// Every HID device hidapi sees (hid_init first; empty when hidapi cannot initialise).
std::vector<HidCandidate> enumerate_hid();

}  // namespace telex::local
