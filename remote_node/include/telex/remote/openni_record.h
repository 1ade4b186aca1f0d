// SPDX-License-Identifier: MIT
// Records an OpenNI2 device's depth stream to an .oni file with openni::Recorder, and repairs
// recordings that OpenNI2's file driver would open but never play.
#pragma once

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace telex::remote {

// What record_oni_frames saw while recording: the frames it read from the device, each with the
// device's timestamp. The Recorder writes every frame the device delivers while it runs, which
// can include frames this reader skipped (newest-wins); a frame recorded at device time t plays
// back with timestamp t - (device time of the first recorded frame).
struct OniCapture {
  std::vector<cv::Mat1w> depth_mm;
  std::vector<std::uint64_t> device_timestamp_us;
  int frames() const { return static_cast<int>(depth_mm.size()); }
};

// Records `frames` depth frames from device `uri` ("" = any, "Dummy" = OpenNI2's test device) to
// `path`, then makes the file playable (repair_oni_for_playback) unless `repair` is false (the
// file is then exactly what openni::Recorder wrote). Returns the frames read while recording
// (fewer when the device stops delivering within `timeout`). Throws std::runtime_error naming the
// device or the file on failure to open.
OniCapture record_oni_frames(const std::string& uri, const std::filesystem::path& path, int frames,
                             std::chrono::milliseconds timeout = std::chrono::milliseconds(1000),
                             bool repair = true);

// As record_oni_frames, returning only the number of frames read.
int record_oni(const std::string& uri, const std::filesystem::path& path, int frames,
               std::chrono::milliseconds timeout = std::chrono::milliseconds(1000));

// OpenNI2's file driver (OniFile, PlayerStream::OnNewDataCallback) drops every frame of a stream
// whose recording carries no "xnCropping" property: it reads the stream's cropping property per
// frame and returns early when it is missing. openni::Recorder writes that property only for
// streams that support cropping, which OpenNI2's Dummy device does not, so its recordings open,
// report their frame count and reach end-of-file without delivering a frame. This inserts a
// "cropping disabled" record after each image node's NodeAdded record that lacks one and shifts
// every file position stored in the file (undo chain, seek table and its offset) to match.
// Returns the number of records inserted (0: nothing to do). Throws std::runtime_error naming the
// file when it is not an .oni recording this code can parse.
int repair_oni_for_playback(const std::filesystem::path& in, const std::filesystem::path& out);

// Number of image (depth, colour, IR) nodes in `path` that lack the cropping record the file
// driver needs. Throws std::runtime_error as above.
int oni_nodes_missing_cropping(const std::filesystem::path& path);

}  // namespace telex::remote
