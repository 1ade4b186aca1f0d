// SPDX-License-Identifier: MIT
// The operator's stereo view: body capsules from the tracked hand, the remote depth registered to
// the left eye, both eyes rendered, the overlay drawn to fit.
#include "telex/local/stereo_view.h"

#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "telex/common/colorize.h"
#include "telex/common/registration.h"
#include "telex/local/status_band.h"

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

// The overlay: the normal-map inset (top right, a quarter of the width) and the status text,
// wrapped to fit the width.
void overlay(cv::Mat3b& img, const StereoViewInputs& in) {
  if (in.surface != nullptr && !in.surface->normals.empty()) {
    const cv::Mat3b inset = colorize_normals(in.surface->normals);
    const int w = img.cols / 4, h = w * inset.rows / std::max(1, inset.cols);
    if (w > 0 && h > 0 && h < img.rows) {
      cv::Mat3b small;
      cv::resize(inset, small, {w, h}, 0, 0, cv::INTER_AREA);
      small.copyTo(img(cv::Rect(img.cols - w - 4, 4, w, h)));
    }
  }
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
    out.push_back({p, p, 0.010, pressure_bgr(f.normal_force_N)});
    const glm::dvec3 end = p + f.force_N * in.arrow_m_per_N;
    if (glm::length(end - p) > 1e-4) {
      out.push_back({p, end, 0.002, {0, 200, 255}});
      out.push_back({end, end, 0.004, {0, 200, 255}});
    }
  }
  return out;
}

EyeRectifier::EyeRectifier(CameraModel camera, const glm::dmat3& R_TargetEye)
    : camera_(camera), R_TargetEye_(R_TargetEye) {}

cv::Mat3b EyeRectifier::apply(const cv::Mat3b& image, const Intrinsics& target) {
  if (image.empty()) return image;
  if (image.size() != for_size_ || !(target == for_target_)) {
    const Intrinsics k = camera_.k.width == image.cols && camera_.k.height == image.rows
                             ? camera_.k
                             : camera_.k.scaled(image.cols, image.rows);
    const cv::Matx33d K(k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1);
    const cv::Matx33d P(target.fx, 0, target.cx, 0, target.fy, target.cy, 0, 0, 1);
    cv::Matx33d R;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) R(r, c) = R_TargetEye_[c][r];  // glm is column-major
    cv::initUndistortRectifyMap(K, camera_.distortion, R, P, {target.width, target.height},
                                CV_16SC2, map1_, map2_);
    for_size_ = image.size();
    for_target_ = target;
  }
  cv::Mat3b out;
  cv::remap(image, out, map1_, map2_, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
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

bool StereoView::prepare(const StereoViewInputs& in, std::array<EyeView, 2>& views,
                         std::vector<Capsule>& capsules) {
  const cv::Size size(in.k.width, in.k.height);
  if (!renderer_ || size != cv::Size(renderer_size_.width, renderer_size_.height)) {
    renderer_.reset();  // before the next one, when both share the current context
    renderer_ = current_context_ ? std::make_unique<StereoRenderer>(
                                       size.width, size.height, StereoRenderer::UseCurrentContext{})
                                 : std::make_unique<StereoRenderer>(size.width, size.height);
    renderer_size_ = size;
  }
  const auto fit = [&size](const cv::Mat3b& m) {
    if (m.empty() || m.size() == size) return m;
    cv::Mat3b r;
    cv::resize(m, r, size, 0, 0, cv::INTER_AREA);
    return r;
  };
  // A calibrated eye is undistorted (and the left one rectified) into the depth's camera; an
  // uncalibrated one is only resized to it.
  const auto bring = [&](std::size_t i) {
    return rectifier_[i] ? rectifier_[i]->apply(in.eye_bgr[i], in.k) : fit(in.eye_bgr[i]);
  };
  std::array<cv::Mat3b, 2> eye{bring(0), bring(1)};
  const bool one_eye = eye[0].empty() != eye[1].empty();
  if (eye[0].empty()) eye[0] = eye[1];
  if (eye[1].empty()) eye[1] = eye[0];

  capsules = view_capsules(body_, in);
  EyeView& right = views[index_of(Side::Right)];
  EyeView& left = views[index_of(Side::Left)];
  right.k = left.k = in.k;
  left.p_RightEye = {-in.baseline_m, 0.0, 0.0};
  right.background = eye[index_of(Side::Right)];
  left.background = eye[index_of(Side::Left)];
  if (!in.depth_mm.empty() && in.depth_mm.size() == size) {
    right.depth_mm = in.depth_mm;
    // The remote depth is registered to the right eye; the left eye sees it from B to the left.
    const RigidTransform X_LeftRight{glm::dmat3(1.0), glm::dvec3(in.baseline_m, 0.0, 0.0)};
    left.depth_mm = reproject_depth({in.depth_mm, in.k}, in.k, X_LeftRight).depth_mm;
  }
  return one_eye;
}

StereoViewImages StereoView::render(const StereoViewInputs& in) {
  StereoViewImages out;
  std::array<EyeView, 2> views;
  std::vector<Capsule> capsules;
  out.one_eye = prepare(in, views, capsules);
  out.right = renderer_->render(views[index_of(Side::Right)], capsules);
  out.left = renderer_->render(views[index_of(Side::Left)], capsules);
  overlay(out.left, in);
  overlay(out.right, in);
  cv::hconcat(out.left, out.right, out.sbs);
  return out;
}

void StereoView::render_into(const StereoViewInputs& in, const std::array<GlTarget, 2>& targets) {
  std::array<EyeView, 2> views;
  std::vector<Capsule> capsules;
  prepare(in, views, capsules);
  for (const Side side : kSides) {
    EyeView& v = views[index_of(side)];
    v.read_back = false;
    renderer_->render(v, capsules);
    const GlTarget& t = targets[index_of(side)];
    renderer_->blit_to(t.texture, t.width, t.height);
  }
}

}  // namespace telex::local
