// SPDX-License-Identifier: Apache-2.0
#include "toonforce/sim/sim_trace.hpp"

#include <array>

#include "toonforce/trace/telemetry_trace.hpp"

namespace toonforce {

namespace {
constexpr std::array<const char*, 13> kSimColumns{"true_x",    "true_y",    "true_z", "true_vx", "true_vy",
                                                  "true_vz",   "hand_x",    "hand_y", "hand_z",  "device_fx",
                                                  "device_fy", "device_fz", "segment"};
}  // namespace

std::vector<std::string> sim_trace_columns(const std::vector<std::string>& value_names) {
  std::vector<std::string> columns = telemetry_columns(value_names, false);
  columns.insert(columns.end(), kSimColumns.begin(), kSimColumns.end());
  return columns;
}

bool sim_record_row(TraceRow& row, const SimRecord& r, std::size_t values) {
  const auto& tx = r.true_position_m;
  const auto& tv = r.true_velocity_m_per_s;
  const auto& h = r.hand_target_m;
  const auto& df = r.device_force_n;
  const std::array<double, kSimColumns.size()> more{
      tx.x, tx.y, tx.z, tv.x, tv.y, tv.z, h.x, h.y, h.z, df.x, df.y, df.z, static_cast<double>(r.segment)};
  return frame_row(row, r.frame, values, false, more);
}

bool write_sim_record(TraceWriter& writer, const SimRecord& r, std::size_t values) {
  TraceRow row;
  return sim_record_row(row, r, values) && writer.write(row.core, row.extras());
}

}  // namespace toonforce
