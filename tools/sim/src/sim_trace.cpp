#include "toonforce/sim/sim_trace.hpp"


#include <fmt/compile.h>
#include <fmt/format.h>

namespace toonforce {

namespace {
constexpr std::size_t kCapacity = 1 << 16;
// A row is 25 numbers of at most 24 characters (shortest round-trip doubles) and 3 small
// integers, with separators: well under this.
constexpr std::size_t kRowMax = 1024;
}  // namespace

SimTraceWriter::SimTraceWriter() : buffer_(new char[kCapacity]) {}

void SimTraceWriter::append(std::string_view text) {
  if (kCapacity - used_ < text.size()) flush();
  text.copy(buffer_.get() + used_, text.size());
  used_ += text.size();
}

void SimTraceWriter::FileCloser::operator()(std::FILE* f) const noexcept {
  if (f != nullptr && f != stdout) std::fclose(f);
}

Result<SimTraceWriter> SimTraceWriter::open(const std::string& path) {
  SimTraceWriter writer;
  writer.path_ = path;
  writer.file_.reset(path == "-" ? stdout : std::fopen(path.c_str(), "wb"));
  if (!writer.file_) return Error{fmt::format("{}: cannot open the trace for writing", path)};
  writer.append(kHeader);
  writer.append("\n");
  return writer;
}

SimTraceWriter SimTraceWriter::in_memory() {
  SimTraceWriter writer;
  writer.to_memory_ = true;
  writer.append(kHeader);
  writer.append("\n");
  return writer;
}

SimTraceWriter::~SimTraceWriter() {
  if (file_) flush();
}

void SimTraceWriter::write(const SimRecord& r) {
  if (kCapacity - used_ < kRowMax) flush();
  // Straight into the buffer (no growth checks per number), with compiled format strings:
  // formatting is the dearest part of a traced run (see the benchmark).
  char* out = buffer_.get() + used_;
  const auto& p = r.position_m;
  const auto& v = r.velocity_m_per_s;
  const auto& f = r.force_n;
  out = fmt::format_to(out, FMT_COMPILE("{},{},{},{},{},{},{},{},{},{},{},{},"), r.t_s, p.x, p.y, p.z, v.x, v.y, v.z, f.x, f.y, f.z,
                 r.faults, r.limits);
  if (r.has_diagnostics) {
    const Diagnostics& d = r.diagnostics;
    out = fmt::format_to(out, FMT_COMPILE("{},{},{},"), d.in_contact ? 1 : 0, d.impact_time_s, d.cliff_state);
  } else {
    out = fmt::format_to(out, FMT_COMPILE(",,,"));
  }
  const auto& tx = r.true_position_m;
  const auto& tv = r.true_velocity_m_per_s;
  const auto& h = r.hand_target_m;
  const auto& df = r.device_force_n;
  out = fmt::format_to(out, FMT_COMPILE("{},{},{},{},{},{},{},{},{},{},{},{},{}\n"), tx.x, tx.y, tx.z, tv.x, tv.y, tv.z, h.x, h.y, h.z,
                 df.x, df.y, df.z, r.segment);
  used_ = static_cast<std::size_t>(out - buffer_.get());
}

void SimTraceWriter::flush() {
  if (to_memory_) {
    memory_.append(buffer_.get(), used_);
  } else if (file_ && used_ > 0) {
    if (std::fwrite(buffer_.get(), 1, used_, file_.get()) != used_) failed_ = true;
  }
  used_ = 0;
}

Result<bool> SimTraceWriter::close() {
  flush();
  if (file_) {
    if (std::fflush(file_.get()) != 0) failed_ = true;
    if (file_.get() != stdout && std::fclose(file_.release()) != 0) failed_ = true;
    file_.reset();
  }
  if (failed_) return Error{fmt::format("{}: writing the trace failed (disk full?)", path_)};
  return true;
}

}  // namespace toonforce
