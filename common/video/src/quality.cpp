// SPDX-License-Identifier: MIT
// PSNR, SSIM and the moving stereo test scene.
#include "telex/video/quality.h"

#include <cmath>
#include <opencv2/imgproc.hpp>

#include "telex/base/demand.h"

namespace telex::video {

double psnr_db(const cv::Mat3b& source, const cv::Mat3b& decoded) {
  TELEX_DEMAND(source.size() == decoded.size());
  const double err = cv::norm(source, decoded, cv::NORM_L2SQR);
  if (err == 0.0) return 100.0;
  const double mse = err / (static_cast<double>(source.total()) * 3.0);
  return 10.0 * std::log10(255.0 * 255.0 / mse);
}

double ssim(const cv::Mat3b& source, const cv::Mat3b& decoded) {
  TELEX_DEMAND(source.size() == decoded.size());
  constexpr double kC1 = (0.01 * 255) * (0.01 * 255), kC2 = (0.03 * 255) * (0.03 * 255);
  cv::Mat x, y, gray;
  cv::cvtColor(source, gray, cv::COLOR_BGR2GRAY);
  gray.convertTo(x, CV_32F);
  cv::cvtColor(decoded, gray, cv::COLOR_BGR2GRAY);
  gray.convertTo(y, CV_32F);
  const auto blur = [](const cv::Mat& m) {
    cv::Mat out;
    cv::GaussianBlur(m, out, cv::Size(11, 11), 1.5);
    return out;
  };
  const cv::Mat mu_x = blur(x), mu_y = blur(y);
  const cv::Mat mu_xx = mu_x.mul(mu_x), mu_yy = mu_y.mul(mu_y), mu_xy = mu_x.mul(mu_y);
  const cv::Mat var_x = blur(x.mul(x)) - mu_xx, var_y = blur(y.mul(y)) - mu_yy;
  const cv::Mat cov_xy = blur(x.mul(y)) - mu_xy;
  cv::Mat num = (2 * mu_xy + kC1).mul(2 * cov_xy + kC2);
  cv::Mat den = (mu_xx + mu_yy + kC1).mul(var_x + var_y + kC2);
  cv::Mat map;
  cv::divide(num, den, map);
  return cv::mean(map)[0];
}

namespace {
// The backdrop: smooth colour gradients under a fixed-seed texture, the same every frame.
const cv::Mat3b& backdrop(cv::Size size) {
  thread_local cv::Mat3b cached;
  if (cached.size() == size) return cached;
  cv::Mat3f f(size);
  for (int y = 0; y < size.height; ++y)
    for (int x = 0; x < size.width; ++x) {
      const float u = static_cast<float>(x) / size.width, v = static_cast<float>(y) / size.height;
      f(y, x) = cv::Vec3f(60 + 120 * u, 80 + 100 * v, 150 - 60 * u * v) +
                cv::Vec3f(1, 1, 1) * 25.0f * std::sin(40.0f * u) * std::cos(23.0f * v);
    }
  cv::Mat3f texture(size);
  cv::RNG rng(0x7e1e);
  rng.fill(texture, cv::RNG::NORMAL, 0.0, 30.0);
  cv::GaussianBlur(texture, texture, cv::Size(0, 0), 2.0);
  cv::Mat3f sum = f + texture;
  sum.convertTo(cached, CV_8UC3);
  return cached;
}

// The shapes at frame `index`: near ones (larger disparity) move faster.
void draw_shapes(int index, cv::Size size, int eye_sign, cv::Mat3b& img) {
  const double t = index / 30.0;
  const double s = size.width / 1280.0;
  for (int k = 0; k < 6; ++k) {
    const double depth = 1.0 + 0.5 * k;  // metres, for the disparity only
    const int disparity_px = static_cast<int>(std::lround(eye_sign * 24.0 * s / depth));
    const double phase = 1.3 * k;
    const int cx = static_cast<int>(size.width * (0.5 + 0.4 * std::sin(0.7 * t / depth + phase))) +
                   disparity_px;
    const int cy = static_cast<int>(size.height * (0.5 + 0.35 * std::cos(0.9 * t + phase)));
    const cv::Scalar colour(40 + 35 * k, 220 - 30 * k, 90 + 25 * (k % 3));
    const int r = static_cast<int>((30 + 12 * k) * s);
    if (k % 2 == 0)
      cv::circle(img, {cx, cy}, r, colour, cv::FILLED, cv::LINE_AA);
    else
      cv::rectangle(img, cv::Rect(cx - r, cy - r / 2, 2 * r, r), colour, cv::FILLED);
    cv::putText(img, std::to_string(k), {cx - r / 3, cy + r / 3}, cv::FONT_HERSHEY_SIMPLEX, s * 1.2,
                cv::Scalar(255, 255, 255) - colour, 2, cv::LINE_AA);
  }
}
}  // namespace

void render_moving_eyes(int index, cv::Size eye_size, double noise, cv::Mat3b& left_bgr,
                        cv::Mat3b& right_bgr) {
  const cv::Mat3b& back = backdrop(cv::Size(eye_size.width + 64, eye_size.height));
  // The far backdrop shifts a little between the eyes (8 px at 1280 wide).
  const int shift = static_cast<int>(std::lround(8.0 * eye_size.width / 1280.0));
  back(cv::Rect(32 - shift, 0, eye_size.width, eye_size.height)).copyTo(left_bgr);
  back(cv::Rect(32 + shift, 0, eye_size.width, eye_size.height)).copyTo(right_bgr);
  draw_shapes(index, eye_size, -1, left_bgr);
  draw_shapes(index, eye_size, +1, right_bgr);
  if (noise <= 0.0) return;
  cv::RNG rng(0x5eed + static_cast<std::uint64_t>(index));
  cv::Mat3s grain(eye_size);
  for (cv::Mat3b* eye : {&left_bgr, &right_bgr}) {
    rng.fill(grain, cv::RNG::NORMAL, 0.0, noise);
    cv::Mat3s sum;
    eye->convertTo(sum, CV_16SC3);
    sum += grain;
    sum.convertTo(*eye, CV_8UC3);
  }
}

}  // namespace telex::video
