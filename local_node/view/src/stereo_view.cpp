// SPDX-License-Identifier: MIT
// The operator's stereo view: body capsules from the tracked hand, the remote depth registered to
// the left eye, both eyes rendered, the overlay drawn to fit.
#include "telex/local/view/stereo_view.h"

#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "telex/base/demand.h"
#include "telex/common/colorize.h"
#include "telex/common/registration.h"
#include "telex/local/view/fig7_view.h"
#include "telex/local/view/operator_view.h"
#include "telex/local/view/status_band.h"
#include "telex/video/frame_counter.h"

namespace telex::local {
namespace {

// The body is solved in the right eye's frame: its up is the camera's -y (a level head assumed).
BodyDims camera_frame_body(BodyDims d) {
  d.up_world = {0.0, -1.0, 0.0};
  return d;
}

// Green (light touch) to red (3 N and more).
cv::Vec3b pressure_bgr(double n) {
  const double t = std::clamp(n / 3.0, 0.0, 1.0);
  return {40, static_cast<unsigned char>(220 * (1.0 - t)),
          static_cast<unsigned char>(80 + 175 * t)};
}

// The overlay: the normal-map inset with the haptic path's windows outlined (none when empty)
// and the status text, wrapped to fit the width.
void overlay(cv::Mat3b& img, const StereoViewInputs& in, const cv::Mat3b& inset) {
  paste_normal_inset(img, inset);
  draw_status_band(img, in.status, 0.45, 1);
}

}  // namespace

std::optional<std::size_t> nearest_capture(std::span<const std::int64_t> captures,
                                           std::int64_t want_ns) {
  std::optional<std::size_t> best;
  for (std::size_t i = 0; i < captures.size(); ++i) {
    const auto gap = [&](std::size_t k) {
      const std::int64_t d = captures[k] - want_ns;
      return d < 0 ? -static_cast<std::uint64_t>(d) : static_cast<std::uint64_t>(d);
    };
    if (!best || gap(i) < gap(*best)) best = i;
  }
  return best;
}

std::vector<Capsule> view_capsules(Body& body, const StereoViewInputs& in) {
  const HandState& hand = in.hand;
  BodyInputs bi;
  bi.time_ns = hand.time_ns;
  // Per side, the hand's joints as the tracker chained them (its own glove bends and geometry).
  std::array<const std::array<std::array<glm::dvec3, 4>, kFingerCount>*, 2> joints{};
  for (const Side side : kSides) {
    const std::size_t i = index_of(side);
    const ArmTrack& a = hand.arms[i];
    const auto shoulder = [&](bool valid, const glm::dvec3& p) {
      return Pose{valid ? p : in.default_shoulder_camera[i], {1.0, 0.0, 0.0, 0.0}};
    };
    if (a.wrist_valid) {  // a tracked hand body: its orientation, shoulder and elbow if tracked
      bi.wrist[i] = a.X_CameraWrist;
      bi.wrist_orientation[i] = a.wrist_orientation;
      bi.shoulder[i] = shoulder(a.shoulder_valid, a.p_CameraShoulder);
      if (a.elbow_valid) bi.elbow[i] = a.p_CameraElbow;
      joints[i] = &a.joints_camera;
    } else if (side == Side::Right && hand.skeleton_valid) {  // a scripted or glove-only hand
      bi.wrist[i] = Pose{hand.wrist_camera, {1.0, 0.0, 0.0, 0.0}};
      bi.wrist_orientation[i] = false;
      bi.shoulder[i] = shoulder(hand.shoulder_valid, hand.shoulder_camera);
      joints[i] = &hand.joints_camera;
    }
  }
  BodyState state = body.update(bi);
  for (const Side side : kSides) {
    ArmState& arm = state.arms[index_of(side)];
    if (!arm.visible || joints[index_of(side)] == nullptr) continue;
    for (std::size_t f = 0; f < kFingerCount; ++f)
      for (std::size_t j = 0; j < 4; ++j) arm.hand.joints[f][j] = (*joints[index_of(side)])[f][j];
  }
  std::vector<Capsule> out = body_capsules(
      state, [](const glm::dvec3& p) { return p; }, in.skin_bgr);
  // Fingertips in contact: a marker at the god-point on the remote surface (the finger itself
  // is inside the surface then, hidden by it), coloured by pressure, and the force as an arrow (a
  // thin capsule with a round head) from it.
  for (std::size_t i = 0; i < kFingerCount; ++i) {
    const FingertipForce& f = in.forces[i];
    if (!hand.tips[i].valid || !f.contact) continue;
    const glm::dvec3 p = f.p_ModelProxy;
    out.push_back({p, p, 0.010, pressure_bgr(f.normal_force_N), false});
    const glm::dvec3 end = p + f.force_N * in.arrow_m_per_N;
    if (glm::length(end - p) > 1e-4) {
      out.push_back({p, end, 0.002, {0, 200, 255}, false});
      out.push_back({end, end, 0.004, {0, 200, 255}, false});
    }
  }
  return out;
}

std::vector<glm::dvec3> view_fingertips(const HandState& hand) {
  std::vector<glm::dvec3> out;
  bool right_tracked = false;
  for (const Side side : kSides) {
    const ArmTrack& a = hand.arms[index_of(side)];
    if (!a.wrist_valid) continue;
    right_tracked = right_tracked || side == Side::Right;
    for (const auto& finger : a.joints_camera) out.push_back(finger[3]);
  }
  if (!right_tracked && hand.skeleton_valid)
    for (const auto& finger : hand.joints_camera) out.push_back(finger[3]);
  return out;
}

EyeRectifier::EyeRectifier(CameraModel camera, const glm::dmat3& R_TargetEye)
    : camera_(camera), R_TargetEye_(R_TargetEye) {}

cv::Mat3b EyeRectifier::apply(const cv::Mat3b& image, const Intrinsics& target,
                              const cv::Scalar& border, const glm::dmat3& R_DisplayTarget) {
  if (image.empty()) return image;
  if (image.size() != for_size_ || !(target == for_target_) ||
      R_DisplayTarget != for_R_DisplayTarget_) {
    const Intrinsics k = camera_.k.width == image.cols && camera_.k.height == image.rows
                             ? camera_.k
                             : camera_.k.scaled(image.cols, image.rows);
    const cv::Matx33d K(k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1);
    const cv::Matx33d P(target.fx, 0, target.cx, 0, target.fy, target.cy, 0, 0, 1);
    // OpenCV's rectification: p_Display = R p_Eye.
    const glm::dmat3 R_DisplayEye = R_DisplayTarget * R_TargetEye_;
    cv::Matx33d R;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) R(r, c) = R_DisplayEye[c][r];  // glm is column-major
    cv::initUndistortRectifyMap(K, camera_.distortion, R, P, {target.width, target.height},
                                CV_16SC2, map1_, map2_);
    for_size_ = image.size();
    for_target_ = target;
    for_R_DisplayTarget_ = R_DisplayTarget;
  }
  cv::Mat3b out;
  cv::remap(image, out, map1_, map2_, cv::INTER_LINEAR, cv::BORDER_CONSTANT, border);
  return out;
}

void StereoView::set_eye_cameras(const std::array<std::optional<CameraModel>, 2>& eyes,
                                 const glm::dmat3& R_RightEyeLeftEye) {
  for (const Side side : kSides) {
    auto& r = rectifier_[index_of(side)];
    r.reset();
    if (eyes[index_of(side)])
      r.emplace(*eyes[index_of(side)], side == Side::Left ? R_RightEyeLeftEye : glm::dmat3(1.0));
  }
}

StereoView::StereoView(const BodyDims& dims) : body_(camera_frame_body(dims)) {}
StereoView::StereoView(int width, int height, const BodyDims& dims)
    : renderer_(std::make_unique<StereoRenderer>(width, height)),
      renderer_size_(width, height),
      body_(camera_frame_body(dims)) {}
StereoView::~StereoView() = default;

void StereoView::warp_eyes(const StereoViewInputs& in, std::array<EyeView*, 2> eyes) {
  const glm::dmat3 R_DisplayBase = glm::transpose(*in.R_BaseDisplay);
  const glm::dmat3 R_DisplayDepth = R_DisplayBase * *in.R_BaseDepth;
  // The video's own capture pose, when the pair carried it; else the depth's.
  const glm::dmat3 R_VideoDepth =
      in.R_BaseVideo ? glm::transpose(*in.R_BaseVideo) * *in.R_BaseDepth : glm::dmat3(1.0);
  const glm::dmat3 R_DisplayPrevious =
      R_BasePreviousDisplay_ ? R_DisplayBase * *R_BasePreviousDisplay_ : glm::dmat3(1.0);
  R_BasePreviousDisplay_ = in.R_BaseDisplay;
  for (const Side side : kSides) {
    EyeView& e = *eyes[index_of(side)];
    auto& w = warp_[index_of(side)];
    // The warped picture stays in the renderer's context (the warp is made in it): no read-back.
    if (!w)
      w = std::make_unique<DepthWarp>(e.k.width, e.k.height, WarpOptions{.read_back_bgr = false});
    // The eye's images are in its own (turned) frame, which the head carries as it does the
    // camera's: each motion of the camera-aligned eye, re-expressed in the turned one.
    const glm::dmat3& R = e.R_EyeRight;
    const auto turned = [&R](const RigidTransform& X) {
      return RigidTransform{R * X.rotation * glm::transpose(R), R * X.translation_m};
    };
    WarpedEye warped = w->warp(e.background, e.depth_mm, e.k,
                               turned(eye_display_from_capture(R_DisplayDepth, e.p_RightEye)),
                               turned(eye_display_from_capture(R_VideoDepth, e.p_RightEye)),
                               R * R_DisplayPrevious * glm::transpose(R));
    // The captured picture stays as the background's: the skin's exposure is taken from it.
    e.background_texture = warped.texture;
    e.depth_mm = std::move(warped.depth_mm);
  }
}

void StereoView::prepare_geometry(const StereoViewInputs& in, std::array<EyeView, 2>& views,
                                  std::vector<Capsule>& capsules) {
  const cv::Size depth_size(in.k.width, in.k.height);
  cv::Size size = in.eye_size;
  if (size.empty()) {
    const cv::Mat3b& video = in.eye_bgr[1].empty() ? in.eye_bgr[0] : in.eye_bgr[1];
    size = video.empty() ? depth_size : video.size();
  }
  k_eye_ = size == depth_size ? in.k : eye_intrinsics(in.k, size);
  // Each eye's pinhole, by Side: the display's when given, else the eyes' camera.
  k_drawn_ = {k_eye_, k_eye_};
  outside_ = cv::Scalar();  // beyond the camera's field: black in its own pinhole
  if (in.display_k[0] && in.display_k[1]) {
    k_drawn_ = {*in.display_k[0], *in.display_k[1]};
    size = {k_drawn_[1].width, k_drawn_[1].height};
    TELEX_DEMAND(k_drawn_[0].width == size.width && k_drawn_[0].height == size.height);
    k_eye_ = k_drawn_[1];
    outside_ = kOutsideCameraBgr;
  }
  if (!renderer_ || size != cv::Size(renderer_size_.width, renderer_size_.height)) {
    for (auto& w : warp_) w.reset();  // their objects live in the old renderer's context
    renderer_.reset();  // before the next one: its end releases the thread's current context
    renderer_ = current_context_ ? std::make_unique<StereoRenderer>(
                                       size.width, size.height, StereoRenderer::UseCurrentContext{})
                                 : std::make_unique<StereoRenderer>(size.width, size.height);
    renderer_size_ = size;
  }
  capsules = view_capsules(body_, in);
  EyeView& right = views[index_of(Side::Right)];
  EyeView& left = views[index_of(Side::Left)];
  right.k = k_drawn_[index_of(Side::Right)];
  left.k = k_drawn_[index_of(Side::Left)];
  left.p_RightEye = {-in.baseline_m, 0.0, 0.0};
  // Each eye's display turned from its camera (identity but for a canted headset).
  right.R_EyeRight = glm::transpose(in.R_CameraDisplay[index_of(Side::Right)]);
  left.R_EyeRight = glm::transpose(in.R_CameraDisplay[index_of(Side::Left)]);
  right.fingertips = left.fingertips = view_fingertips(in.hand);
}

void StereoView::prepare_depth(const StereoViewInputs& in, std::array<EyeView, 2>& views) {
  if (in.depth_mm.empty() || in.depth_mm.size() != cv::Size(in.k.width, in.k.height)) return;
  EyeView& right = views[index_of(Side::Right)];
  EyeView& left = views[index_of(Side::Left)];
  // Once per depth frame: a display drawing faster than the depth comes draws the same eyes' depth.
  EyeDepths& c = eye_depths_;
  if (c.source.data == in.depth_mm.data && c.source.size() == in.depth_mm.size() && c.k == in.k &&
      c.baseline_m == in.baseline_m && c.R_CameraDisplay == in.R_CameraDisplay &&
      c.eye_k[0] == right.k && c.eye_k[1] == left.k) {
    right.depth_mm = c.right;
    left.depth_mm = c.left;
    return;
  }
  // The remote depth is registered to the right eye; the left eye sees it from B to the left.
  // Both are reprojected at the depth's size and then sampled (nearest: an occluding edge stays
  // an edge) at each eye pixel's ray.
  // p_Left = p_Right + (B, 0, 0): each point moves along its row (shift_depth_along_rows).
  // The strips the right eye could not see behind an edge, and the left border, are what the left
  // video shows there: given the depth behind, not left as holes the warp would outline.
  cv::Mat1w left_mm;
  shift_depth_along_rows(in.depth_mm, in.k.fx, in.baseline_m, left_mm);
  fill_disocclusions(left_mm, in.k.fx, in.baseline_m);
  right.depth_mm =
      resample_depth_turned(in.depth_mm, in.k, right.k, in.R_CameraDisplay[index_of(Side::Right)]);
  left.depth_mm =
      resample_depth_turned(left_mm, in.k, left.k, in.R_CameraDisplay[index_of(Side::Left)]);
  c = {in.depth_mm,       in.k,           in.baseline_m, in.R_CameraDisplay,
       {right.k, left.k}, right.depth_mm, left.depth_mm};
}

const cv::Mat3b& StereoView::normal_inset_for(const StereoViewInputs& in, cv::Mat3f& normals,
                                              cv::Size size) {
  InsetWork& c = inset_;
  const bool depth_fits =
      !in.depth_mm.empty() && in.depth_mm.size() == cv::Size(in.k.width, in.k.height);
  // Once per depth frame and surface, as the eyes' depth (the cache holds the depth, so its
  // buffer is not another frame's while it is here).
  if (depth_fits && c.depth.data == in.depth_mm.data && c.depth.size() == in.depth_mm.size() &&
      c.surface == in.surface && c.k == in.k && c.size == size) {
    normals = c.normals;
    return c.inset;
  }
  // The normal map the view shows: full-frame, computed here when the haptic path built only
  // fingertip windows. From the depth alone: before any video is taken.
  normals = depth_fits ? display_normals(in.depth_mm, in.k, in.surface) : cv::Mat3f();
  const std::vector<cv::Rect> windows = haptic_windows(in.surface, normals);
  c = {depth_fits ? in.depth_mm : cv::Mat1w(),
       in.surface,
       in.k,
       size,
       normals,
       normal_inset(normals, windows, size.width, size.height)};
  return c.inset;
}

bool StereoView::prepare_video(const StereoViewInputs& in, std::array<EyeView, 2>& views) {
  // Each eye's display turned from its camera (identity but for a canted headset), by Side.
  const std::array<glm::dmat3, 2>& R_CameraDisplay = in.R_CameraDisplay;
  // An uncalibrated eye is taken to see what the depth camera sees, scaled to its image's size.
  const auto fit = [&](const cv::Mat3b& m, std::size_t i) -> cv::Mat3b {
    if (m.empty()) return m;
    return resample_pinhole(m, in.k.scaled(m.cols, m.rows), k_drawn_[i], R_CameraDisplay[i],
                            cv::INTER_LINEAR, outside_);
  };
  // A synthetic eye's frame counter (telex/video/frame_counter.h) is read here, from the video
  // this frame draws, and painted over: measurable, never in front of the operator.
  const std::array<cv::Mat3b, 2> video = without_frame_counters(in.eye_bgr);
  // A calibrated eye is undistorted (and the left one rectified) into the eyes' pinhole camera.
  const auto bring = [&](std::size_t i) {
    return rectifier_[i] ? rectifier_[i]->apply(video[i], k_drawn_[i], outside_,
                                                glm::transpose(R_CameraDisplay[i]))
                         : fit(video[i], i);
  };
  std::array<cv::Mat3b, 2> eye{bring(0), bring(1)};
  const bool one_eye = eye[0].empty() != eye[1].empty();
  warped_ = false;
  // One eye's video serves both, in the other eye's pinhole (the same one unless display_k).
  const auto other = [&](std::size_t from, std::size_t to) {
    return resample_pinhole(eye[from], k_drawn_[from], k_drawn_[to],
                            glm::transpose(R_CameraDisplay[from]) * R_CameraDisplay[to],
                            cv::INTER_LINEAR, outside_);
  };
  if (eye[0].empty()) eye[0] = other(1, 0);
  if (eye[1].empty()) eye[1] = other(0, 1);
  EyeView& right = views[index_of(Side::Right)];
  EyeView& left = views[index_of(Side::Left)];
  right.background = eye[index_of(Side::Right)];
  left.background = eye[index_of(Side::Left)];
  if (!right.depth_mm.empty() && in.R_BaseDepth && in.R_BaseDisplay && !eye[0].empty()) {
    warp_eyes(in, {&left, &right});
    warped_ = true;
  }
  if (!warped_) {  // the next warp's holes must not take a picture from another pose
    for (auto& w : warp_)
      if (w) w->reset_previous();
    R_BasePreviousDisplay_.reset();
  }
  return one_eye;
}

std::array<cv::Mat3b, 2> StereoView::without_frame_counters(const std::array<cv::Mat3b, 2>& eyes) {
  std::array<cv::Mat3b, 2> out = eyes;
  frame_counter_.reset();
  for (std::size_t i = 0; i < out.size(); ++i) {
    if (out[i].empty()) continue;
    const auto counter = video::read_frame_counter(out[i]);
    if (!counter) continue;
    // The right eye's counter, or the only eye's.
    if (i == index_of(Side::Right) || !frame_counter_) frame_counter_ = counter;
    out[i] = out[i].clone();  // the pair is shared with the receiver: erased in a copy
    video::erase_frame_counter(out[i]);
  }
  return out;
}

bool StereoView::draw_bodies(const StereoViewInputs& early, const LateVideo& late_video,
                             StereoViewInputs& late, std::array<EyeView, 2>& views) {
  std::vector<Capsule> capsules;
  prepare_geometry(early, views, capsules);
  prepare_depth(early, views);
  late = early;
  // Without a late video the eyes' pictures are prepared first and light the skin; with one, the
  // body is drawn first, lit by the video at hand, and the newest video is then composed under
  // it: the pair shown is as young as the body's drawing allows.
  bool one_eye = late_video ? false : prepare_video(late, views);
  for (const Side side : kSides) {
    const std::size_t i = index_of(side);
    const cv::Mat3b& early_video =
        early.eye_bgr[i].empty() ? early.eye_bgr[1 - i] : early.eye_bgr[i];
    renderer_->draw_body_layer(static_cast<int>(i), views[i], capsules,
                               exposure_from_image(late_video ? early_video : views[i].background));
  }
  if (late_video) {
    renderer_->finish();
    late_video(late);
    one_eye = prepare_video(late, views);
  }
  return one_eye;
}

StereoViewImages StereoView::render(const StereoViewInputs& early, const LateVideo& late_video) {
  StereoViewImages out;
  // The inset once for both eyes, before any video is taken, at the size of the eyes drawn last
  // (again if these are not).
  const cv::Size inset_for = renderer_size_;
  cv::Mat3b inset = normal_inset_for(early, out.normals, inset_for);
  std::array<EyeView, 2> views;
  StereoViewInputs in;
  out.one_eye = draw_bodies(early, late_video, in, views);
  if (renderer_size_ != inset_for) inset = normal_inset_for(early, out.normals, renderer_size_);
  out.warped = warped_;
  out.frame_counter = frame_counter_;
  out.right = renderer_->compose(index_of(Side::Right), views[index_of(Side::Right)]);
  out.left = renderer_->compose(index_of(Side::Left), views[index_of(Side::Left)]);
  if (in.fig7) {
    cv::Mat3b interaction = out.right.clone();
    overlay(interaction, in, {});
    out.fig7 = fig7_layout(interaction, k_eye_, out.normals, in.k, in.forces, in.arrow_m_per_N);
  }
  if (in.overlays) {
    overlay(out.left, in, inset);
    overlay(out.right, in, inset);
  }
  cv::hconcat(out.left, out.right, out.sbs);
  return out;
}

void StereoView::render_into(const StereoViewInputs& in, const std::array<GlTarget, 2>& targets,
                             const LateVideo& late_video) {
  std::array<EyeView, 2> views;
  StereoViewInputs late;
  draw_bodies(in, late_video, late, views);
  for (const Side side : kSides) {
    EyeView& v = views[index_of(side)];
    v.read_back = false;
    renderer_->compose(index_of(side), v);
    const GlTarget& t = targets[index_of(side)];
    renderer_->blit_to(t.texture, t.width, t.height);
  }
}

}  // namespace telex::local
