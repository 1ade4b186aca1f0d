// SPDX-License-Identifier: MIT
// hidapi's enumeration as plain rows.
#include "telex/local/displays/hid.h"

#include <hidapi.h>

namespace telex::local {

namespace {

std::string narrow(const wchar_t* w) {
  std::string out;
  for (; w != nullptr && *w != 0; ++w) out.push_back(*w < 128 ? static_cast<char>(*w) : '?');
  return out;
}

}  // namespace

std::vector<HidCandidate> enumerate_hid() {
  std::vector<HidCandidate> out;
  if (hid_init() != 0) return out;
  hid_device_info* list = hid_enumerate(0, 0);
  for (hid_device_info* d = list; d != nullptr; d = d->next)
    out.push_back({d->path ? d->path : "", d->vendor_id, d->product_id, narrow(d->serial_number),
                   narrow(d->product_string), narrow(d->manufacturer_string)});
  hid_free_enumeration(list);
  return out;
}

}  // namespace telex::local
