// SPDX-License-Identifier: Apache-2.0
// The Falcon's calibration file (hal/falcon calibration.hpp): its format, its errors (file,
// line, key, as scene files), where it lives, and how open_falcon() chooses it. The driver
// over libusb reading a file runs in usb_test.cpp.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "toonforce/config/falcon_calibration_file.hpp"
#include "toonforce/hal/falcon/calibration.hpp"
#include "toonforce/hal/falcon/falcon.hpp"

namespace toonforce::falcon {
namespace {

namespace fs = std::filesystem;

std::string error_of(std::string_view text) {
  auto r = parse_falcon_calibration(text, "cal.toml");
  EXPECT_FALSE(r) << "accepted:\n" << text;
  return r ? std::string() : r.error();
}

TEST(FalconCalibrationFile, ReadsTheConstantAndTheMeasurement) {
  auto r = parse_falcon_calibration(
      "serial = \"A7X\"\nwords_per_newton_metre = 4200\n[measurement]\nmethod = \"weight\"\n"
      "reference_force_n = 4.905\nmeasured_force_n = 11.68\ndate = \"2026-11-23\"\nnote = \"500 g\"\n",
      "cal.toml");
  ASSERT_TRUE(r) << r.error();
  EXPECT_EQ(r.value().serial, "A7X");
  EXPECT_EQ(r.value().words_per_n_m, 4200.0);
  EXPECT_EQ(r.value().method, "weight");
  EXPECT_EQ(r.value().reference_force_n, 4.905);
  EXPECT_EQ(r.value().measured_force_n, 11.68);
  EXPECT_EQ(r.value().note, "500 g");
}

TEST(FalconCalibrationFile, WhatIsWrittenReadsBackTheSame) {
  FalconCalibration c;
  c.serial = "FT \"odd\" \\ serial";
  c.words_per_n_m = 10000.0 / 3.0;  // not a short decimal: every digit must survive
  c.method = "spring-scale";
  c.reference_force_n = 2.0;
  c.measured_force_n = 1.7;
  c.date = "2026-11-23T10:00:00Z";
  c.note = "line one\nline two";
  auto r = parse_falcon_calibration(format_falcon_calibration(c), "written.toml");
  ASSERT_TRUE(r) << r.error() << format_falcon_calibration(c);
  EXPECT_EQ(r.value().serial, c.serial);
  EXPECT_EQ(r.value().words_per_n_m, c.words_per_n_m);
  EXPECT_EQ(r.value().method, c.method);
  EXPECT_EQ(r.value().measured_force_n, c.measured_force_n);
  EXPECT_EQ(r.value().note, c.note);
}

TEST(FalconCalibrationFile, ErrorsNameTheFileTheLineAndTheKey) {
  EXPECT_NE(error_of("serial = \"x\"\n").find("cal.toml:1: missing required key 'words_per_newton_metre'"),
            std::string::npos);
  EXPECT_NE(error_of("# c\nwords_per_newton_metre = \"ten thousand\"\n")
                .find("cal.toml:2: words_per_newton_metre: must be a number, not a string"),
            std::string::npos);
  EXPECT_NE(error_of("words_per_newton_metre = -5\n").find("cal.toml:1: words_per_newton_metre: must be > 0"),
            std::string::npos);
  const std::string range = error_of("\n\nwords_per_newton_metre = 10\n");
  EXPECT_NE(range.find("cal.toml:3: words_per_newton_metre: 10 is outside 1000..100000"), std::string::npos) << range;
  const std::string typo = error_of("words_per_newton_meter = 10000\n");
  EXPECT_NE(typo.find("words_per_newton_meter"), std::string::npos) << typo;
  EXPECT_NE(typo.find("words_per_newton_metre"), std::string::npos) << "suggests the known key: " << typo;
  const std::string method = error_of("words_per_newton_metre = 9000\n[measurement]\nmethod = \"guess\"\n");
  EXPECT_NE(method.find("cal.toml:3: measurement.method: 'guess' is not one of weight, spring-scale, manual"),
            std::string::npos)
      << method;
  EXPECT_NE(error_of("words_per_newton_metre = = 3\n").find("cal.toml:1"), std::string::npos);
}

class CalibrationFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("toonforce_cal_" + std::to_string(::getpid()) + "_" +
                                        ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    if (const char* x = std::getenv("XDG_CONFIG_HOME")) saved_xdg_ = x;
    ::setenv("XDG_CONFIG_HOME", (dir_ / "config").c_str(), 1);
  }
  void TearDown() override {
    if (saved_xdg_) {
      ::setenv("XDG_CONFIG_HOME", saved_xdg_->c_str(), 1);
    } else {
      ::unsetenv("XDG_CONFIG_HOME");
    }
    fs::remove_all(dir_);
  }
  fs::path dir_;
  std::optional<std::string> saved_xdg_;
};

TEST_F(CalibrationFiles, TheDefaultPathIsPerSerialNumberUnderTheConfigHome) {
  EXPECT_EQ(default_falcon_calibration_path("A7X"), (dir_ / "config/toonforce/falcon-A7X.toml").string());
  EXPECT_EQ(default_falcon_calibration_path("a/b c"), (dir_ / "config/toonforce/falcon-a_b_c.toml").string());
  EXPECT_EQ(default_falcon_calibration_path(""), (dir_ / "config/toonforce/falcon.toml").string());
}

TEST_F(CalibrationFiles, WithoutAFileTheConstantIsLibnifalconsAndSaysSo) {
  auto r = resolve_falcon_calibration("", "A7X", &read_falcon_calibration);
  ASSERT_TRUE(r) << r.error();
  EXPECT_FALSE(r.value().from_file);
  EXPECT_EQ(r.value().calibration.words_per_n_m, kUncalibratedWordsPerNewtonMetre);
  EXPECT_NE(r.value().source.find("uncalibrated"), std::string::npos) << r.value().source;
  EXPECT_NE(r.value().source.find("toonforce bringup falcon"), std::string::npos) << r.value().source;
}

TEST_F(CalibrationFiles, TheFileWrittenForThisSerialIsFoundAndAnotherSerialsIsRefused) {
  FalconCalibration c;
  c.serial = "A7X";
  c.words_per_n_m = 4321.0;
  ASSERT_TRUE(write_falcon_calibration(default_falcon_calibration_path("A7X"), c));
  auto found = resolve_falcon_calibration("", "A7X", &read_falcon_calibration);
  ASSERT_TRUE(found) << found.error();
  EXPECT_TRUE(found.value().from_file);
  EXPECT_EQ(found.value().calibration.words_per_n_m, 4321.0);
  EXPECT_NE(found.value().source.find("falcon-A7X.toml"), std::string::npos);

  auto other = resolve_falcon_calibration(default_falcon_calibration_path("A7X"), "B8Y", &read_falcon_calibration);
  ASSERT_FALSE(other);
  EXPECT_NE(other.error().find("measured on the Falcon with serial number A7X, but the one opened is B8Y"),
            std::string::npos)
      << other.error();
}

TEST_F(CalibrationFiles, TheDeviceLayerReadsAFileOnlyThroughTheReaderItIsHanded) {
  // hal/ parses nothing: without a reader, a file that should be read is an error that says so,
  // never a silent uncalibrated start; with none to read, the constant as before.
  FalconCalibration c;
  c.words_per_n_m = 4000.0;
  ASSERT_TRUE(write_falcon_calibration(default_falcon_calibration_path("A7X"), c));
  auto unread = resolve_falcon_calibration("", "A7X", nullptr);
  ASSERT_FALSE(unread);
  EXPECT_NE(unread.error().find("reads no Falcon calibration files"), std::string::npos) << unread.error();
  auto none = resolve_falcon_calibration("", "NOFILE", nullptr);
  ASSERT_TRUE(none) << none.error();
  EXPECT_FALSE(none.value().from_file);
}

TEST_F(CalibrationFiles, AGivenFileMustExist) {
  auto r = resolve_falcon_calibration((dir_ / "nope.toml").string(), "A7X", &read_falcon_calibration);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().find("nope.toml: no such Falcon calibration file"), std::string::npos) << r.error();
}

}  // namespace
}  // namespace toonforce::falcon
