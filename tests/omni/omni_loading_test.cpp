// SPDX-License-Identifier: Apache-2.0
// Loading OpenHaptics at run time (hd_library.hpp): every way it can fail gives a message that
// says what is wrong and what to install or fix. The libraries loaded here are fakes of our own
// (tests/omni/fake_hd/): these tests prove the loader and binding against the documented HD
// API, not against the real driver.
#include <dlfcn.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <stdlib.h>

#include <filesystem>
#include <fstream>

#include "fake_hd_client.hpp"
#include "toonforce/hal/omni/hd_library.hpp"
#include "toonforce/hal/omni/omni_device.hpp"

namespace toonforce {
namespace {

using test::kFakeHd;
using ::testing::HasSubstr;

class OmniLoading : public ::testing::Test {
 protected:
  void SetUp() override {
    RecordProperty("proves", test::kProves);
    unsetenv(hd::kLibraryEnvVar);
  }
  void TearDown() override { unsetenv(hd::kLibraryEnvVar); }
};

TEST_F(OmniLoading, WithoutOpenHapticsTheMessageSaysWhatToInstallAndHowToPointAtIt) {
  // Only meaningful where OpenHaptics is not installed (CI; this machine).
  if (void* real = dlopen("libHD.so", RTLD_LAZY | RTLD_NOLOAD); real != nullptr) {
    GTEST_SKIP() << "a libHD.so is installed on this machine";
  }
  for (const char* name : hd::kDefaultLibraryNames) {
    if (dlopen(name, RTLD_LAZY | RTLD_NODELETE) != nullptr) GTEST_SKIP() << name << " is installed here";
  }
  const hd::LoadOutcome out = hd::load_library();
  EXPECT_EQ(out.library, nullptr);
  EXPECT_EQ(out.problem, hd::LoadProblem::kNotFound);
  EXPECT_THAT(out.message, HasSubstr("none of libHD.so, libHD.so.3.4, libHD.so.3.0 was found"));
  EXPECT_THAT(out.message, HasSubstr("Install OpenHaptics 3.4"));
  EXPECT_THAT(out.message, HasSubstr("Touch Device Driver"));
  EXPECT_THAT(out.message, HasSubstr("TOONFORCE_LIBHD=/path/to/libHD.so"));
}

TEST_F(OmniLoading, AnExplicitPathThatDoesNotExistIsNamed) {
  const hd::LoadOutcome out = hd::load_library("/nonexistent/toonforce/libHD.so");
  EXPECT_EQ(out.problem, hd::LoadProblem::kNotFound);
  EXPECT_THAT(out.message, HasSubstr("/nonexistent/toonforce/libHD.so does not exist"));
}

TEST_F(OmniLoading, TheEnvironmentVariableIsNamedWhenItsFileIsMissing) {
  setenv(hd::kLibraryEnvVar, "/nonexistent/libHD.so.3.4", 1);
  const hd::LoadOutcome out = hd::load_library();
  EXPECT_EQ(out.problem, hd::LoadProblem::kNotFound);
  EXPECT_THAT(out.message, HasSubstr("TOONFORCE_LIBHD=/nonexistent/libHD.so.3.4 does not exist"));
}

TEST_F(OmniLoading, TheEnvironmentVariableLoadsALibraryFromANonStandardPlace) {
  setenv(hd::kLibraryEnvVar, kFakeHd, 1);
  const hd::LoadOutcome out = hd::load_library();
  ASSERT_NE(out.library, nullptr) << out.message;
  EXPECT_EQ(out.library->path(), std::filesystem::canonical(kFakeHd).string());
  EXPECT_EQ(out.library->file_version(), "");  // libHD.so carries no version in its name
}

TEST_F(OmniLoading, AnExplicitPathWinsOverTheEnvironment) {
  setenv(hd::kLibraryEnvVar, "/nonexistent/libHD.so", 1);
  const hd::LoadOutcome out = hd::load_library(kFakeHd);
  ASSERT_NE(out.library, nullptr) << out.message;
}

TEST_F(OmniLoading, TheSameFileLoadedTwiceIsOneLibraryThatStaysLoaded) {
  const hd::LoadOutcome first = hd::load_library(kFakeHd);
  const hd::LoadOutcome second = hd::load_library(kFakeHd);
  ASSERT_NE(first.library, nullptr) << first.message;
  EXPECT_EQ(first.library, second.library);
  // Never unloaded (OMNI.md §2.1): the object is still mapped after any dlclose attempt.
  dlclose(dlopen(kFakeHd, RTLD_LAZY));
  EXPECT_NE(dlopen(kFakeHd, RTLD_LAZY | RTLD_NOLOAD), nullptr);
}

TEST_F(OmniLoading, AMissingFunctionIsNamed) {
  const hd::LoadOutcome out = hd::load_library(test::kFakeHdMissingSymbol);
  EXPECT_EQ(out.library, nullptr);
  EXPECT_EQ(out.problem, hd::LoadProblem::kSymbolMissing);
  EXPECT_THAT(out.message, HasSubstr("does not export hdGetSchedulerTimeStamp"));
  EXPECT_THAT(out.message, HasSubstr("1 of the 23 HD functions"));
  EXPECT_THAT(out.message, HasSubstr("Install OpenHaptics 3.0 or later"));
}

TEST_F(OmniLoading, AnotherMajorVersionInTheFileNameIsRefused) {
  const hd::LoadOutcome out = hd::load_library(test::kFakeHdV2);  // libHD.so -> libHD.so.2.0.0
  EXPECT_EQ(out.library, nullptr);
  EXPECT_EQ(out.problem, hd::LoadProblem::kWrongVersion);
  EXPECT_THAT(out.message, HasSubstr("libHD.so.2.0.0 is OpenHaptics HD library version 2.0.0"));
  EXPECT_THAT(out.message, HasSubstr("needs version 3"));
}

TEST_F(OmniLoading, AMissingDependencyIsNamedWithItsFix) {
  const hd::LoadOutcome out = hd::load_library(test::kFakeHdNeedsDep);
  EXPECT_EQ(out.library, nullptr);
  EXPECT_EQ(out.problem, hd::LoadProblem::kDependencyMissing);
  EXPECT_THAT(out.message, HasSubstr("needs libPhantomIOLib42.so"));
  EXPECT_THAT(out.fix, HasSubstr("install the 3D Systems Touch Device Driver"));
  EXPECT_THAT(out.message, HasSubstr("Install the 3D Systems Touch Device Driver"));
}

TEST_F(OmniLoading, AFileThatIsNotALibraryIsReportedAsSuch) {
  const auto path =
      std::filesystem::temp_directory_path() / ("toonforce-not-elf-" + std::to_string(getpid())) / "libHD.so";
  std::filesystem::create_directories(path.parent_path());
  std::ofstream(path) << "not a shared object\n";
  const hd::LoadOutcome out = hd::load_library(path.string());
  std::filesystem::remove_all(path.parent_path());
  EXPECT_EQ(out.problem, hd::LoadProblem::kNotLoadable);
  EXPECT_THAT(out.message, HasSubstr("could not be loaded"));
  EXPECT_THAT(out.message, HasSubstr("64-bit x86-64"));
}

TEST_F(OmniLoading, AVersionReportedByTheLibraryOtherThan3IsRefusedAndTheDeviceReleased) {
  test::FakeHd fake;
  fake.reset();
  fake.set_version("2.10.1");
  OmniOptions options;
  options.library_path = kFakeHd;
  auto omni = open_omni(options);
  ASSERT_FALSE(omni.ok());
  EXPECT_THAT(omni.error(), HasSubstr("reports OpenHaptics HD version 2.10.1"));
  EXPECT_THAT(omni.error(), HasSubstr("needs version 3"));
  EXPECT_EQ(fake.stats().device_initialized, 0);  // hdDisableDevice after the refusal
  fake.set_version("3.4.0");
  auto again = open_omni(options);
  EXPECT_TRUE(again.ok()) << again.error();
}

TEST_F(OmniLoading, OpenOmniPassesTheLoaderMessageOn) {
  OmniOptions options;
  options.library_path = test::kFakeHdMissingSymbol;
  auto omni = open_omni(options);
  ASSERT_FALSE(omni.ok());
  EXPECT_THAT(omni.error(), HasSubstr("hdGetSchedulerTimeStamp"));
}

TEST(OmniVersionText, MajorVersionIsTheLeadingNumber) {
  EXPECT_EQ(hd::major_version("3.40.1"), 3);
  EXPECT_EQ(hd::major_version("3"), 3);
  EXPECT_EQ(hd::major_version("12.0"), 12);
  EXPECT_EQ(hd::major_version("v3"), -1);
  EXPECT_EQ(hd::major_version(""), -1);
  EXPECT_EQ(hd::major_version("99999999999999999999"), -1);
}

TEST(OmniVersionText, TheFileNameCarriesTheVersionAfterSo) {
  EXPECT_EQ(hd::version_from_file_name("libHD.so.3.4.0"), "3.4.0");
  EXPECT_EQ(hd::version_from_file_name("libHD.so.3.0"), "3.0");
  EXPECT_EQ(hd::version_from_file_name("libHD.so"), "");
  EXPECT_EQ(hd::version_from_file_name("libHD.so.old"), "");
}

TEST(OmniDependencyFix, KnownDependenciesGetTheirOwnInstructions) {
  EXPECT_THAT(hd::dependency_fix("libPhantomIOLib42.so"), HasSubstr("Touch Device Driver"));
  EXPECT_THAT(hd::dependency_fix("libPHANToMIO.so.4"), HasSubstr("PHANTOM Device Drivers"));
  EXPECT_THAT(hd::dependency_fix("libncurses.so.5"), HasSubstr("apt-get install libncurses5 libtinfo5"));
  EXPECT_THAT(hd::dependency_fix("libfoo.so.1"), HasSubstr("libfoo.so.1"));
}

}  // namespace
}  // namespace toonforce
