// SPDX-License-Identifier: MIT
// ROS 1 bags through Debian's rosbag_storage, behind types that carry no ROS header. This target is
// compiled as C++17 (ROS 1's generated messages do not compile as C++20); the header is valid C++17
// and C++20 so the rest of the project includes it as it is.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace telex::bag {

// Pinhole intrinsics as sensor_msgs/CameraInfo carries them (K, no distortion).
struct CameraIntrinsics {
  double fx = 0, fy = 0, cx = 0, cy = 0;
  int width = 0, height = 0;
};

// geometry_msgs/Pose: position (m) and orientation quaternion (x, y, z, w).
struct Pose {
  std::array<double, 3> p{0, 0, 0};
  std::array<double, 4> q{0, 0, 0, 1};
};

// One geometry_msgs/TransformStamped of a tf2_msgs/TFMessage: X_ParentChild.
struct Transform {
  std::string parent, child;
  Pose pose;
};

enum class Compression { None, Lz4, Bz2 };

// Writes a bag. Not thread-safe: one writer thread owns it. Every call throws std::runtime_error
// naming the file when the library fails (disk full, closed bag).
class Writer {
 public:
  Writer(const std::string& path, Compression compression = Compression::Lz4);
  ~Writer();
  Writer(const Writer&) = delete;
  Writer& operator=(const Writer&) = delete;

  // sensor_msgs/Image 16UC1 (millimetres, 0 = no data) and its sensor_msgs/CameraInfo (same
  // header). Written at bag time `bag_time_ns` (0: the stamp).
  void depth_mm(const std::string& image_topic, const std::string& info_topic,
                std::int64_t stamp_ns, std::uint32_t seq, const std::string& frame_id,
                const cv::Mat& depth_mm, const CameraIntrinsics& k, std::int64_t bag_time_ns = 0);
  // sensor_msgs/Image 32FC1 (metres, NaN = no data) and its CameraInfo.
  void depth_m(const std::string& image_topic, const std::string& info_topic, std::int64_t stamp_ns,
               std::uint32_t seq, const std::string& frame_id, const cv::Mat& depth_m,
               const CameraIntrinsics& k);
  // sensor_msgs/Image bgr8.
  void colour(const std::string& topic, std::int64_t stamp_ns, const std::string& frame_id,
              const cv::Mat& bgr);
  // tf2_msgs/TFMessage on /tf.
  void tf(std::int64_t stamp_ns, const std::vector<Transform>& transforms);
  // geometry_msgs/PoseArray.
  void poses(const std::string& topic, std::int64_t stamp_ns, std::uint32_t seq,
             const std::string& frame_id, const std::vector<Pose>& poses);
  // geometry_msgs/WrenchStamped.
  void wrench(const std::string& topic, std::int64_t stamp_ns, const std::string& frame_id,
              const std::array<double, 3>& force_N, const std::array<double, 3>& torque_Nm);
  // std_msgs/String.
  void text(const std::string& topic, std::int64_t stamp_ns, const std::string& text);
  // Writes the index and closes the file (the destructor does it too, without throwing).
  void close();
  const std::string& path() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

struct TopicInfo {
  std::string topic;
  std::string type;  // e.g. sensor_msgs/Image
  std::uint64_t messages = 0;
  std::string encoding;                   // sensor_msgs/Image: the first message's encoding
  std::int64_t begin_ns = 0, end_ns = 0;  // bag times of the first and the last message
  // Messages per second over the topic's span (0 with fewer than two messages).
  double rate_hz() const {
    return messages > 1 && end_ns > begin_ns
               ? 1e9 * static_cast<double>(messages - 1) / static_cast<double>(end_ns - begin_ns)
               : 0.0;
  }
};

// One decoded message. Types other than those below arrive as Kind::Other with topic and time.
struct Message {
  enum class Kind { Image, CameraInfo, Wrench, PoseArray, Tf, Text, Other };
  Kind kind = Kind::Other;
  std::string topic;
  std::string type;
  std::int64_t bag_time_ns = 0;  // when it was written
  std::int64_t stamp_ns = 0;     // header stamp (bag time for messages without a header)
  std::uint32_t seq = 0;
  std::string frame_id;
  // Image: encoding as stored; image holds 16UC1 as CV_16UC1, 32FC1 as CV_32FC1, bgr8 / rgb8 /
  // bgra8 / rgba8 as CV_8UC3 BGR, mono8 as CV_8UC1; any other encoding leaves image empty.
  std::string encoding;
  cv::Mat image;
  CameraIntrinsics camera;  // CameraInfo
  std::array<double, 3> force_N{0, 0, 0}, torque_Nm{0, 0, 0};
  std::vector<Pose> poses;
  std::vector<Transform> transforms;
  std::string text;
};

// Reads a bag: its topics, then its messages in time order. Throws std::runtime_error naming the
// file when it cannot be opened or is not a bag, and when a message cannot be decoded.
class Reader {
 public:
  explicit Reader(const std::string& path);
  ~Reader();
  Reader(const Reader&) = delete;
  Reader& operator=(const Reader&) = delete;

  const std::vector<TopicInfo>& topics() const;
  // "/a (sensor_msgs/Image 16UC1, 300 messages), /b (...)", or "no topics".
  std::string describe_topics() const;
  // Restricts the stream to `topics` (all of them when empty) and starts from the beginning.
  void select(const std::vector<std::string>& topics);
  // The next message in bag-time order; false at the end.
  bool next(Message& out);
  const std::string& path() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Checks the framing of a bag file (every length, position and count rosbag_storage will follow,
// the chunks unpacked) before the library reads it: Debian's rosbag_storage trusts them and
// overflows its heap on a corrupt file. Throws std::runtime_error naming the file and the first
// inconsistency. Reader calls it; it reads the whole file once.
void check_bag_file(const std::string& path);

// ROS time of a nanosecond count (sec, nsec) and back; the count must be positive.
std::int64_t ros_ns(std::uint32_t sec, std::uint32_t nsec);

}  // namespace telex::bag
