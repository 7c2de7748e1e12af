// SPDX-License-Identifier: Apache-2.0
#pragma once
// Host checks behind `toonforce devices` and the permission advice in errors: is a udev rule
// for the Falcon installed, and is this user in the group it grants access to?
#include <string>
#include <vector>

namespace toonforce::falcon {

struct UdevRuleCheck {
  bool installed = false;
  std::string path;  ///< the rules file that mentions the Falcon's product id
};
/// Looks for a rules file mentioning 0403/cb48 in the directories udev reads.
UdevRuleCheck check_udev_rule(const std::vector<std::string>& dirs = {"/etc/udev/rules.d", "/run/udev/rules.d",
                                                                      "/usr/lib/udev/rules.d", "/lib/udev/rules.d"});

struct GroupCheck {
  bool exists = false;      ///< the group is defined on this host
  bool in_session = false;  ///< this process has it (getgroups or primary group)
  bool listed = false;      ///< /etc/group lists this user as a member (maybe since a later login)
};
GroupCheck check_group(const std::string& name);

}  // namespace toonforce::falcon
