#pragma once
/// A trace: a CSV file whose first ten columns are fixed by the spec (interfaces.md, `toonforce
/// sim` and `toonforce run`): t,x,y,z,vx,vy,vz,fx,fy,fz (time [s], HIP position [m] and velocity
/// [m/s] as the controller saw them, commanded force [N]), then any extra columns a producer
/// names. Numbers are written so that they read back as the same double ("nan" for NaN, as
/// replay writes), in fmt's shortest round-trip form, so identical runs give identical bytes.
/// Rows are buffered and handed to the operating system whole, so a trace cut short by a stop
/// is valid up to its last complete row. `toonforce run` and `toonforce sim` both write theirs
/// with it (telemetry_trace.hpp gives the servo loop's columns).
///
///   auto w = TraceWriter::open("out.csv", {"faults", "contact"});
///   w->write({t, x, v, f}, {faults, contact});

#include <array>
#include <cstdint>
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
  /// A writer into memory (tests, benchmarks); text() returns what it wrote.
  static std::unique_ptr<TraceWriter> in_memory(std::vector<std::string> extra_columns);
  ~TraceWriter();
  TraceWriter(const TraceWriter&) = delete;
  TraceWriter& operator=(const TraceWriter&) = delete;

  /// One row; `extras` must have one value per extra column. False once a write failed.
  bool write(const TraceCore& core, std::span<const double> extras);
  /// Hands the buffered rows to the operating system; false if any write failed.
  bool flush();
  /// Flushes and closes; false if any write failed. Called by the destructor if not before.
  bool close();
  /// What an in-memory writer has written so far.
  const std::string& text();

  std::size_t rows() const noexcept { return rows_; }
  std::size_t extra_columns() const noexcept { return extras_; }
  const std::string& path() const noexcept { return path_; }
  const std::vector<std::string>& columns() const noexcept { return columns_; }

 private:
  TraceWriter(std::FILE* file, std::string path, std::vector<std::string> extra_columns);
  void append(std::string_view text);
  char* put(char* out, std::size_t column, double x) noexcept;

  /// A column's last value and its text: a value that repeats from one row to the next (a
  /// held hand, an idle observer, a latched state) is copied, not formatted again.
  struct LastValue {
    std::uint64_t bits = 0;
    std::uint8_t size = 0;  ///< 0: nothing yet
    char text[26] = {};
  };

  std::FILE* file_;
  std::string path_;
  std::size_t extras_;
  std::vector<std::string> columns_;  ///< every column, the core ten first
  std::size_t rows_ = 0;
  bool failed_ = false;
  bool to_memory_ = false;
  std::unique_ptr<char[]> buffer_;  ///< whole rows only, flushed before a row might not fit
  std::size_t used_ = 0;
  std::string memory_;
  std::vector<LastValue> last_;  ///< one per column
};

}  // namespace toonforce
