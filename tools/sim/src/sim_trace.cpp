#include "toonforce/sim/sim_trace.hpp"

#include <iterator>

namespace toonforce {

namespace {
constexpr std::size_t kFlushBytes = 1 << 16;
}

void SimTraceWriter::FileCloser::operator()(std::FILE* f) const noexcept {
  if (f != nullptr && f != stdout) std::fclose(f);
}

Result<SimTraceWriter> SimTraceWriter::open(const std::string& path) {
  SimTraceWriter writer;
  writer.path_ = path;
  writer.file_.reset(path == "-" ? stdout : std::fopen(path.c_str(), "wb"));
  if (!writer.file_) return Error{fmt::format("{}: cannot open the trace for writing", path)};
  fmt::format_to(std::back_inserter(writer.buffer_), "{}\n", kHeader);
  return writer;
}

SimTraceWriter SimTraceWriter::in_memory() {
  SimTraceWriter writer;
  writer.to_memory_ = true;
  fmt::format_to(std::back_inserter(writer.buffer_), "{}\n", kHeader);
  return writer;
}

SimTraceWriter::~SimTraceWriter() {
  if (file_) flush();
}

void SimTraceWriter::write(const SimRecord& r) {
  auto out = std::back_inserter(buffer_);
  const auto& p = r.position_m;
  const auto& v = r.velocity_m_per_s;
  const auto& f = r.force_n;
  fmt::format_to(out, "{},{},{},{},{},{},{},{},{},{},{},{},", r.t_s, p.x, p.y, p.z, v.x, v.y, v.z, f.x, f.y, f.z,
                 r.faults, r.limits);
  if (r.has_diagnostics) {
    const Diagnostics& d = r.diagnostics;
    fmt::format_to(out, "{},{},{},", d.in_contact ? 1 : 0, d.impact_time_s, d.cliff_state);
  } else {
    fmt::format_to(out, ",,,");
  }
  const auto& tx = r.true_position_m;
  const auto& tv = r.true_velocity_m_per_s;
  const auto& h = r.hand_target_m;
  const auto& df = r.device_force_n;
  fmt::format_to(out, "{},{},{},{},{},{},{},{},{},{},{},{},{}\n", tx.x, tx.y, tx.z, tv.x, tv.y, tv.z, h.x, h.y, h.z,
                 df.x, df.y, df.z, r.segment);
  if (buffer_.size() >= kFlushBytes) flush();
}

void SimTraceWriter::flush() {
  if (to_memory_) {
    memory_.append(buffer_.data(), buffer_.size());
  } else if (file_ && buffer_.size() > 0) {
    if (std::fwrite(buffer_.data(), 1, buffer_.size(), file_.get()) != buffer_.size()) failed_ = true;
  }
  buffer_.clear();
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
