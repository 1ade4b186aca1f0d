// SPDX-License-Identifier: MIT
// The "room" scene a newcomer first sees: materials on every surface, the book where the optical
// axis meets the table (where the demo presses and strokes), and textures laid out in the world so
// that both eyes see the same pattern on the same surface.
#include <gtest/gtest.h>

#include <glm/geometric.hpp>
#include <opencv2/imgproc.hpp>
#include <set>

#include "telex/common/synthetic.h"
#include "telex/remote/synthetic_view.h"

namespace telex::remote {
namespace {

TEST(SyntheticRoom, EverySurfaceHasAMaterialAndTheAxisMeetsTheBook) {
  const auto scene = synth::Scene::named("room");
  std::set<synth::Material> used;
  for (int id = 0; id < scene.object_count(); ++id) {
    EXPECT_NE(scene.material(id), synth::Material::Default) << "object " << id;
    used.insert(scene.material(id));
  }
  EXPECT_GE(used.size(), 6u) << "floor, walls, table and objects of several materials";
  const auto hit = scene.raycast(glm::dvec3(0.0), glm::dvec3(0, 0, 1));
  ASSERT_TRUE(hit.has_value());
  EXPECT_EQ(scene.material(hit->object_id), synth::Material::Book);
  EXPECT_NEAR(hit->t_m, 0.854, 0.01);  // the book's top, 0.49 m below the camera pitched 35 deg
  // The stroke slides 100 mm toward +x: still on the book.
  const auto slid = scene.raycast(glm::dvec3(0.1, 0, 0), glm::dvec3(0, 0, 1));
  ASSERT_TRUE(slid.has_value());
  EXPECT_EQ(slid->object_id, hit->object_id);
  EXPECT_THROW(synth::Scene().set_material(0, synth::Material::Wood), std::invalid_argument);
}

TEST(SyntheticRoom, TexturesAreInTheWorldSoBothEyesAgree) {
  const auto scene = synth::Scene::named("room");
  const Intrinsics k = kinect_v1_intrinsics(320, 240);
  const auto views = render_stereo_views(scene, k);
  const auto truth = synth::render(scene, k, synth::SensorModel::ideal());
  // Textured: the floor and table are not flat colours (a flat-shaded plane varies only slowly).
  cv::Mat gray;
  cv::cvtColor(views.right_bgr, gray, cv::COLOR_BGR2GRAY);
  cv::Mat lap;
  cv::Laplacian(gray, lap, CV_32F);
  cv::Scalar mean, stddev;
  cv::meanStdDev(lap, mean, stddev);
  EXPECT_GT(stddev[0], 4.0) << "the eye video shows texture";
  // Every right-eye pixel with a surface, moved to the left eye by its true depth, lands on the
  // same colour (up to lighting from the other eye and sampling): the pattern is in the world.
  int compared = 0, agree = 0;
  for (int y = 0; y < truth.true_depth_m.rows; y += 3) {
    for (int x = 0; x < truth.true_depth_m.cols; x += 3) {
      const float z = truth.true_depth_m(y, x);
      if (!(z > 0.0f)) continue;
      const double xl = x + k.fx * kInterpupillaryM / z;
      const int xi = static_cast<int>(std::lround(xl));
      if (xi < 1 || xi >= k.width - 1) continue;
      ++compared;
      const cv::Vec3b a = views.right_bgr(y, x), b = views.left_bgr(y, xi);
      if (cv::norm(cv::Vec3f(a) - cv::Vec3f(b)) < 40.0) ++agree;
    }
  }
  ASSERT_GT(compared, 3000);
  EXPECT_GT(static_cast<double>(agree) / compared, 0.85);
}

}  // namespace
}  // namespace telex::remote
