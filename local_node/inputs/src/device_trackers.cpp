// SPDX-License-Identifier: MIT
// The device-backed trackers (device_trackers.h): NatNet (+ gloves) and a glove alone.
#include "device_trackers.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <glm/gtc/quaternion.hpp>
#include <stdexcept>

#include "telex/common/head_kinematics.h"
#include "telex/local/inputs/glove.h"
#include "telex/local/inputs/natnet_client.h"

namespace telex::local {

namespace {

// The NatNet stream as a tracker input: where frames should come from, and what keeps them away.
TrackerInput natnet_input(const NatNetClientConfig& c, int local_command_port) {
  TrackerInput in;
  const std::string cmd = std::to_string(c.command_port);
  if (c.multicast) {
    in.what = "NatNet frames from " + c.server_ip + " (multicast group " + c.multicast_group +
              ", data port " + std::to_string(c.data_port) + " on interface " + c.local_address +
              "; command port " + cmd + ")";
    in.check =
        "is Motive streaming there (Streaming pane: Broadcast Frame Data on, transmission "
        "type Multicast, that group)? Is local=IP this station's interface facing the "
        "Motive PC (0.0.0.0 lets the system choose)? Does a firewall drop UDP ports " +
        cmd + " and " + std::to_string(c.data_port) + "? Or try natnet:" + c.server_ip + ",unicast";
  } else {
    in.what = "NatNet frames from " + c.server_ip + " (unicast, command port " + cmd + ")";
    in.check =
        "is Motive running there and streaming (Streaming pane: Broadcast Frame Data on, "
        "transmission type Unicast)? Is " +
        c.server_ip + " the Motive PC's address? Does a firewall drop UDP between them (port " +
        cmd + " there, " + std::to_string(local_command_port) + " here)?";
  }
  return in;
}

// A glove as a tracker input.
TrackerInput glove_input(const GloveDevice& glove) {
  return {glove.reports(), "reports from the " + glove.name(),
          "is the glove switched on (a wireless one paired with its kit) and its cable or "
          "receiver plugged in?"};
}

// NatNet rigid bodies + hand model; finger bends from a glove when one is attached. The haptic
// hand gives the fingertips; both hands, shoulders and elbows that have body ids are tracked for
// the view's body (HandState::arms).
class NatNetTracker final : public HandTracker {
 public:
  NatNetTracker(NatNetClientConfig ccfg, const TrackerConfig& cfg,
                std::unique_ptr<GloveDevice> glove, std::unique_ptr<GloveDevice> other_glove)
      : cfg_(cfg), glove_(std::move(glove)), other_glove_(std::move(other_glove)) {
    haptic_ = cfg.use_left_hand ? Side::Left : Side::Right;
    const auto by_side = [](int left, int right) {
      return std::array<std::int32_t, 2>{left, right};
    };
    hand_id_ = by_side(cfg.left_hand_body_id, cfg.right_hand_body_id);
    shoulder_id_ = by_side(cfg.left_shoulder_body_id, cfg.right_shoulder_body_id);
    elbow_id_ = by_side(cfg.left_elbow_body_id, cfg.right_elbow_body_id);
    if (hand_id_[index_of(haptic_)] < 0 || (cfg.head_body_id < 0 && !cfg.head_from_hmd))
      throw std::invalid_argument("natnet tracker: head and hand rigid body ids must be set");
    ccfg.body_ids = {cfg.head_body_id};
    for (const auto& ids : {hand_id_, shoulder_id_, elbow_id_})
      for (const std::int32_t id : ids)
        if (id >= 0) ccfg.body_ids.push_back(id);
    hand_cfg_[index_of(Side::Right)] = cfg.hand;
    hand_cfg_[index_of(Side::Left)] = cfg.hand;  // the head-to-camera offset is shared
    static_cast<HandGeometry&>(hand_cfg_[index_of(Side::Left)]) = cfg.left_hand;
    hand_cfg_[index_of(Side::Right)].left = false;
    hand_cfg_[index_of(Side::Left)].left = true;
    for (auto& bends : bend_)
      for (std::size_t f = 0; f < 5; ++f)
        bends[f] = {cfg.default_bend[f], cfg.default_bend[f], cfg.default_bend[f]};
    name_ = "natnet:" + ccfg.server_ip + (glove_ ? "+" + glove_->name() : "") +
            (other_glove_ ? "+" + other_glove_->name() : "");
    const NatNetClientConfig kept = ccfg;
    client_ = std::make_unique<NatNetClient>(std::move(ccfg));
    natnet_input_ = natnet_input(kept, client_->command_port());
  }

  bool poll(std::int64_t now_ns, HandState& out) override {
    ++stats_.polls;
    bool mocap_fresh = false, fresh = false;
    if (client_->latest(incoming_)) {
      // A frame whose head or haptic hand failed the pose checks is set aside whole: the last
      // good state stays and ages, so the haptic loop's staleness limit releases the fingers and
      // the head is not sent from it (a rejected shoulder or elbow is only not drawn).
      const auto rejected = [&](std::int32_t id) {
        const auto* b = id >= 0 ? incoming_.find(id) : nullptr;
        return b != nullptr && b->rejected;
      };
      const bool head_rejected = !cfg_.head_from_hmd && rejected(cfg_.head_body_id);
      if (head_rejected || rejected(hand_id_[index_of(haptic_)])) {
        ++stats_.frames_rejected;
      } else {
        sample_ = incoming_;
        have_sample_ = true;
        mocap_fresh = fresh = true;
        mocap_ns_ = now_ns;
      }
    }
    GloveSample g;
    if (glove_ && glove_->latest(g)) {
      bend_[index_of(haptic_)] = g.joints;
      fresh = true;
    }
    if (other_glove_ && other_glove_->latest(g)) {
      bend_[1 - index_of(haptic_)] = g.joints;
      fresh = true;
    }
    if (!fresh || !have_sample_) return false;
    const NatNetSample::Body* head = sample_.find(cfg_.head_body_id);
    NatNetSample::Body hmd;
    std::int64_t motion_ns = sample_.mid_exposure_ns;
    if (cfg_.head_from_hmd) {  // the headset's pose stands for the head body's
      std::int64_t hmd_ns = 0;
      hmd.valid = hmd.present = cfg_.head_from_hmd(hmd.pose, hmd_ns);
      head = &hmd;
      if (hmd.valid) motion_ns = std::min(motion_ns, hmd_ns);
    }
    const bool head_valid = head && head->valid;
    const auto body = [&](std::int32_t id) -> const NatNetSample::Body* {
      const auto* b = id >= 0 ? sample_.find(id) : nullptr;
      return b && b->valid && head_valid ? b : nullptr;
    };
    HandState cur = previous_;
    const std::size_t h = index_of(haptic_);
    cur.head_valid = head_valid;
    if (head_valid) cur.R_BaseCamera = operator_head_in_base(cfg_.hand.R_CameraHead, head->pose);
    for (const Side side : kSides) {
      const std::size_t i = index_of(side);
      const HandModelConfig& hc = hand_cfg_[i];
      ArmTrack& arm = cur.arms[i];
      const auto* hand = body(hand_id_[i]);
      arm.wrist_valid = arm.wrist_orientation = hand != nullptr;
      if (hand) {
        const HandPoints pts = hand_forward(hc, hand->pose, bend_[i]);
        if (i == h) {
          // Velocities use the server's frame stamps (jitter-free), so they only change with a
          // new mocap frame; a glove-only update moves the fingers and keeps the last velocity.
          fill_hand_state(hc, head->pose, pts,
                          static_cast<std::int64_t>(std::llround(sample_.timestamp_s * 1e9)), cur);
          if (mocap_fresh) update_velocities(previous_, cur);
        }
        arm.X_CameraWrist.p_m = world_to_camera(hc, head->pose, hand->pose.p_m);
        arm.X_CameraWrist.q =
            glm::quat_cast(hc.R_CameraHead * glm::mat3_cast(glm::conjugate(head->pose.q))) *
            hand->pose.q;
        for (std::size_t f = 0; f < kFingerCount; ++f)
          for (std::size_t j = 0; j < 4; ++j)
            arm.joints_camera[f][j] = world_to_camera(hc, head->pose, pts.joints[f][j]);
      } else if (i == h) {
        for (auto& t : cur.tips) t.valid = false;
        cur.skeleton_valid = false;
      }
      const auto* shoulder = body(shoulder_id_[i]);
      arm.shoulder_valid = shoulder != nullptr;
      if (shoulder) arm.p_CameraShoulder = world_to_camera(hc, head->pose, shoulder->pose.p_m);
      const auto* elbow = body(elbow_id_[i]);
      arm.elbow_valid = elbow != nullptr;
      if (elbow) arm.p_CameraElbow = world_to_camera(hc, head->pose, elbow->pose.p_m);
    }
    cur.shoulder_valid = cur.arms[h].shoulder_valid;
    if (cur.shoulder_valid) cur.shoulder_camera = cur.arms[h].p_CameraShoulder;
    cur.body_count = 0;
    for (const auto& b : sample_.bodies) {
      if (!b.present || cur.body_count >= kMaxTrackedBodies) continue;
      cur.bodies[static_cast<std::size_t>(cur.body_count++)] = {b.id, b.pose.p_m, b.pose.q,
                                                                b.valid};
    }
    cur.bodies_fresh = mocap_fresh;
    cur.bodies_sampled_ns = sample_.mid_exposure_ns;
    previous_ = cur;
    out = cur;
    out.time_ns = mocap_ns_;
    out.motion_ns = motion_ns;
    ++stats_.updates;
    return true;
  }

  std::string name() const override { return name_; }
  std::string scheduling() const override { return client_->scheduling(); }
  std::vector<TrackerInput> inputs() const override {
    std::vector<TrackerInput> in{natnet_input_};
    in[0].frames = client_->stats().frames;
    // A server that answers the connect request but sends no frame is another case.
    if (const auto info = client_->server_info())
      in[0].check = "Motive answered the connect request (NatNet " +
                    std::to_string(info->natnet_version.major) + "." +
                    std::to_string(info->natnet_version.minor) +
                    ") but no frame came: is Broadcast Frame Data on in its Streaming pane? " +
                    in[0].check;
    for (const auto* gl : {glove_.get(), other_glove_.get()})
      if (gl != nullptr) in.push_back(glove_input(*gl));
    return in;
  }
  std::optional<ThreadFaultReport> thread_fault() const override {
    if (auto f = client_->thread_fault()) return f;
    for (const auto* gl : {glove_.get(), other_glove_.get()})
      if (gl != nullptr)
        if (auto f = gl->thread_fault()) return f;
    return std::nullopt;
  }
  TrackerStats stats() const override {
    TrackerStats s = stats_.snapshot();
    const auto c = client_->stats();
    s.frames_in = c.frames;
    s.frames_dropped = client_->overwritten();
    s.parse_errors = c.parse_errors;
    s.io_errors = c.io_errors;
    s.foreign_datagrams = c.foreign_datagrams;
    s.frame_jumps = c.frame_jumps;
    s.rejected_nonfinite = c.rejected_nonfinite;
    s.rejected_quaternion = c.rejected_quaternion;
    s.rejected_too_fast = c.rejected_too_fast;
    s.thread_faults = c.thread_faults;
    for (const auto* gl : {glove_.get(), other_glove_.get()}) {
      if (!gl) continue;
      s.frames_in += gl->reports();
      s.frames_dropped += gl->overwritten();
      s.parse_errors += gl->bad_reports();
      s.io_errors += gl->read_errors();
      s.thread_faults += gl->thread_faults();
    }
    return s;
  }

 private:
  TrackerConfig cfg_;
  Side haptic_ = Side::Right;
  std::array<HandModelConfig, 2> hand_cfg_;  // by Side
  std::unique_ptr<GloveDevice> glove_, other_glove_;
  std::unique_ptr<NatNetClient> client_;
  std::array<std::int32_t, 2> hand_id_{-1, -1}, shoulder_id_{-1, -1}, elbow_id_{-1, -1};
  NatNetSample sample_, incoming_;  // the last frame taken, and the newest before it is checked
  bool have_sample_ = false;
  std::int64_t mocap_ns_ = 0;         // poll time of the last frame taken
  std::array<JointBends, 2> bend_{};  // each joint's bend by Side: the glove's, or the default
  HandState previous_;
  std::string name_;
  TrackerInput natnet_input_;  // its text; frames filled in by inputs()
  TrackerCounters stats_;
};

// A glove without a mocap system: the wrist is held at a fixed pose in front of the camera with the
// fingers pointing into the scene, so finger bends alone move the tips.
class GloveTracker final : public HandTracker {
 public:
  GloveTracker(std::unique_ptr<GloveDevice> glove, const TrackerConfig& cfg)
      : glove_(std::move(glove)) {
    hand_cfg_ = cfg.hand;
    if (cfg.use_left_hand) static_cast<HandGeometry&>(hand_cfg_) = cfg.left_hand;
    hand_cfg_.left = cfg.use_left_hand;
    // The tracking "world" is the camera frame itself.
    hand_cfg_.p_HeadCamera = glm::dvec3{0.0};
    hand_cfg_.R_CameraHead = glm::dmat3(1.0);
    // Hand x (fingers) -> camera +z, hand y (back of hand) -> camera -y (up), z = x cross y.
    const glm::dmat3 R{glm::dvec3{0, 0, 1}, glm::dvec3{0, -1, 0}, glm::dvec3{1, 0, 0}};
    wrist_.q = glm::quat_cast(R);
    wrist_.p_m = cfg.p_CameraGloveWrist;
  }
  bool poll(std::int64_t now_ns, HandState& out) override {
    ++stats_.polls;
    GloveSample g;
    if (!glove_->latest(g)) return false;
    HandState cur;
    fill_hand_state(hand_cfg_, Pose{}, hand_forward(hand_cfg_, wrist_, g.joints), g.received_ns,
                    cur);
    if (have_previous_) update_velocities(previous_, cur);
    previous_ = cur;
    have_previous_ = true;
    out = cur;
    out.time_ns = now_ns;
    out.motion_ns = g.received_ns;
    ++stats_.updates;
    return true;
  }
  std::string name() const override { return glove_->name(); }
  TrackerStats stats() const override {
    TrackerStats s = stats_.snapshot();
    s.frames_in = glove_->reports();
    s.frames_dropped = glove_->overwritten();
    s.parse_errors = glove_->bad_reports();
    s.io_errors = glove_->read_errors();
    s.thread_faults = glove_->thread_faults();
    return s;
  }
  std::optional<ThreadFaultReport> thread_fault() const override { return glove_->thread_fault(); }
  std::vector<TrackerInput> inputs() const override { return {glove_input(*glove_)}; }

 private:
  std::unique_ptr<GloveDevice> glove_;
  HandModelConfig hand_cfg_;
  Pose wrist_;
  HandState previous_;
  bool have_previous_ = false;
  TrackerCounters stats_;
};

}  // namespace

std::unique_ptr<HandTracker> make_natnet_tracker(const std::string& spec,
                                                 const TrackerConfig& cfg) {
  NatNetClientConfig c;
  c.command_port = cfg.natnet_command_port;
  c.data_port = cfg.natnet_data_port;
  c.multicast_group = cfg.natnet_multicast_group;
  c.local_address = cfg.natnet_local_address;
  c.realtime_priority = cfg.realtime_priority;
  c.receive_hook = cfg.natnet_receive_hook;
  c = parse_natnet_spec(std::string_view(spec).substr(7), "tracker spec '" + spec + "'", c);
  std::unique_ptr<GloveDevice> glove, other_glove;
  const std::size_t haptic = index_of(cfg.use_left_hand ? Side::Left : Side::Right);
  if (!cfg.glove_spec.empty())
    glove = open_glove(cfg.glove_spec, cfg.glove_calibration_path, cfg.glove_range[haptic]);
  if (!cfg.other_glove_spec.empty())
    other_glove = open_glove(cfg.other_glove_spec, "", cfg.glove_range[1 - haptic]);
  return std::make_unique<NatNetTracker>(std::move(c), cfg, std::move(glove),
                                         std::move(other_glove));
}

std::unique_ptr<HandTracker> make_glove_tracker(std::unique_ptr<GloveDevice> glove,
                                                const TrackerConfig& cfg) {
  return std::make_unique<GloveTracker>(std::move(glove), cfg);
}

}  // namespace telex::local
