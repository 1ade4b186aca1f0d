// SPDX-License-Identifier: MIT
// libFuzzer target: the device-layer parsers of the operator station. Byte 0 picks one: the 5DT
// USB report (byte 1 picks the model), the wired and the wireless 5DT serial streams, the 5DT
// info reply, and the Gravity Grabber's device text (hidraw path or VID:PID[:SERIAL]).
#include <cstddef>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <string_view>

#include "telex/local/displays/gravity_grabber.h"
#include "telex/local/inputs/glove.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace telex::local;
  if (size < 2) return 0;
  const std::span<const std::uint8_t> bytes(data + 2, size - 2);
  GloveRaw raw;
  switch (data[0] % 5) {
    case 0: {
      static constexpr GloveModel kModels[] = {GloveModel::Sensors14, GloveModel::Sensors5Right,
                                               GloveModel::Sensors5Left, GloveModel::Serial5};
      if (parse_5dt_usb_report(bytes, kModels[data[1] % 4], raw) == nullptr &&
          (raw.sensor_count != 5 && raw.sensor_count != 14))
        __builtin_trap();
      break;
    }
    case 1:
    case 2: {
      Serial5dtParser p(/*wireless=*/data[0] % 5 == 2);
      std::size_t reports = 0;
      for (auto b : bytes)
        if (p.push(b, raw)) {
          ++reports;
          for (int i = 0; i < 5; ++i)
            if (!(raw.sensors[i] >= 0.0 && raw.sensors[i] <= 1.0)) __builtin_trap();
        }
      // Every byte is a header, part of a report, or skipped: none is lost or counted twice.
      const std::size_t frame = data[0] % 5 == 2 ? k5dtWirelessReportBytes : k5dtSerialReportBytes;
      if (reports * frame + p.skipped_bytes() > bytes.size()) __builtin_trap();
      break;
    }
    case 3: {
      Serial5dtInfo info;
      if (parse_5dt_serial_info(bytes, info) == nullptr && info.name.size() > 16) __builtin_trap();
      break;
    }
    case 4: {
      const std::string_view text(reinterpret_cast<const char*>(bytes.data()), bytes.size());
      try {
        const HidTarget t = parse_hid_target(text);
        if (!t.by_ids() && t.path != text) __builtin_trap();
      } catch (const std::invalid_argument&) {
      }
      break;
    }
  }
  return 0;
}
