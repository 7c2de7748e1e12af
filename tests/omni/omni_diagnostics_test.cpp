// SPDX-License-Identifier: Apache-2.0
// What `toonforce devices` will say about OpenHaptics and about a Touch it cannot open. The
// OpenHaptics check loads fakes of our own (tests/omni/fake_hd/): it proves the check against
// the documented library layout, not against a real installation. Permission failures cannot
// be produced under umockdev as root, so their wording is tested here directly.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <stdlib.h>

#include <cerrno>
#include <filesystem>

#include "fake_hd_client.hpp"
#include "toonforce/hal/omni/hd_library.hpp"
#include "toonforce/hal/omni/touch_detect.hpp"

namespace toonforce {
namespace {

using ::testing::HasSubstr;
using ::testing::IsEmpty;

TEST(OpenHapticsPrerequisite, IsMetWhenTheLibraryLoadsWithEveryFunction) {
  ::testing::Test::RecordProperty("proves", test::kProves);
  const Prerequisite p = openhaptics_prerequisite(test::kFakeHd);
  EXPECT_TRUE(p.ok);
  EXPECT_EQ(p.name, "OpenHaptics HD library (libHD)");
  EXPECT_THAT(p.detail, HasSubstr(std::filesystem::canonical(test::kFakeHd).string() + " loads"));
  EXPECT_THAT(p.detail, HasSubstr("all 23 HD functions"));
  EXPECT_THAT(p.fix, IsEmpty());
}

TEST(OpenHapticsPrerequisite, SaysWhatIsMissingAndWhatToInstall) {
  ::testing::Test::RecordProperty("proves", test::kProves);
  const Prerequisite dep = openhaptics_prerequisite(test::kFakeHdNeedsDep);
  EXPECT_FALSE(dep.ok);
  EXPECT_THAT(dep.detail, HasSubstr("needs libPhantomIOLib42.so"));
  EXPECT_THAT(dep.fix, HasSubstr("Touch Device Driver"));

  const Prerequisite symbol = openhaptics_prerequisite(test::kFakeHdMissingSymbol);
  EXPECT_FALSE(symbol.ok);
  EXPECT_THAT(symbol.detail, HasSubstr("hdGetSchedulerTimeStamp"));
  EXPECT_THAT(symbol.fix, HasSubstr("OpenHaptics 3.0 or later"));
}

TEST(OpenHapticsPrerequisite, UsesTheSameSearchAsOpeningTheDevice) {
  ::testing::Test::RecordProperty("proves", test::kProves);
  setenv(hd::kLibraryEnvVar, "/nonexistent/libHD.so", 1);
  const Prerequisite p = openhaptics_prerequisite();
  unsetenv(hd::kLibraryEnvVar);
  EXPECT_FALSE(p.ok);
  EXPECT_THAT(p.detail, HasSubstr("TOONFORCE_LIBHD=/nonexistent/libHD.so does not exist"));
  EXPECT_THAT(p.fix, HasSubstr("libHD.so"));
}

TEST(TouchOpenFailure, PermissionOnTheUsbNodeAsksForAUdevRule) {
  const OpenProblem p = describe_open_failure("/dev/bus/usb/001/005", "usb", EACCES);
  EXPECT_EQ(p.problem, "this user may not open /dev/bus/usb/001/005 (permission denied)");
  EXPECT_THAT(p.fix, HasSubstr("SUBSYSTEM==\"usb\", ATTRS{idVendor}==\"2988\""));
  EXPECT_THAT(p.fix, HasSubstr("udevadm"));
  EXPECT_THAT(p.fix, HasSubstr("plugdev"));
}

TEST(TouchOpenFailure, PermissionOnTheSerialPortAsksForTheDialoutGroup) {
  const OpenProblem p = describe_open_failure("/dev/ttyACM0", "tty", EACCES);
  EXPECT_THAT(p.problem, HasSubstr("/dev/ttyACM0"));
  EXPECT_THAT(p.fix, HasSubstr("usermod -aG dialout"));
}

TEST(TouchOpenFailure, PermissionOnHidrawAsksForAHidrawRule) {
  EXPECT_THAT(describe_open_failure("/dev/hidraw3", "hidraw", EPERM).fix, HasSubstr("SUBSYSTEM==\"hidraw\""));
}

TEST(TouchOpenFailure, AMissingOrBusyNodeSaysSo) {
  EXPECT_THAT(describe_open_failure("/dev/ttyACM0", "tty", ENOENT).fix, HasSubstr("cdc_acm"));
  EXPECT_THAT(describe_open_failure("/dev/bus/usb/001/005", "usb", ENODEV).problem, HasSubstr("does not exist"));
  EXPECT_THAT(describe_open_failure("/dev/ttyACM0", "tty", EBUSY).problem, HasSubstr("in use by another program"));
  EXPECT_THAT(describe_open_failure("/dev/ttyACM0", "tty", EIO).problem, HasSubstr("cannot be opened"));
}

}  // namespace
}  // namespace toonforce
