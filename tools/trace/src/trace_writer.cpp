#include "toonforce/trace/trace_writer.hpp"

#include <bit>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>

#include <fmt/compile.h>
#include <fmt/format.h>

namespace toonforce {

namespace {
constexpr std::size_t kCapacity = std::size_t{1} << 16;
/// A value is at most 24 characters in its shortest round-trip form, plus the separator.
constexpr std::size_t kValueMax = 26;

/// One value in its shortest round-trip form, as fmt's "{}" writes it. Most columns of a row
/// hold whole numbers (zeros of the axes a stroke does not use, flags, states, the tick), and
/// fmt writes a whole double exactly as the integer it equals; the integer path gives the same
/// characters for about a tenth of the shortest-double search's cost (the dearest part of a
/// traced simulation, tools/bench/sim_speed.cpp). -0 keeps its sign, as "{}" writes it.
char* put_value(char* out, double x) noexcept {
  constexpr double kWholeMax = 1e15;  // fmt writes whole doubles below 1e16 without an exponent
  if (x > -kWholeMax && x < kWholeMax && x == static_cast<double>(static_cast<std::int64_t>(x)) &&
      !(x == 0.0 && std::signbit(x))) {
    return fmt::format_to(out, FMT_COMPILE("{}"), static_cast<std::int64_t>(x));
  }
  return fmt::format_to(out, FMT_COMPILE("{}"), x);
}
}  // namespace

Result<std::unique_ptr<TraceWriter>> TraceWriter::open(const std::string& path, std::vector<std::string> extra_columns) {
  std::FILE* file = path == "-" ? stdout : std::fopen(path.c_str(), "wb");
  if (file == nullptr) return Error{fmt::format("{}: cannot open the trace for writing: {}", path, std::strerror(errno))};
  std::unique_ptr<TraceWriter> writer(new TraceWriter(file, path, std::move(extra_columns)));
  if (!writer->flush()) return Error{fmt::format("{}: cannot write the trace header", path)};
  return writer;
}

std::unique_ptr<TraceWriter> TraceWriter::in_memory(std::vector<std::string> extra_columns) {
  std::unique_ptr<TraceWriter> writer(new TraceWriter(nullptr, "(memory)", std::move(extra_columns)));
  writer->to_memory_ = true;
  return writer;
}

TraceWriter::TraceWriter(std::FILE* file, std::string path, std::vector<std::string> extra_columns)
    : file_(file), path_(std::move(path)), extras_(extra_columns.size()), buffer_(new char[kCapacity]) {
  for (const std::string_view c : kTraceCoreColumns) columns_.emplace_back(c);
  for (std::string& c : extra_columns) columns_.push_back(std::move(c));
  last_.resize(columns_.size());
  std::string header;
  for (const std::string& c : columns_) header += (header.empty() ? "" : ",") + c;
  header += '\n';
  append(header);
}

TraceWriter::~TraceWriter() { static_cast<void>(close()); }

void TraceWriter::append(std::string_view text) {
  if (kCapacity - used_ < text.size()) flush();
  if (text.size() > kCapacity) {  // a header longer than the buffer: straight through
    if (to_memory_) {
      memory_.append(text);
    } else if (file_ != nullptr && std::fwrite(text.data(), 1, text.size(), file_) != text.size()) {
      failed_ = true;
    }
    return;
  }
  text.copy(buffer_.get() + used_, text.size());
  used_ += text.size();
}

bool TraceWriter::write(const TraceCore& c, std::span<const double> extras) {
  if (failed_ || (file_ == nullptr && !to_memory_)) return false;
  if (extras.size() != extras_) {
    failed_ = true;  // a programming error: the row would not match the header
    return false;
  }
  const std::size_t row_max = (kTraceCoreColumns.size() + extras.size()) * kValueMax + 1;
  if (kCapacity - used_ < row_max) flush();
  // Straight into the buffer with compiled format strings: formatting is the dearest part of
  // a traced simulation (tools/bench/sim_speed.cpp).
  char* out = buffer_.get() + used_;
  const auto& p = c.position_m;
  const auto& v = c.velocity_m_per_s;
  const auto& f = c.force_n;
  out = put(out, 0, c.t_s);
  std::size_t column = 1;
  for (const double x : {p.x, p.y, p.z, v.x, v.y, v.z, f.x, f.y, f.z}) {
    *out++ = ',';
    out = put(out, column++, x);
  }
  for (const double x : extras) {
    *out++ = ',';
    out = put(out, column++, x);
  }
  *out++ = '\n';
  used_ = static_cast<std::size_t>(out - buffer_.get());
  ++rows_;
  return true;
}

char* TraceWriter::put(char* out, std::size_t column, double x) noexcept {
  LastValue& last = last_[column];
  const auto bits = std::bit_cast<std::uint64_t>(x);
  if (last.size != 0 && last.bits == bits) {
    std::memcpy(out, last.text, last.size);
    return out + last.size;
  }
  char* const end = put_value(out, x);
  last.bits = bits;
  last.size = static_cast<std::uint8_t>(end - out);
  std::memcpy(last.text, out, last.size);
  return end;
}

bool TraceWriter::flush() {
  if (to_memory_) {
    memory_.append(buffer_.get(), used_);
  } else if (file_ != nullptr && used_ > 0) {
    if (std::fwrite(buffer_.get(), 1, used_, file_) != used_) failed_ = true;
  }
  used_ = 0;
  if (file_ != nullptr && std::fflush(file_) != 0) failed_ = true;
  return !failed_;
}

const std::string& TraceWriter::text() {
  flush();
  return memory_;
}

bool TraceWriter::close() {
  flush();
  if (file_ == nullptr) return !failed_;
  if (file_ != stdout && std::fclose(file_) != 0) failed_ = true;
  file_ = nullptr;
  return !failed_;
}

}  // namespace toonforce
