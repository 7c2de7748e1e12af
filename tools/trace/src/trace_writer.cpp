#include "toonforce/trace/trace_writer.hpp"

#include <cerrno>
#include <cstring>
#include <iterator>

#include <fmt/format.h>

namespace toonforce {

Result<std::unique_ptr<TraceWriter>> TraceWriter::open(const std::string& path, std::vector<std::string> extra_columns) {
  std::FILE* file = path == "-" ? stdout : std::fopen(path.c_str(), "wb");
  if (file == nullptr) return Error{fmt::format("{}: cannot open the trace for writing: {}", path, std::strerror(errno))};
  std::unique_ptr<TraceWriter> writer(new TraceWriter(file, path, extra_columns.size()));
  std::string header;
  for (const std::string_view c : kTraceCoreColumns) header += fmt::format("{}{}", header.empty() ? "" : ",", c);
  for (const std::string& c : extra_columns) header += "," + c;
  header += '\n';
  if (std::fwrite(header.data(), 1, header.size(), file) != header.size()) {
    return Error{fmt::format("{}: cannot write the trace header", path)};
  }
  return writer;
}

TraceWriter::TraceWriter(std::FILE* file, std::string path, std::size_t extras)
    : file_(file), path_(std::move(path)), extras_(extras) {}

TraceWriter::~TraceWriter() { static_cast<void>(close()); }

bool TraceWriter::write(const TraceCore& c, std::span<const double> extras) {
  if (failed_ || file_ == nullptr) return false;
  if (extras.size() != extras_) {
    failed_ = true;  // a programming error: the row would not match the header
    return false;
  }
  line_.clear();
  auto out = std::back_inserter(line_);
  fmt::format_to(out, "{},{},{},{},{},{},{},{},{},{}", c.t_s, c.position_m.x, c.position_m.y, c.position_m.z,
                 c.velocity_m_per_s.x, c.velocity_m_per_s.y, c.velocity_m_per_s.z, c.force_n.x, c.force_n.y,
                 c.force_n.z);
  for (const double v : extras) fmt::format_to(out, ",{}", v);
  line_ += '\n';
  if (std::fwrite(line_.data(), 1, line_.size(), file_) != line_.size()) {
    failed_ = true;
    return false;
  }
  ++rows_;
  return true;
}

bool TraceWriter::flush() {
  if (file_ != nullptr && std::fflush(file_) != 0) failed_ = true;
  return !failed_;
}

bool TraceWriter::close() {
  if (file_ == nullptr) return !failed_;
  if (std::fflush(file_) != 0) failed_ = true;
  if (file_ != stdout && std::fclose(file_) != 0) failed_ = true;
  file_ = nullptr;
  return !failed_;
}

}  // namespace toonforce
