// SPDX-License-Identifier: Apache-2.0
// toonforce-dds's reading of the viewer's columns (tools/dds/state_bridge.hpp): which values of
// a row are which device's, for one device and for a world; names that cannot be ROS 2 topics
// and rows that lack a device's value are refused with a message naming them.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "toonforce/dds/state_bridge.hpp"

namespace toonforce::dds {
namespace {

TEST(DdsColumns, OneDevicesValuesAreTheViewersFixedColumnsWithItsVelocity) {
  const std::vector<std::string> columns{"t", "tick", "x", "y", "z", "vx", "vy", "vz", "fx", "fy", "fz", "latched"};
  auto d = device_columns(columns, "falcon_a");
  ASSERT_TRUE(d) << d.error();
  ASSERT_EQ(d->size(), 1U);
  const DeviceColumns& c = d->front();
  EXPECT_EQ(c.name, "falcon_a");
  EXPECT_EQ(c.x, 2U);
  EXPECT_EQ(c.z, 4U);
  ASSERT_TRUE(c.vx.has_value());
  EXPECT_EQ(*c.vz, 7U);
  EXPECT_EQ(c.fx, 8U);
  EXPECT_EQ(c.latched, 11U);
}

TEST(DdsColumns, AWorldsDevicesAreThoseWithAStateColumnAndHaveNoVelocity) {
  const std::vector<std::string> columns{
      "t",        "left.x",       "left.y",     "left.z",        "left.fx",     "left.fy",
      "left.fz",  "left.latched", "left.state", "right.x",       "right.y",     "right.z",
      "right.fx", "right.fy",     "right.fz",   "right.latched", "right.state", "held"};
  auto d = device_columns(columns, "ignored");
  ASSERT_TRUE(d) << d.error();
  ASSERT_EQ(d->size(), 2U);
  EXPECT_EQ(d.value()[0].name, "left");
  EXPECT_EQ(d.value()[1].name, "right");
  EXPECT_EQ(d.value()[1].x, 9U);
  EXPECT_EQ(d.value()[1].latched, 15U);
  EXPECT_FALSE(d.value()[0].vx.has_value());  // nothing made up: a world row carries no velocity
}

TEST(DdsColumns, AMissingColumnOrANameThatIsNoRosTokenIsRefusedByName) {
  auto missing = device_columns({"t", "x", "y", "z", "fx", "fy", "latched"}, "device");
  ASSERT_FALSE(missing);
  EXPECT_NE(missing.error().find("'fz'"), std::string::npos) << missing.error();
  auto bad = device_columns({"t", "x", "y", "z", "fx", "fy", "fz", "latched"}, "my-device");
  ASSERT_FALSE(bad);
  EXPECT_NE(bad.error().find("my-device"), std::string::npos) << bad.error();
  EXPECT_TRUE(ros_token("left_2"));
  EXPECT_FALSE(ros_token("2left"));
  EXPECT_FALSE(ros_token("a/b"));
  EXPECT_FALSE(ros_token(""));
}

TEST(DdsControl, OnlyUtf8ThatAWebSocketTakesIsForwarded) {
  EXPECT_TRUE(utf8(R"({"type": "status"})"));
  EXPECT_TRUE(utf8("caf\xc3\xa9 \xe2\x82\xac \xf0\x9f\x98\x80"));  // 2, 3 and 4 bytes
  EXPECT_FALSE(utf8("\xc3"));                                      // cut short
  EXPECT_FALSE(utf8("\xc0\xaf"));                                  // overlong '/'
  EXPECT_FALSE(utf8("\xe0\x80\xaf"));                              // overlong, 3 bytes
  EXPECT_FALSE(utf8("\xed\xa0\x80"));                              // a surrogate
  EXPECT_FALSE(utf8("\xf4\x90\x80\x80"));                          // past U+10FFFF
  EXPECT_FALSE(utf8("\xff"));
  EXPECT_FALSE(utf8("ok\x80"));  // a continuation byte alone
}

TEST(DdsColumns, TopicsAreRos2NamesAsItsDdsMiddlewaresSpellThem) {
  EXPECT_EQ(topic_name("left", "pose"), "rt/toonforce/left/pose");
}

}  // namespace
}  // namespace toonforce::dds
