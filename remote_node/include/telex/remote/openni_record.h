// SPDX-License-Identifier: MIT
// Records an OpenNI2 device's depth stream to an .oni file with openni::Recorder.
#pragma once

#include <chrono>
#include <filesystem>
#include <string>

namespace telex::remote {

// Records `frames` depth frames from device `uri` ("" = any, "Dummy" = OpenNI2's test device) to
// `path`. Returns the number of frames seen while recording (fewer when the device stops delivering
// within `timeout`). Throws std::runtime_error naming the device or the file on failure to open.
int record_oni(const std::string& uri, const std::filesystem::path& path, int frames,
               std::chrono::milliseconds timeout = std::chrono::milliseconds(1000));

}  // namespace telex::remote
