#pragma once
/// Writing the `toonforce sim` trace (interfaces.md): a header row, then one row per servo
/// tick, every number written so that it reads back as the same double (fmt's shortest
/// round-trip form, so identical runs give identical bytes). This is the only place that
/// knows the trace format: when the servo loop's telemetry writer lands, this class is what
/// gives way to it.
///
/// Columns, in order:
///   t,x,y,z,vx,vy,vz,fx,fy,fz   time [s]; HIP position [m] and velocity [m/s] as the
///                               controller saw them; commanded force [N] after safety
///   faults,limits               Fault and Limit bits of the tick
///   contact,impact_t,cliff_state  in contact (0/1); seconds since the running impact
///                               transient's trigger (nan if none); first cliff: -1 none,
///                               0 supported, 1 fallen (all three empty on a fault tick)
///   true_x..true_vz             the handle's true position and velocity (not delayed, not
///                               quantised)
///   hand_x,hand_y,hand_z        the hand's reference (where it aims)
///   device_fx..device_fz        the force the device applied (saturated, quantised, held)
///   segment                     hand script segment index from 0 (= count after the script)

#include <cstdio>
#include <memory>
#include <string>
#include <string_view>

#include "toonforce/sim/closed_loop.hpp"

namespace toonforce {

class SimTraceWriter {
 public:
  static constexpr std::string_view kHeader =
      "t,x,y,z,vx,vy,vz,fx,fy,fz,faults,limits,contact,impact_t,cliff_state,"
      "true_x,true_y,true_z,true_vx,true_vy,true_vz,hand_x,hand_y,hand_z,"
      "device_fx,device_fy,device_fz,segment";

  /// Opens `path` for writing ("-": standard output) and writes the header.
  static Result<SimTraceWriter> open(const std::string& path);
  /// A writer into memory (tests, benchmarks); text() returns what it wrote.
  static SimTraceWriter in_memory();

  void write(const SimRecord& record);
  /// Flushes and closes; an error if any write failed.
  Result<bool> close();
  /// What an in-memory writer has written so far.
  const std::string& text() {
    flush();
    return memory_;
  }

  SimTraceWriter(SimTraceWriter&&) noexcept = default;
  SimTraceWriter& operator=(SimTraceWriter&&) noexcept = default;
  ~SimTraceWriter();

 private:
  struct FileCloser {
    void operator()(std::FILE* f) const noexcept;
  };
  SimTraceWriter();
  void flush();
  void append(std::string_view text);

  std::unique_ptr<std::FILE, FileCloser> file_;
  std::string path_;
  std::unique_ptr<char[]> buffer_;  ///< fixed size: flushed before a row might not fit
  std::size_t used_ = 0;
  std::string memory_;
  bool to_memory_ = false;
  bool failed_ = false;
};

}  // namespace toonforce
