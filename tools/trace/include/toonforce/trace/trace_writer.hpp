// SPDX-License-Identifier: Apache-2.0
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
inline constexpr std::array<std::string_view, 10> kTraceCoreColumns{"t",  "x",  "y",  "z",  "vx",
                                                                    "vy", "vz", "fx", "fy", "fz"};

/// The largest trace `run` and `sim` write unless told otherwise (--max-output): 1 GiB, about
/// one to two and a half hours of a 1 kHz `run` trace (120-350 bytes a row). Reaching it warns and stops the trace, never the run.
inline constexpr std::uint64_t kDefaultTraceLimitBytes = std::uint64_t{1} << 30;

/// What to tell the user before a trace of about `expected_bytes` (0: unknown, e.g. a run until
/// stopped) is written to `path` under `limit_bytes` (0: none): that it will pass the limit, or
/// that its file system has less room than it may take. Empty when there is nothing to say.
std::string trace_room_warning(const std::string& path, std::uint64_t expected_bytes, std::uint64_t limit_bytes);

/// "1.5 GiB", "300 MiB", "12 KiB", "512 bytes".
std::string describe_bytes(std::uint64_t bytes);

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
  /// Goes on writing rows at the end of an existing trace (its header already there), after
  /// cutting it back to its last whole row: `toonforce run`'s guardian ends the trace of a
  /// loop process that died in the middle of a row (tools/run/guardian.hpp).
  static Result<std::unique_ptr<TraceWriter>> append_to(const std::string& path,
                                                        std::vector<std::string> extra_columns);
  /// A writer into memory (tests, benchmarks); text() returns what it wrote.
  static std::unique_ptr<TraceWriter> in_memory(std::vector<std::string> extra_columns);
  ~TraceWriter();
  TraceWriter(const TraceWriter&) = delete;
  TraceWriter& operator=(const TraceWriter&) = delete;

  /// One row; `extras` must have one value per extra column. False once a write failed or the
  /// size limit was reached (size_limit_reached() tells which).
  bool write(const TraceCore& core, std::span<const double> extras);
  /// At most `max_bytes` (header included; 0: no limit): a row that would go past it is not
  /// written, nor any after it, so the file ends on a whole row (a long hand-script
  /// hold filled a disk at 50 MB/s without a word).
  void limit_size(std::uint64_t max_bytes) noexcept { limit_bytes_ = max_bytes; }
  bool size_limit_reached() const noexcept { return limit_reached_; }
  std::uint64_t size_bytes() const noexcept { return size_bytes_; }  ///< header and rows written
  /// Hands the buffered rows to the operating system; false if any write failed. After a
  /// failed write (a full disk, EFBIG under `ulimit -f`) nothing more is written to the file,
  /// and a regular file is cut back to its last whole row.
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
  bool put_out(const char* data, std::size_t size);
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
  std::uint64_t limit_bytes_ = 0;  ///< 0: none
  std::uint64_t size_bytes_ = 0;
  bool limit_reached_ = false;
  bool to_memory_ = false;
  std::unique_ptr<char[]> buffer_;  ///< whole rows only, flushed before a row might not fit
  std::size_t used_ = 0;
  std::uint64_t committed_ = 0;  ///< bytes the file holds for sure: whole rows (and the header)
  std::string memory_;
  std::vector<LastValue> last_;  ///< one per column
};

}  // namespace toonforce
