// SPDX-License-Identifier: MIT
// The only translation unit that includes ROS headers: rosbag_storage and the standard messages,
// compiled as C++17.
#include "telex/bag/bag.h"

#include <geometry_msgs/PoseArray.h>
#include <geometry_msgs/WrenchStamped.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <std_msgs/String.h>
#include <tf2_msgs/TFMessage.h>

#include <cstring>
#include <map>
#include <memory>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <stdexcept>

namespace telex::bag {

namespace {

// ROS 1 deserialisers resize a vector to the length the bytes claim before they check that the
// bytes hold it (ros/serialization.h VectorSerializer::read): a corrupt CameraInfo asked for
// 19.7 GB (libFuzzer). So each message's bytes are walked first, every length checked against
// what is left, and the message is then deserialised from those same bytes.
class Layout {
 public:
  Layout(const std::uint8_t* p, std::size_t n) : p_(p), left_(n) {}
  void skip(std::size_t n, const char* what) {
    if (n > left_)
      throw std::runtime_error(std::string(what) + " needs " + std::to_string(n) +
                               " bytes, the message has " + std::to_string(left_) + " left");
    p_ += n;
    left_ -= n;
  }
  std::uint32_t u32(const char* what) {
    const std::uint8_t* at = p_;
    skip(4, what);
    return static_cast<std::uint32_t>(at[0]) | static_cast<std::uint32_t>(at[1]) << 8 |
           static_cast<std::uint32_t>(at[2]) << 16 | static_cast<std::uint32_t>(at[3]) << 24;
  }
  void bytes(const char* what, std::size_t elem) {  // u32 count, then count * elem bytes
    const std::uint64_t count = u32(what);
    if (count > left_ / elem)
      throw std::runtime_error(std::string(what) + " claims " + std::to_string(count) +
                               " elements of " + std::to_string(elem) + " bytes, the message has " +
                               std::to_string(left_) + " left");
    skip(static_cast<std::size_t>(count) * elem, what);
  }
  void header() {
    skip(12, "header");  // seq, stamp
    bytes("header.frame_id", 1);
  }
  std::size_t left() const { return left_; }

 private:
  const std::uint8_t* p_;
  std::size_t left_;
};

// Walks the types the reader decodes (their fields in order, from the .msg files).
void check_layout(const std::string& type, const std::vector<std::uint8_t>& raw) {
  Layout l(raw.data(), raw.size());
  if (type == "sensor_msgs/Image") {
    l.header();
    l.skip(8, "height, width");
    l.bytes("encoding", 1);
    l.skip(5, "is_bigendian, step");
    l.bytes("data", 1);
  } else if (type == "sensor_msgs/CameraInfo") {
    l.header();
    l.skip(8, "height, width");
    l.bytes("distortion_model", 1);
    l.bytes("D", 8);
    l.skip((9 + 9 + 12) * 8 + 8 + 17, "K, R, P, binning, roi");
  } else if (type == "geometry_msgs/WrenchStamped") {
    l.header();
    l.skip(6 * 8, "wrench");
  } else if (type == "geometry_msgs/PoseArray") {
    l.header();
    l.bytes("poses", 7 * 8);
  } else if (type == "tf2_msgs/TFMessage") {
    const std::uint32_t n = l.u32("transforms");
    constexpr std::size_t kMinTransform = 12 + 4 + 4 + 7 * 8;
    if (n > l.left() / kMinTransform)
      throw std::runtime_error("transforms claims " + std::to_string(n) +
                               " elements, the message has " + std::to_string(l.left()) +
                               " bytes left");
    for (std::uint32_t i = 0; i < n; ++i) {
      l.header();
      l.bytes("child_frame_id", 1);
      l.skip(7 * 8, "transform");
    }
  } else if (type == "std_msgs/String") {
    l.bytes("data", 1);
  }
}

// rosbag's MessageInstance::instantiate, from bytes already checked: same type and MD5 test.
template <class T>
std::optional<T> decode(const rosbag::MessageInstance& m, std::vector<std::uint8_t>& raw) {
  if (m.getDataType() != ros::message_traits::datatype<T>() ||
      (m.getMD5Sum() != "*" && m.getMD5Sum() != ros::message_traits::md5sum<T>()))
    return std::nullopt;
  T msg;
  ros::serialization::IStream in(raw.data(), static_cast<std::uint32_t>(raw.size()));
  ros::serialization::deserialize(in, msg);
  return msg;
}

// The message's bytes, checked for its type.
std::vector<std::uint8_t> message_bytes(const rosbag::MessageInstance& m) {
  std::vector<std::uint8_t> raw(m.size());
  ros::serialization::OStream out(raw.data(), static_cast<std::uint32_t>(raw.size()));
  m.write(out);
  check_layout(m.getDataType(), raw);
  return raw;
}

ros::Time to_ros(std::int64_t ns) {
  if (ns <= 0) throw std::invalid_argument("bag time must be positive, got " + std::to_string(ns));
  return ros::Time(static_cast<std::uint32_t>(ns / 1'000'000'000),
                   static_cast<std::uint32_t>(ns % 1'000'000'000));
}

std::int64_t from_ros(const ros::Time& t) { return ros_ns(t.sec, t.nsec); }

std_msgs::Header header(std::int64_t stamp_ns, std::uint32_t seq, const std::string& frame_id) {
  std_msgs::Header h;
  h.stamp = to_ros(stamp_ns);
  h.seq = seq;
  h.frame_id = frame_id;
  return h;
}

sensor_msgs::CameraInfo camera_info(const std_msgs::Header& h, const CameraIntrinsics& k) {
  sensor_msgs::CameraInfo info;
  info.header = h;
  info.width = static_cast<std::uint32_t>(k.width);
  info.height = static_cast<std::uint32_t>(k.height);
  info.distortion_model = "plumb_bob";
  info.D.assign(5, 0.0);
  info.K = {k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1};
  info.R = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  info.P = {k.fx, 0, k.cx, 0, 0, k.fy, k.cy, 0, 0, 0, 1, 0};
  return info;
}

sensor_msgs::Image image_msg(const std_msgs::Header& h, const cv::Mat& m, const char* encoding) {
  sensor_msgs::Image im;
  im.header = h;
  im.width = static_cast<std::uint32_t>(m.cols);
  im.height = static_cast<std::uint32_t>(m.rows);
  im.encoding = encoding;
  im.is_bigendian = 0;
  const std::size_t row_bytes = m.elemSize() * static_cast<std::size_t>(m.cols);
  im.step = static_cast<std::uint32_t>(row_bytes);
  im.data.resize(row_bytes * static_cast<std::size_t>(m.rows));
  for (int r = 0; r < m.rows; ++r)
    std::memcpy(im.data.data() + row_bytes * static_cast<std::size_t>(r), m.ptr(r), row_bytes);
  return im;
}

geometry_msgs::Pose pose_msg(const Pose& p) {
  geometry_msgs::Pose out;
  out.position.x = p.p[0];
  out.position.y = p.p[1];
  out.position.z = p.p[2];
  out.orientation.x = p.q[0];
  out.orientation.y = p.q[1];
  out.orientation.z = p.q[2];
  out.orientation.w = p.q[3];
  return out;
}

Pose from_msg(const geometry_msgs::Pose& p) {
  return {{p.position.x, p.position.y, p.position.z},
          {p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w}};
}

// The image's pixels as OpenCV holds them, or an empty Mat for an encoding this project does not
// read. Throws when the declared size and step disagree with the data.
cv::Mat decode_image(const sensor_msgs::Image& im) {
  int type = -1, channels = 1;
  std::size_t elem = 1;
  const std::string& e = im.encoding;
  if (e == "16UC1" || e == "mono16") {
    type = CV_16UC1;
    elem = 2;
  } else if (e == "32FC1") {
    type = CV_32FC1;
    elem = 4;
  } else if (e == "bgr8" || e == "rgb8") {
    type = CV_8UC3;
    elem = 3;
    channels = 3;
  } else if (e == "bgra8" || e == "rgba8") {
    type = CV_8UC4;
    elem = 4;
    channels = 4;
  } else if (e == "mono8" || e == "8UC1") {
    type = CV_8UC1;
  } else {
    return {};
  }
  const std::size_t row_bytes = elem * im.width;
  if (im.width == 0 || im.height == 0 || im.step < row_bytes ||
      im.data.size() < static_cast<std::size_t>(im.step) * im.height)
    throw std::runtime_error("image " + std::to_string(im.width) + "x" + std::to_string(im.height) +
                             " " + e + " with step " + std::to_string(im.step) + " holds " +
                             std::to_string(im.data.size()) + " bytes: truncated or inconsistent");
  cv::Mat out(static_cast<int>(im.height), static_cast<int>(im.width), type);
  for (std::uint32_t r = 0; r < im.height; ++r)
    std::memcpy(out.ptr(static_cast<int>(r)),
                im.data.data() + static_cast<std::size_t>(im.step) * r, row_bytes);
  if (im.is_bigendian && elem / static_cast<std::size_t>(channels) > 1) {
    // 16- and 32-bit samples written by a big-endian host.
    const std::size_t sample = elem / static_cast<std::size_t>(channels);
    for (int r = 0; r < out.rows; ++r) {
      auto* p = out.ptr<std::uint8_t>(r);
      for (std::size_t i = 0; i + sample <= row_bytes; i += sample)
        for (std::size_t a = 0, b = sample - 1; a < b; ++a, --b) std::swap(p[i + a], p[i + b]);
    }
  }
  if (e == "rgb8") cv::cvtColor(out, out, cv::COLOR_RGB2BGR);
  if (e == "bgra8") cv::cvtColor(out, out, cv::COLOR_BGRA2BGR);
  if (e == "rgba8") cv::cvtColor(out, out, cv::COLOR_RGBA2BGR);
  return out;
}

}  // namespace

std::int64_t ros_ns(std::uint32_t sec, std::uint32_t nsec) {
  return static_cast<std::int64_t>(sec) * 1'000'000'000 + static_cast<std::int64_t>(nsec);
}

// ---- Writer ----

struct Writer::Impl {
  std::string path;
  std::unique_ptr<rosbag::Bag> bag = std::make_unique<rosbag::Bag>();
  bool open = false;

  // After a failed write or close (a full disk) the library's Bag cannot be closed: its
  // destructor calls close() again, which throws again (the chunk still cannot be written) and,
  // thrown from a destructor, ends the process. The Bag is given up instead (its memory and its
  // file handle are kept until exit) and the file keeps what was written: every whole chunk
  // before the failure, which `rosbag reindex` reads back.
  void abandon() {
    open = false;
    (void)bag.release();  // deliberately kept, see above
  }

  template <typename M>
  void write(const std::string& topic, std::int64_t time_ns, const M& msg) {
    if (!open) throw std::runtime_error("bag " + path + " is closed");
    try {
      bag->write(topic, to_ros(time_ns), msg);
    } catch (const std::exception& e) {
      abandon();
      throw std::runtime_error("cannot write " + topic + " to bag " + path + ": " + e.what());
    }
  }
};

Writer::Writer(const std::string& path, Compression compression) : impl_(new Impl) {
  impl_->path = path;
  try {
    impl_->bag->open(path, rosbag::bagmode::Write);
  } catch (const std::exception& e) {
    impl_->abandon();  // a header that could not be written cannot be closed either
    throw std::runtime_error("cannot create bag " + path + ": " + e.what());
  }
  impl_->bag->setCompression(compression == Compression::Lz4   ? rosbag::compression::LZ4
                             : compression == Compression::Bz2 ? rosbag::compression::BZ2
                                                               : rosbag::compression::Uncompressed);
  impl_->open = true;
}

Writer::~Writer() {
  try {
    close();
  } catch (...) {
    // The destructor cannot report; close() called directly does.
  }
}

void Writer::close() {
  if (!impl_->open) return;
  impl_->open = false;
  try {
    impl_->bag->close();
  } catch (const std::exception& e) {
    impl_->abandon();
    throw std::runtime_error("cannot close bag " + impl_->path + ": " + e.what());
  }
}

const std::string& Writer::path() const { return impl_->path; }

void Writer::depth_mm(const std::string& image_topic, const std::string& info_topic,
                      std::int64_t stamp_ns, std::uint32_t seq, const std::string& frame_id,
                      const cv::Mat& depth_mm, const CameraIntrinsics& k,
                      std::int64_t bag_time_ns) {
  if (depth_mm.type() != CV_16UC1) throw std::invalid_argument("depth_mm needs a CV_16UC1 image");
  const auto h = header(stamp_ns, seq, frame_id);
  const std::int64_t t = bag_time_ns > 0 ? bag_time_ns : stamp_ns;
  impl_->write(image_topic, t, image_msg(h, depth_mm, "16UC1"));
  if (!info_topic.empty()) impl_->write(info_topic, t, camera_info(h, k));
}

void Writer::depth_m(const std::string& image_topic, const std::string& info_topic,
                     std::int64_t stamp_ns, std::uint32_t seq, const std::string& frame_id,
                     const cv::Mat& depth_m, const CameraIntrinsics& k) {
  if (depth_m.type() != CV_32FC1) throw std::invalid_argument("depth_m needs a CV_32FC1 image");
  const auto h = header(stamp_ns, seq, frame_id);
  impl_->write(image_topic, stamp_ns, image_msg(h, depth_m, "32FC1"));
  if (!info_topic.empty()) impl_->write(info_topic, stamp_ns, camera_info(h, k));
}

void Writer::colour(const std::string& topic, std::int64_t stamp_ns, const std::string& frame_id,
                    const cv::Mat& bgr) {
  if (bgr.type() != CV_8UC3) throw std::invalid_argument("colour needs a CV_8UC3 BGR image");
  impl_->write(topic, stamp_ns, image_msg(header(stamp_ns, 0, frame_id), bgr, "bgr8"));
}

void Writer::tf(std::int64_t stamp_ns, const std::vector<Transform>& transforms) {
  tf2_msgs::TFMessage msg;
  for (const auto& t : transforms) {
    geometry_msgs::TransformStamped ts;
    ts.header = header(stamp_ns, 0, t.parent);
    ts.child_frame_id = t.child;
    ts.transform.translation.x = t.pose.p[0];
    ts.transform.translation.y = t.pose.p[1];
    ts.transform.translation.z = t.pose.p[2];
    ts.transform.rotation.x = t.pose.q[0];
    ts.transform.rotation.y = t.pose.q[1];
    ts.transform.rotation.z = t.pose.q[2];
    ts.transform.rotation.w = t.pose.q[3];
    msg.transforms.push_back(ts);
  }
  impl_->write("/tf", stamp_ns, msg);
}

void Writer::poses(const std::string& topic, std::int64_t stamp_ns, std::uint32_t seq,
                   const std::string& frame_id, const std::vector<Pose>& poses) {
  geometry_msgs::PoseArray msg;
  msg.header = header(stamp_ns, seq, frame_id);
  for (const auto& p : poses) msg.poses.push_back(pose_msg(p));
  impl_->write(topic, stamp_ns, msg);
}

void Writer::wrench(const std::string& topic, std::int64_t stamp_ns, const std::string& frame_id,
                    const std::array<double, 3>& force_N, const std::array<double, 3>& torque_Nm) {
  geometry_msgs::WrenchStamped msg;
  msg.header = header(stamp_ns, 0, frame_id);
  msg.wrench.force.x = force_N[0];
  msg.wrench.force.y = force_N[1];
  msg.wrench.force.z = force_N[2];
  msg.wrench.torque.x = torque_Nm[0];
  msg.wrench.torque.y = torque_Nm[1];
  msg.wrench.torque.z = torque_Nm[2];
  impl_->write(topic, stamp_ns, msg);
}

void Writer::text(const std::string& topic, std::int64_t stamp_ns, const std::string& text) {
  std_msgs::String msg;
  msg.data = text;
  impl_->write(topic, stamp_ns, msg);
}

// ---- Reader ----

struct Reader::Impl {
  std::string path;
  rosbag::Bag bag;
  std::vector<TopicInfo> topics;
  std::optional<rosbag::View> view;
  rosbag::View::iterator it;
};

Reader::Reader(const std::string& path) : impl_(new Impl) {
  impl_->path = path;
  check_bag_file(path);
  try {
    impl_->bag.open(path, rosbag::bagmode::Read);
    rosbag::View all(impl_->bag);
    std::map<std::string, TopicInfo> by_topic;
    for (const auto* c : all.getConnections()) {
      auto& t = by_topic[c->topic];
      t.topic = c->topic;
      t.type = c->datatype;
    }
    for (auto& [name, t] : by_topic) {
      rosbag::View one(impl_->bag, rosbag::TopicQuery(name));
      t.messages = one.size();
      if (t.messages > 0) {
        t.begin_ns = from_ros(one.getBeginTime());
        t.end_ns = from_ros(one.getEndTime());
      }
      if (t.type == "sensor_msgs/Image" && one.size() > 0) {
        const auto it = one.begin();  // the instance lives in the iterator
        const rosbag::MessageInstance& first = *it;
        auto raw = message_bytes(first);
        if (auto im = decode<sensor_msgs::Image>(first, raw)) t.encoding = im->encoding;
      }
      impl_->topics.push_back(t);
    }
  } catch (const std::exception& e) {
    throw std::runtime_error("cannot read bag " + path + ": " + e.what());
  }
  select({});
}

Reader::~Reader() = default;

const std::vector<TopicInfo>& Reader::topics() const { return impl_->topics; }
const std::string& Reader::path() const { return impl_->path; }

std::string Reader::describe_topics() const {
  std::string out;
  for (const auto& t : impl_->topics) {
    if (!out.empty()) out += ", ";
    out += t.topic + " (" + t.type + (t.encoding.empty() ? "" : " " + t.encoding) + ", " +
           std::to_string(t.messages) + " messages)";
  }
  return out.empty() ? "no topics" : out;
}

void Reader::select(const std::vector<std::string>& topics) {
  impl_->view.reset();
  if (topics.empty())
    impl_->view.emplace(impl_->bag);
  else
    impl_->view.emplace(impl_->bag, rosbag::TopicQuery(topics));
  impl_->it = impl_->view->begin();
}

bool Reader::next(Message& out) {
  if (impl_->it == impl_->view->end()) return false;
  const rosbag::MessageInstance& m = *impl_->it;
  const std::string where = impl_->path + " " + m.getTopic();
  out = Message{};
  out.topic = m.getTopic();
  out.type = m.getDataType();
  out.bag_time_ns = from_ros(m.getTime());
  out.stamp_ns = out.bag_time_ns;
  try {
    auto raw = message_bytes(m);
    if (auto im = decode<sensor_msgs::Image>(m, raw)) {
      out.kind = Message::Kind::Image;
      out.stamp_ns = from_ros(im->header.stamp);
      out.seq = im->header.seq;
      out.frame_id = im->header.frame_id;
      out.encoding = im->encoding;
      out.image = decode_image(*im);
    } else if (auto ci = decode<sensor_msgs::CameraInfo>(m, raw)) {
      out.kind = Message::Kind::CameraInfo;
      out.stamp_ns = from_ros(ci->header.stamp);
      out.seq = ci->header.seq;
      out.frame_id = ci->header.frame_id;
      out.camera = {ci->K[0],
                    ci->K[4],
                    ci->K[2],
                    ci->K[5],
                    static_cast<int>(ci->width),
                    static_cast<int>(ci->height)};
    } else if (auto w = decode<geometry_msgs::WrenchStamped>(m, raw)) {
      out.kind = Message::Kind::Wrench;
      out.stamp_ns = from_ros(w->header.stamp);
      out.seq = w->header.seq;
      out.frame_id = w->header.frame_id;
      out.force_N = {w->wrench.force.x, w->wrench.force.y, w->wrench.force.z};
      out.torque_Nm = {w->wrench.torque.x, w->wrench.torque.y, w->wrench.torque.z};
    } else if (auto pa = decode<geometry_msgs::PoseArray>(m, raw)) {
      out.kind = Message::Kind::PoseArray;
      out.stamp_ns = from_ros(pa->header.stamp);
      out.seq = pa->header.seq;
      out.frame_id = pa->header.frame_id;
      for (const auto& p : pa->poses) out.poses.push_back(from_msg(p));
    } else if (auto tf = decode<tf2_msgs::TFMessage>(m, raw)) {
      out.kind = Message::Kind::Tf;
      for (const auto& ts : tf->transforms) {
        Transform t;
        t.parent = ts.header.frame_id;
        t.child = ts.child_frame_id;
        t.pose.p = {ts.transform.translation.x, ts.transform.translation.y,
                    ts.transform.translation.z};
        t.pose.q = {ts.transform.rotation.x, ts.transform.rotation.y, ts.transform.rotation.z,
                    ts.transform.rotation.w};
        out.transforms.push_back(t);
      }
      if (!tf->transforms.empty()) out.stamp_ns = from_ros(tf->transforms.front().header.stamp);
    } else if (auto s = decode<std_msgs::String>(m, raw)) {
      out.kind = Message::Kind::Text;
      out.text = s->data;
    }
  } catch (const std::exception& e) {
    throw std::runtime_error("cannot decode a message of " + where + ": " + e.what());
  }
  ++impl_->it;
  return true;
}

}  // namespace telex::bag
