// SPDX-License-Identifier: Apache-2.0
// The OpenHaptics frame (x right, y up, z toward the user, mm) against the scene frame of spec
// effects.md §0 (x right, y away from the user, z up, m, origin at the workspace centre):
// scene = (x, -z, y) after removing the centre. Expected values are worked out by hand from
// that formula, not from the code under test.
#include <gtest/gtest.h>

#include <cmath>

#include "toonforce/hal/omni/omni_frame.hpp"

namespace toonforce::omni {
namespace {

constexpr double kTol = 1e-12;

void expect_near(const Vec3<double>& a, const Vec3<double>& b, double tol = kTol) {
  EXPECT_NEAR(a.x, b.x, tol);
  EXPECT_NEAR(a.y, b.y, tol);
  EXPECT_NEAR(a.z, b.z, tol);
}

Vec3<double> cross(const Vec3<double>& a, const Vec3<double>& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}

const Frame kFrame{{4.0, -5.0, 10.0}};  // a workspace centre off the device origin [mm]

TEST(OmniFrame, UpInTheDeviceIsUpInTheScene) {
  // 20 mm above the centre (device +y) is scene +z, 0.02 m.
  expect_near(kFrame.position_m({4.0, 15.0, 10.0}), {0.0, 0.0, 0.020});
}

TEST(OmniFrame, TowardTheUserInTheDeviceIsMinusYInTheScene) {
  // Device +z points at the user; scene +y points away from the user.
  expect_near(kFrame.position_m({4.0, -5.0, 40.0}), {0.0, -0.030, 0.0});
}

TEST(OmniFrame, RightIsRightInBoth) { expect_near(kFrame.position_m({-6.0, -5.0, 10.0}), {-0.010, 0.0, 0.0}); }

TEST(OmniFrame, TheWorkspaceCentreIsTheSceneOrigin) {
  expect_near(kFrame.position_m({4.0, -5.0, 10.0}), {0.0, 0.0, 0.0});
  expect_near(kFrame.device_position_mm({0.0, 0.0, 0.0}), {4.0, -5.0, 10.0});
}

TEST(OmniFrame, PositionsGoBackAndForthExactly) {
  const Vec3<double> scene{0.0123, -0.0456, 0.0789};
  expect_near(kFrame.position_m(kFrame.device_position_mm(scene)), scene, 1e-15);
}

TEST(OmniFrame, VelocitiesRotateAndScaleWithoutTheOffset) {
  expect_near(Frame::velocity_m_per_s({100.0, 200.0, 300.0}), {0.1, -0.3, 0.2});
}

TEST(OmniFrame, ASceneForceUpIsADeviceForceUp) {
  // Scene +z (out of a floor) must push the handle up: device +y.
  expect_near(Frame::device_force_n({0.0, 0.0, 2.0}), {0.0, 2.0, 0.0});
  // Scene +y (away from the user) is device -z.
  expect_near(Frame::device_force_n({0.0, 1.5, 0.0}), {0.0, 0.0, -1.5});
  expect_near(Frame::device_force_n({1.0, 0.5, 0.25}), {1.0, 0.25, -0.5});
}

TEST(OmniFrame, ForcesKeepTheirMagnitudeAndComeBack) {
  const Vec3<double> f{0.7, -1.1, 2.3};
  const Vec3<double> d = Frame::device_force_n(f);
  EXPECT_NEAR(dot(d, d), dot(f, f), 1e-12);
  expect_near(Frame::scene_force_n(d), f);
}

TEST(OmniFrame, TheRotationIsProperSoHandednessIsKept) {
  // Right-handed in, right-handed out: x cross y = z in both frames.
  const Vec3<double> x = Frame::rotate_to_scene({1, 0, 0});
  const Vec3<double> y = Frame::rotate_to_scene({0, 1, 0});
  const Vec3<double> z = Frame::rotate_to_scene({0, 0, 1});
  expect_near(cross(x, y), z);
}

TEST(OmniFrame, AWorkspaceBoxBecomesASceneBoxAroundTheOrigin) {
  // The fake's usable workspace: x -80..80, y -65..55, z -40..30 mm; centre (0, -5, -5).
  const DeviceBoxMm box{-80.0, -65.0, -40.0, 80.0, 55.0, 30.0};
  const Frame frame{Frame::centre_of(box)};
  expect_near(frame.centre_mm, {0.0, -5.0, -5.0});
  const auto scene = frame.scene_box_m(box);
  // scene x from device x; scene y = -(device z - cz): -35..35 mm; scene z = device y - cy.
  expect_near(scene[0], {-0.080, -0.035, -0.060});
  expect_near(scene[1], {0.080, 0.035, 0.060});
}

}  // namespace
}  // namespace toonforce::omni
