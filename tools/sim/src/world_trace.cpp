// SPDX-License-Identifier: Apache-2.0
#include "toonforce/sim/world_trace.hpp"

#include <cerrno>
#include <cmath>
#include <cstring>
#include <iterator>

#include <fmt/format.h>

namespace toonforce {

std::vector<std::string> world_columns(const WorldDescription& world) {
  std::vector<std::string> c{"t"};
  for (const WorldDeviceEntry& d : world.devices) {
    for (const char* v : {"x", "y", "z", "fx", "fy", "fz", "coupling_fx", "coupling_fy", "coupling_fz", "ball_fx",
                          "ball_fy", "ball_fz", "faults", "latched", "state"}) {
      c.push_back(fmt::format("{}.{}", d.name, v));
    }
  }
  for (std::size_t j = 0; j < world.couplings.size(); ++j) {
    for (const char* v : {"fx", "fy", "fz"}) c.push_back(fmt::format("coupling{}.{}", j + 1, v));
  }
  if (world.ball) {
    for (const char* v : {"x", "y", "z"}) c.push_back(fmt::format("ball.{}", v));
  }
  c.emplace_back("held");
  return c;
}

std::string world_column_unit(const std::string& column) {
  if (column == "t") return "s";
  const std::size_t dot = column.rfind('.');
  const std::string v = dot == std::string::npos ? column : column.substr(dot + 1);
  if (v == "x" || v == "y" || v == "z") return "m";
  if (v.size() >= 2 && v[v.size() - 2] == 'f' && (v.back() == 'x' || v.back() == 'y' || v.back() == 'z')) return "N";
  return "";
}

void world_row(const WorldFrame& f, std::vector<double>& row) {
  row.clear();
  row.push_back(f.t_s);
  for (std::size_t i = 0; i < f.devices && i < f.device.size(); ++i) {
    const WorldDeviceFrame& d = f.device[i];
    for (const Vec3<double>& v : {d.hip_m, d.force_n, d.coupling_n, d.ball_n}) {
      row.push_back(v.x);
      row.push_back(v.y);
      row.push_back(v.z);
    }
    row.push_back(static_cast<double>(d.faults));
    row.push_back(static_cast<double>(d.latched));
    row.push_back(static_cast<double>(d.state));
  }
  for (std::size_t j = 0; j < f.couplings && j < f.coupling_n.size(); ++j) {
    row.push_back(f.coupling_n[j].x);
    row.push_back(f.coupling_n[j].y);
    row.push_back(f.coupling_n[j].z);
  }
  if (f.has_ball) {
    row.push_back(f.ball_m.x);
    row.push_back(f.ball_m.y);
    row.push_back(f.ball_m.z);
  }
  row.push_back(f.held ? 1.0 : 0.0);
}

double coupling_imbalance_n(const WorldFrame& f) noexcept {
  Vec3<double> total{};
  for (std::size_t i = 0; i < f.devices && i < f.device.size(); ++i) total += f.device[i].coupling_n;
  return std::sqrt(dot(total, total));
}

Result<std::unique_ptr<WorldTrace>> WorldTrace::open(const std::string& path, const std::vector<std::string>& columns,
                                                     const std::string& flag) {
  std::FILE* file = path == "-" ? stdout : std::fopen(path.c_str(), "w");
  if (file == nullptr) return Error{fmt::format("{} {}: cannot write it: {}", flag, path, std::strerror(errno))};
  auto trace = std::unique_ptr<WorldTrace>(new WorldTrace(file, path != "-"));
  std::string header;
  for (std::size_t i = 0; i < columns.size(); ++i) header += (i == 0 ? "" : ",") + columns[i];
  header += '\n';
  trace->ok_ = std::fputs(header.c_str(), file) >= 0;
  trace->written_bytes_ = header.size();
  return trace;
}

WorldTrace::~WorldTrace() { static_cast<void>(close()); }

bool WorldTrace::write(const std::vector<double>& row) {
  if (!ok_ || limit_reached_) return false;
  line_.clear();
  for (std::size_t i = 0; i < row.size(); ++i)
    fmt::format_to(std::back_inserter(line_), "{}{}", i == 0 ? "" : ",", row[i]);
  line_ += '\n';
  if (limit_bytes_ != 0 && written_bytes_ + line_.size() > limit_bytes_) {
    limit_reached_ = true;
    return false;
  }
  ok_ = std::fwrite(line_.data(), 1, line_.size(), file_) == line_.size();
  written_bytes_ += line_.size();
  return ok_;
}

bool WorldTrace::flush() {
  if (file_ != nullptr && std::fflush(file_) != 0) ok_ = false;
  return ok_;
}

bool WorldTrace::close() {
  if (file_ == nullptr) return ok_;
  if (std::fflush(file_) != 0) ok_ = false;
  if (owned_ && std::fclose(file_) != 0) ok_ = false;
  file_ = nullptr;
  return ok_;
}

}  // namespace toonforce
