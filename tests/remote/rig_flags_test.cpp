// SPDX-License-Identifier: MIT
// The rig's registration reaches telex-remote's configuration; the flags given win.
#include <gtest/gtest.h>

#include "flags.h"

namespace telex::remote {
namespace {

Rig rig_with_extrinsics() {
  Rig rig;
  rig.depth = Intrinsics{570.3, 570.3, 319.5, 239.5, 640, 480};
  rig.eye[1] = CameraModel{{530.0, 531.0, 320.0, 240.0, 640, 480}, {}};
  rig.X_RightEyeDepth = RigidTransform{glm::dmat3(1.0), {-0.03, 0.045, 0.0}};
  return rig;
}

TEST(RemoteRig, TheRigRegistersIntoTheRightEyeUnlessFlagsSayOtherwise) {
  RegistrationConfig reg = parse_registration("none", "0.025,0,0", "0,0,0", "", 1.0);
  apply_rig(rig_with_extrinsics(), {}, reg);
  EXPECT_EQ(reg.mode, RegisterMode::Full);
  EXPECT_EQ(reg.X_EyeDepth.translation_m, glm::dvec3(-0.03, 0.045, 0.0));
  EXPECT_EQ(reg.eye.fx, 530.0);
  ASSERT_TRUE(reg.depth);
  EXPECT_EQ(reg.depth->fx, 570.3);

  RegistrationConfig flagged = parse_registration("shift", "0.02,0,0", "0,0,0", "", 1.0);
  const glm::dvec3 from_flag = flagged.X_EyeDepth.translation_m;
  apply_rig(rig_with_extrinsics(), {true, true, false, false}, flagged);
  EXPECT_EQ(flagged.mode, RegisterMode::Shift);
  EXPECT_EQ(flagged.X_EyeDepth.translation_m, from_flag);
  EXPECT_EQ(flagged.eye.fx, 530.0);  // --register-eye was not given

  RegistrationConfig plain = parse_registration("none", "0.025,0,0", "0,0,0", "", 1.0);
  apply_rig(Rig{}, {}, plain);  // a rig without calibration changes nothing
  EXPECT_EQ(plain.mode, RegisterMode::None);
  EXPECT_FALSE(plain.depth);
}

}  // namespace
}  // namespace telex::remote
