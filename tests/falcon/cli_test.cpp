// SPDX-License-Identifier: Apache-2.0
// The Falcon's toonforce subcommands that need no device: `toonforce falcon udev-rule` and the
// errors of `toonforce falcon firmware` for files that are not known images. (`toonforce
// devices` and loads against emulated Falcons run in usb_test.cpp, under umockdev.)
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "run_command.hpp"
#include "synthetic_firmware.hpp"
#include <fmt/format.h>

#include "toonforce/hal/falcon/falcon.hpp"
#include "toonforce/hal/falcon/kinematics.hpp"

namespace toonforce {
namespace {

using Result = test::CommandRun;
Result run(const std::string& args) { return test::run_toonforce(args); }

TEST(FalconCli, UdevRuleIsTheRepositoryFileGrantingPlugdevNotEveryone) {
  const Result r = run("falcon udev-rule");
  ASSERT_EQ(r.status, 0) << r.output;
  std::ifstream in(std::string(TOONFORCE_SOURCE_DIR) + "/hal/falcon/udev/60-novint-falcon.rules");
  std::stringstream text;
  text << in.rdbuf();
  const std::string file = text.str();
  EXPECT_EQ(r.output, file);
  EXPECT_EQ(std::string(falcon_udev_rule()), file);
  // The one rule line: matches the Falcon, group plugdev, mode 0660 (not world-writable).
  EXPECT_NE(file.find("ATTR{idVendor}==\"0403\", ATTR{idProduct}==\"cb48\""), std::string::npos);
  EXPECT_NE(file.find("GROUP=\"plugdev\""), std::string::npos);
  EXPECT_NE(file.find("MODE=\"0660\""), std::string::npos);
  EXPECT_EQ(file.find("0666"), std::string::npos);
}

TEST(FalconCli, FirmwareRefusesFilesThatAreNotKnownImages) {
  const auto dir = std::filesystem::temp_directory_path() / ("toonforce_cli_fw_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const auto write = [&](const char* name, const std::vector<std::uint8_t>& bytes) {
    const auto path = (dir / name).string();
    std::ofstream out(path, std::ios::binary);
    out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
    return path;
  };
  const Result missing = run("falcon firmware " + (dir / "missing.bin").string());
  EXPECT_EQ(missing.status, 1);
  EXPECT_NE(missing.output.find("missing.bin: it does not exist"), std::string::npos) << missing.output;

  const Result small = run("falcon firmware " + write("small.bin", falcon::test::make_boot_image({10})));
  EXPECT_EQ(small.status, 1);
  EXPECT_NE(small.output.find("not the size of any known Falcon firmware image: 8492 (nvent_firmware.bin)"),
            std::string::npos)
      << small.output;

  const Result unknown = run("falcon firmware " + write("unknown.bin", falcon::test::make_boot_image({4231})));
  EXPECT_EQ(unknown.status, 1);
  EXPECT_NE(unknown.output.find("matches no known Falcon firmware image"), std::string::npos) << unknown.output;

  auto bad = falcon::test::make_boot_image({4231});
  bad[0] = 0;
  const Result broken = run("falcon firmware " + write("broken.bin", bad));
  EXPECT_EQ(broken.status, 1);
  EXPECT_NE(broken.output.find("is not a Falcon firmware image: byte 0"), std::string::npos) << broken.output;
  std::filesystem::remove_all(dir);
}

TEST(FalconCli, FirmwareNeedsAFile) {
  const Result r = run("falcon firmware");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("FILE is required"), std::string::npos) << r.output;
}

TEST(FalconCli, EnvelopePrintsWhatTheKinematicsGiveAndWritesTheGrid) {
  const auto dir = std::filesystem::temp_directory_path() / ("toonforce_cli_env_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::string csv = (dir / "envelope.csv").string();
  const Result r = run("falcon envelope --step 10 --csv " + csv);
  ASSERT_EQ(r.status, 0) << r.output;
  falcon::ForceEnvelope centre;
  ASSERT_TRUE(falcon::force_envelope_at(falcon::FalconGeometry{}, {0, 0, 0.110}, {}, centre));
  // Scene frame: along y is the Falcon's z, along z its y.
  const std::string line = fmt::format("at the workspace centre: along x {:.2f} N, along y {:.2f} N, along z {:.2f} N, "
                                       "in every direction {:.2f} N",
                                       centre.axis_n.x, centre.axis_n.z, centre.axis_n.y, centre.every_direction_n);
  EXPECT_NE(r.output.find(line), std::string::npos) << line << "\n---\n" << r.output;
  // The grid: 13 x 11 x 13 points at 10 mm, one line each after the comment and the header.
  std::ifstream in(csv);
  std::string text;
  std::size_t lines = 0;
  std::size_t unreachable = 0;
  while (std::getline(in, text)) {
    ++lines;
    if (text.size() > 6 && text.substr(text.size() - 4) == ",,,,") ++unreachable;
  }
  EXPECT_EQ(lines, 2u + 13u * 11u * 13u);
  EXPECT_GT(unreachable, 0u) << "the corners of the box are out of reach";

  // A calibrated constant half as large doubles every force.
  const std::string cal = (dir / "cal.toml").string();
  std::ofstream(cal) << "words_per_newton_metre = 5000\n";
  const Result calibrated = run("falcon envelope --step 20 --calibration " + cal);
  ASSERT_EQ(calibrated.status, 0) << calibrated.output;
  EXPECT_NE(calibrated.output.find(fmt::format("in every direction {:.2f} N", 2 * centre.every_direction_n)),
            std::string::npos)
      << calibrated.output;
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace toonforce
