// SPDX-License-Identifier: MIT
// Shaded colour renders of synthetic scenes for the synthetic stereo source.
#include "telex/remote/synthetic_view.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>

namespace telex::remote {
namespace {

using synth::Material;

const std::array<cv::Vec3f, 8> kBase = {cv::Vec3f(180, 180, 180), cv::Vec3f(90, 140, 200),
                                        cv::Vec3f(60, 170, 90),   cv::Vec3f(200, 120, 60),
                                        cv::Vec3f(80, 80, 210),   cv::Vec3f(190, 90, 170),
                                        cv::Vec3f(60, 200, 200),  cv::Vec3f(140, 110, 90)};

// Deterministic lattice noise in [0, 1): a hash of the integer cell, trilinearly interpolated
// with a smoothstep, summed over octaves. Patterns are functions of world position, so they are
// identical in both eyes and in every frame.
float hash3(int x, int y, int z) {
  std::uint32_t h = static_cast<std::uint32_t>(x) * 73856093u ^
                    static_cast<std::uint32_t>(y) * 19349663u ^
                    static_cast<std::uint32_t>(z) * 83492791u;
  h ^= h >> 13;
  h *= 0x5bd1e995u;
  h ^= h >> 15;
  return static_cast<float>(h & 0xffffu) / 65536.0f;
}

float value_noise(const glm::dvec3& p) {
  const glm::dvec3 f = glm::floor(p);
  const int x = static_cast<int>(f.x), y = static_cast<int>(f.y), z = static_cast<int>(f.z);
  const glm::dvec3 t = p - f;
  const glm::dvec3 s = t * t * (3.0 - 2.0 * t);
  auto lerp = [](double a, double b, double w) { return a + (b - a) * w; };
  const double c00 = lerp(hash3(x, y, z), hash3(x + 1, y, z), s.x);
  const double c10 = lerp(hash3(x, y + 1, z), hash3(x + 1, y + 1, z), s.x);
  const double c01 = lerp(hash3(x, y, z + 1), hash3(x + 1, y, z + 1), s.x);
  const double c11 = lerp(hash3(x, y + 1, z + 1), hash3(x + 1, y + 1, z + 1), s.x);
  return static_cast<float>(lerp(lerp(c00, c10, s.y), lerp(c01, c11, s.y), s.z));
}

float fbm(const glm::dvec3& p, int octaves) {
  float sum = 0.0f, amp = 0.5f, norm = 0.0f;
  glm::dvec3 q = p;
  for (int i = 0; i < octaves; ++i) {
    sum += amp * value_noise(q);
    norm += amp;
    amp *= 0.5f;
    q *= 2.03;
  }
  return sum / norm;
}

cv::Vec3f mix(const cv::Vec3f& a, const cv::Vec3f& b, float w) { return a + (b - a) * w; }

struct Surfel {
  cv::Vec3f albedo;    // BGR, 0..255
  float gloss = 0.0f;  // specular weight
  float shininess = 16.0f;
};

// Oak planks 0.14 m wide along z, 1.2 m long with staggered joints, dark seams, fine grain.
Surfel floorboards(const glm::dvec3& w) {
  const double plank_w = 0.14, plank_l = 1.2;
  const double u = w.x / plank_w;
  const int plank = static_cast<int>(std::floor(u));
  const double offset = hash3(plank, 7, 1) * plank_l;
  const double v = (w.z + offset) / plank_l;
  const int board = static_cast<int>(std::floor(v));
  const double fu = u - plank, fv = v - board;
  const float tone = 0.8f + 0.35f * hash3(plank, board, 3);
  const float grain = fbm({w.x * 60.0, 0.0, w.z * 4.0 + plank * 3.1}, 3);
  cv::Vec3f c = mix(cv::Vec3f(60, 105, 150), cv::Vec3f(85, 140, 190), grain) * tone;
  if (fu < 0.025 || fu > 0.975 || fv < 0.006) c *= 0.45f;  // seams and end joints
  return {c, 0.15f, 24.0f};
}

// Warm off-white, mottled at a few centimetres, a skirting board along the floor.
Surfel plaster(const glm::dvec3& w) {
  if (w.y > 0.9) return {cv::Vec3f(215, 220, 225), 0.1f, 12.0f};  // skirting, 10 cm
  const float m = fbm(w * 18.0, 4);
  return {mix(cv::Vec3f(170, 188, 200), cv::Vec3f(200, 214, 222), m), 0.0f, 8.0f};
}

// Walnut-like grain: rings along x bent by noise.
Surfel wood(const glm::dvec3& w) {
  const double bend = 0.6 * fbm({w.x * 3.0, w.y * 3.0, w.z * 3.0}, 3);
  const double ring = 0.5 + 0.5 * std::sin((w.z * 45.0 + bend * 12.0) + w.x * 2.0);
  const float fine = fbm({w.x * 200.0, w.y * 20.0, w.z * 20.0}, 2);
  const cv::Vec3f c =
      mix(cv::Vec3f(30, 62, 105), cv::Vec3f(55, 95, 145), static_cast<float>(ring)) *
      (0.85f + 0.3f * fine);
  return {c, 0.25f, 40.0f};
}

Surfel cardboard(const glm::dvec3& w, const glm::dvec3& n_w) {
  const float fibre = fbm(w * 90.0, 2);
  cv::Vec3f c = cv::Vec3f(95, 150, 190) * (0.9f + 0.2f * fibre);
  // Packing tape over the top, along z.
  const bool top = n_w.y < -0.8;
  if (top && std::abs(std::fmod(std::abs(w.x + 0.36), 1.0)) < 0.025) c = cv::Vec3f(150, 195, 220);
  return {c, top ? 0.1f : 0.02f, 10.0f};
}

// Glazed white with a blue band round its middle.
Surfel ceramic(const glm::dvec3& w) {
  const double band = std::fmod(std::abs(w.y) * 100.0, 10.0);
  const cv::Vec3f c = band > 4.0 && band < 6.0 ? cv::Vec3f(170, 90, 40) : cv::Vec3f(235, 238, 240);
  return {c, 0.9f, 60.0f};
}

Surfel metal(const glm::dvec3& w) {
  const float brush = fbm({w.x * 400.0, w.y * 8.0, w.z * 8.0}, 2);
  return {cv::Vec3f(150, 150, 155) * (0.9f + 0.2f * brush), 1.2f, 80.0f};
}

// Red cloth cover on top, pale page edges on the sides, a title strip.
Surfel book(const glm::dvec3& w, const glm::dvec3& n_w) {
  if (std::abs(n_w.y) < 0.7) {
    const double lines = 0.5 + 0.5 * std::sin(w.y * 3000.0);
    return {cv::Vec3f(200, 215, 225) * (0.9f + 0.1f * static_cast<float>(lines)), 0.05f, 8.0f};
  }
  const float weave = fbm({w.x * 500.0, 0.0, w.z * 500.0}, 2);
  cv::Vec3f c = cv::Vec3f(40, 40, 150) * (0.85f + 0.3f * weave);
  if (std::abs(w.z - 0.64) < 0.012) c = cv::Vec3f(90, 190, 220);  // gilt title strip
  return {c, 0.08f, 10.0f};
}

Surfel surfel_at(Material m, const glm::dvec3& w, const glm::dvec3& n_w, int id) {
  switch (m) {
    case Material::Plaster:
      return plaster(w);
    case Material::Floorboards:
      return floorboards(w);
    case Material::Wood:
      return wood(w);
    case Material::Cardboard:
      return cardboard(w, n_w);
    case Material::Ceramic:
      return ceramic(w);
    case Material::Metal:
      return metal(w);
    case Material::Book:
      return book(w, n_w);
    case Material::Default:
      break;
  }
  return {kBase[static_cast<std::size_t>(std::max(0, id)) % kBase.size()], 0.0f, 16.0f};
}

}  // namespace

cv::Mat3b shade_render(const synth::Rendered& rendered) {
  const cv::Mat1f& z = rendered.true_depth_m;
  cv::Mat3b out(z.size(), cv::Vec3b(0, 0, 0));
  for (int y = 0; y < z.rows; ++y) {
    for (int x = 0; x < z.cols; ++x) {
      const float depth = z(y, x);
      if (!(depth > 0.0f)) continue;
      const cv::Vec3f n = rendered.true_normals(y, x);
      // Head light along the viewing axis: normals face the camera, so -n_z is the cosine.
      const float lambert = std::clamp(-n[2], 0.0f, 1.0f);
      const float fade = 1.0f / (1.0f + 0.35f * depth * depth);
      const int id = rendered.object_id.empty() ? 0 : std::max(0, rendered.object_id(y, x));
      const cv::Vec3f c =
          kBase[static_cast<std::size_t>(id) % kBase.size()] * (0.25f + 0.75f * lambert) * fade;
      out(y, x) = cv::Vec3b(cv::saturate_cast<uchar>(c[0]), cv::saturate_cast<uchar>(c[1]),
                            cv::saturate_cast<uchar>(c[2]));
    }
  }
  return out;
}

cv::Mat3b shade_render(const synth::Rendered& rendered, const synth::Scene& scene,
                       const Intrinsics& k, const glm::dvec3& p_CameraViewpoint) {
  const cv::Mat1f& z = rendered.true_depth_m;
  cv::Mat3b out(z.size(), cv::Vec3b(0, 0, 0));
  const glm::dmat3 R_WorldCamera = glm::transpose(scene.texture_frame());
  // A ceiling light above and in front of the camera (world y is down), and the head light.
  const glm::dvec3 to_light_w = glm::normalize(glm::dvec3(0.3, -1.0, 0.5));
  for (int y = 0; y < z.rows; ++y) {
    for (int x = 0; x < z.cols; ++x) {
      const float depth = z(y, x);
      if (!(depth > 0.0f)) continue;
      const cv::Vec3f nf = rendered.true_normals(y, x);
      const glm::dvec3 n_c(nf[0], nf[1], nf[2]);
      const glm::dvec3 ray((x - k.cx) / k.fx, (y - k.cy) / k.fy, 1.0);
      const glm::dvec3 p_c = ray * static_cast<double>(depth) + p_CameraViewpoint;
      const glm::dvec3 w = R_WorldCamera * p_c;
      const glm::dvec3 n_w = R_WorldCamera * n_c;
      const int id = rendered.object_id.empty() ? 0 : rendered.object_id(y, x);
      const Surfel s = surfel_at(scene.material(id), w, n_w, id);
      const glm::dvec3 to_eye = glm::normalize(-ray);
      const double head = std::clamp(glm::dot(n_c, to_eye), 0.0, 1.0);
      const double ceiling = std::clamp(glm::dot(n_w, to_light_w), 0.0, 1.0);
      const glm::dvec3 half_w = glm::normalize(to_light_w + R_WorldCamera * to_eye);
      const double spec =
          s.gloss * std::pow(std::clamp(glm::dot(n_w, half_w), 0.0, 1.0), s.shininess);
      const float fade = 1.0f / (1.0f + 0.12f * depth * depth);
      const float diffuse = static_cast<float>(0.3 + 0.35 * head + 0.55 * ceiling);
      const cv::Vec3f c =
          s.albedo * diffuse * fade + cv::Vec3f(1, 1, 1) * static_cast<float>(255.0 * spec * fade);
      out(y, x) = cv::Vec3b(cv::saturate_cast<uchar>(c[0]), cv::saturate_cast<uchar>(c[1]),
                            cv::saturate_cast<uchar>(c[2]));
    }
  }
  return out;
}

StereoViews render_stereo_views(const synth::Scene& scene, const Intrinsics& intrinsics,
                                double interpupillary_m) {
  const auto ideal = synth::SensorModel::ideal();
  const glm::dvec3 left_eye(-interpupillary_m, 0.0, 0.0);
  StereoViews v;
  v.right_bgr =
      shade_render(synth::render(scene, intrinsics, ideal), scene, intrinsics, glm::dvec3(0.0));
  v.left_bgr = shade_render(synth::render_from(scene, intrinsics, left_eye, ideal), scene,
                            intrinsics, left_eye);
  return v;
}

}  // namespace telex::remote
