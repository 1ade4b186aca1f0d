// SPDX-License-Identifier: MIT
// The rig file's keys -> the station's configuration (before the flags, which override them).
#include "telex/local/station/station.h"

namespace telex::local {

void apply_rig(const Rig& rig, StationConfig& cfg) {
  TrackerConfig& t = cfg.tracker;
  cfg.X_NatNetStage = rig.X_NatNetStage;
  t.head_body_id = rig.bodies.head;
  t.right_hand_body_id = rig.bodies.right_hand;
  t.left_hand_body_id = rig.bodies.left_hand;
  t.right_shoulder_body_id = rig.bodies.right_shoulder;
  t.left_shoulder_body_id = rig.bodies.left_shoulder;
  t.right_elbow_body_id = rig.bodies.right_elbow;
  t.left_elbow_body_id = rig.bodies.left_elbow;
  t.hand.p_HeadCamera = rig.p_HeadCamera;
  t.hand.R_CameraHead = rig.R_CameraHead;
  static_cast<HandGeometry&>(t.hand) = rig.body.hands[index_of(Side::Right)];
  t.left_hand = rig.body.hands[index_of(Side::Left)];
  t.glove_range = rig.glove;
  cfg.body = rig.body;
  cfg.skin_bgr = {static_cast<unsigned char>(rig.skin_rgb[2]),
                  static_cast<unsigned char>(rig.skin_rgb[1]),
                  static_cast<unsigned char>(rig.skin_rgb[0])};
  cfg.robot_head = rig.robot_head;
  cfg.eye_camera = rig.eye;
  if (rig.X_RightEyeLeftEye) cfg.R_RightEyeLeftEye = rig.X_RightEyeLeftEye->rotation;
  if (const auto b = rig.baseline_m()) cfg.stereo_baseline_m = *b;
  cfg.display_channel = rig.display_channel;
  cfg.display.gravity_grabber = rig.gravity_grabber;
}

}  // namespace telex::local
