// SPDX-License-Identifier: Apache-2.0
// Host checks for `toonforce devices` and permission errors (see udev_check.hpp).
#include "udev_check.hpp"

#include <grp.h>
#include <pwd.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace toonforce::falcon {

UdevRuleCheck check_udev_rule(const std::vector<std::string>& dirs) {
  UdevRuleCheck out;
  for (const auto& dir : dirs) {
    std::error_code ec;
    for (const auto& entry : std::filesystem::directory_iterator(dir, ec)) {
      if (entry.path().extension() != ".rules") continue;
      std::ifstream in(entry.path());
      std::stringstream text;
      text << in.rdbuf();
      std::string s = text.str();
      std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
      if (s.find("cb48") != std::string::npos && s.find("0403") != std::string::npos) {
        out.installed = true;
        out.path = entry.path().string();
        return out;
      }
    }
  }
  return out;
}

GroupCheck check_group(const std::string& name) {
  GroupCheck out;
  const group* g = ::getgrnam(name.c_str());
  if (g == nullptr) return out;
  out.exists = true;
  const gid_t gid = g->gr_gid;
  std::vector<std::string> members;
  for (char** m = g->gr_mem; m != nullptr && *m != nullptr; ++m) members.emplace_back(*m);
  if (::getgid() == gid || ::getegid() == gid) out.in_session = true;
  const int n = ::getgroups(0, nullptr);
  if (n > 0) {
    std::vector<gid_t> groups(static_cast<std::size_t>(n));
    if (::getgroups(n, groups.data()) == n && std::find(groups.begin(), groups.end(), gid) != groups.end()) {
      out.in_session = true;
    }
  }
  if (const passwd* pw = ::getpwuid(::getuid()); pw != nullptr) {
    out.listed = std::find(members.begin(), members.end(), pw->pw_name) != members.end() || pw->pw_gid == gid;
  }
  return out;
}

}  // namespace toonforce::falcon
