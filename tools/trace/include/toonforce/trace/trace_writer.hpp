#pragma once
/// A trace: a CSV file whose first ten columns are fixed by the spec (interfaces.md, `toonforce
/// sim` and `toonforce run`): t,x,y,z,vx,vy,vz,fx,fy,fz (time [s], HIP position [m] and velocity
/// [m/s] as the controller saw them, commanded force [N]), then any extra columns a producer
/// names. Numbers are written so that they read back as the same double ("nan" for NaN, as
/// replay writes). Each row goes out as one whole line, so a trace cut short by a stop is valid
/// up to its last complete row.
///
///   auto w = TraceWriter::open("out.csv", {"faults", "contact"});
///   w->write({t, x, v, f}, {faults, contact});

#include <array>
#include <cstdio>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "toonforce/common/result.hpp"
#include "toonforce/math/vec3.hpp"

namespace toonforce {

/// The ten columns every trace starts with.
inline constexpr std::array<std::string_view, 10> kTraceCoreColumns{"t", "x", "y", "z", "vx", "vy", "vz",
                                                                    "fx", "fy", "fz"};

/// The ten core values of one row.
struct TraceCore {
  double t_s = 0.0;
  Vec3<double> position_m;
  Vec3<double> velocity_m_per_s;
  Vec3<double> force_n;
};

class TraceWriter {
 public:
  /// Creates `path` ("-" for standard output) and writes the header.
  static Result<std::unique_ptr<TraceWriter>> open(const std::string& path, std::vector<std::string> extra_columns);
  ~TraceWriter();
  TraceWriter(const TraceWriter&) = delete;
  TraceWriter& operator=(const TraceWriter&) = delete;

  /// One row; `extras` must have one value per extra column. False once a write failed.
  bool write(const TraceCore& core, std::span<const double> extras);
  /// Flushes to the operating system; false if any write failed.
  bool flush();
  /// Flushes and closes; false if any write failed. Called by the destructor if not before.
  bool close();

  std::size_t rows() const noexcept { return rows_; }
  std::size_t extra_columns() const noexcept { return extras_; }
  const std::string& path() const noexcept { return path_; }

 private:
  TraceWriter(std::FILE* file, std::string path, std::size_t extras);

  std::FILE* file_;
  std::string path_;
  std::size_t extras_;
  std::size_t rows_ = 0;
  bool failed_ = false;
  std::string line_;  ///< reused row buffer
};

}  // namespace toonforce
