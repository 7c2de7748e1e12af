// SPDX-License-Identifier: Apache-2.0
#include "toonforce/trace/trace_writer.hpp"

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <system_error>

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

Result<std::unique_ptr<TraceWriter>> TraceWriter::open(const std::string& path,
                                                       std::vector<std::string> extra_columns) {
  std::FILE* file = path == "-" ? stdout : std::fopen(path.c_str(), "wb");
  if (file == nullptr)
    return Error{fmt::format("{}: cannot open the trace for writing: {}", path, std::strerror(errno))};
  // Unbuffered: the writer's own buffer holds whole rows, so a failed write leaves nothing in
  // stdio for fclose to try again, and the file can be cut back to its last whole row.
  if (file != stdout) std::setvbuf(file, nullptr, _IONBF, 0);
  std::unique_ptr<TraceWriter> writer(new TraceWriter(file, path, std::move(extra_columns)));
  if (!writer->flush()) return Error{fmt::format("{}: cannot write the trace header", path)};
  return writer;
}

Result<std::unique_ptr<TraceWriter>> TraceWriter::append_to(const std::string& path,
                                                            std::vector<std::string> extra_columns) {
  std::FILE* file = std::fopen(path.c_str(), "r+b");
  if (file == nullptr) return Error{fmt::format("{}: cannot open the trace to end it: {}", path, std::strerror(errno))};
  // Back to the end of the last whole row: a writer killed in the middle of one leaves a part.
  std::setvbuf(file, nullptr, _IONBF, 0);
  off_t size = 0;
  if (std::fseek(file, 0, SEEK_END) == 0) size = ftello(file);
  char chunk[4096];
  off_t end = size;
  while (end > 0) {
    const off_t from = std::max<off_t>(0, end - static_cast<off_t>(sizeof chunk));
    const auto n = static_cast<std::size_t>(end - from);
    if (fseeko(file, from, SEEK_SET) != 0 || std::fread(chunk, 1, n, file) != n) break;
    const void* nl = memrchr(chunk, '\n', n);
    if (nl != nullptr) {
      end = from + static_cast<off_t>(static_cast<const char*>(nl) - chunk) + 1;
      break;
    }
    end = from;
  }
  if (end != size && ftruncate(fileno(file), end) != 0) {
    const int error = errno;
    std::fclose(file);
    return Error{fmt::format("{}: cannot cut the trace back to its last whole row: {}", path, std::strerror(error))};
  }
  if (fseeko(file, end, SEEK_SET) != 0) {
    const int error = errno;
    std::fclose(file);
    return Error{fmt::format("{}: cannot go to the trace's end: {}", path, std::strerror(error))};
  }
  std::unique_ptr<TraceWriter> writer(new TraceWriter(file, path, std::move(extra_columns)));
  writer->used_ = 0;  // the header is in the file already
  writer->size_bytes_ = static_cast<std::uint64_t>(end);
  writer->committed_ = static_cast<std::uint64_t>(end);
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
  size_bytes_ += text.size();
  if (kCapacity - used_ < text.size()) flush();
  if (text.size() > kCapacity) {  // a header longer than the buffer: straight through
    if (to_memory_) {
      memory_.append(text);
    } else if (file_ != nullptr) {
      put_out(text.data(), text.size());
    }
    return;
  }
  text.copy(buffer_.get() + used_, text.size());
  used_ += text.size();
}

bool TraceWriter::write(const TraceCore& c, std::span<const double> extras) {
  if (failed_ || limit_reached_ || (file_ == nullptr && !to_memory_)) return false;
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
  const std::size_t end = static_cast<std::size_t>(out - buffer_.get());
  const std::uint64_t row_bytes = end - used_;
  if (limit_bytes_ != 0 && size_bytes_ + row_bytes > limit_bytes_) {
    limit_reached_ = true;  // the row stays unwritten (used_ not advanced): the file ends whole
    return false;
  }
  size_bytes_ += row_bytes;
  used_ = end;
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

bool TraceWriter::put_out(const char* data, std::size_t size) {
  // After a failed write (the stream's error flag), not one byte more to that file. (failed_
  // may also mean a row that did not match the header: the rows before it still go out.)
  if (std::ferror(file_) != 0) return false;
  if (std::fwrite(data, 1, size, file_) == size && std::fflush(file_) == 0) {
    committed_ += size;
    return true;
  }
  failed_ = true;
  const int error = errno;  // what the caller reports (ENOSPC, EFBIG, EPIPE, ...)
  // A regular file ends on its last whole row, not on the part of one the disk took.
  struct stat st {};
  if (file_ != stdout && fstat(fileno(file_), &st) == 0 && S_ISREG(st.st_mode)) {
    static_cast<void>(ftruncate(fileno(file_), static_cast<off_t>(committed_)));
  }
  errno = error;
  return false;
}

bool TraceWriter::flush() {
  if (to_memory_) {
    memory_.append(buffer_.get(), used_);
  } else if (file_ != nullptr && used_ > 0) {
    put_out(buffer_.get(), used_);
  } else if (file_ != nullptr && std::ferror(file_) == 0 && std::fflush(file_) != 0) {
    failed_ = true;
  }
  used_ = 0;
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

std::string describe_bytes(std::uint64_t bytes) {
  const double b = static_cast<double>(bytes);
  if (bytes >= (std::uint64_t{1} << 30)) return fmt::format("{:.3g} GiB", b / 1073741824.0);
  if (bytes >= (std::uint64_t{1} << 20)) return fmt::format("{:.3g} MiB", b / 1048576.0);
  if (bytes >= (std::uint64_t{1} << 10)) return fmt::format("{:.3g} KiB", b / 1024.0);
  return fmt::format("{} bytes", bytes);
}

std::string trace_room_warning(const std::string& path, std::uint64_t expected_bytes, std::uint64_t limit_bytes) {
  if (path.empty() || path == "-") return {};
  std::string out;
  if (limit_bytes != 0 && expected_bytes > limit_bytes) {
    out += fmt::format("{}: this trace would be about {}, over --max-output {}: it stops there (the run goes on); "
                       "--max-output 0 lifts the limit\n",
                       path, describe_bytes(expected_bytes), describe_bytes(limit_bytes));
  }
  // Room on the file system the trace goes to: what the trace may take is the smaller of its
  // expected size and the limit (both may be unknown: then the limit alone).
  std::uint64_t may_take = limit_bytes;
  if (expected_bytes != 0 && (may_take == 0 || expected_bytes < may_take)) may_take = expected_bytes;
  std::error_code ec;
  std::filesystem::path dir = std::filesystem::absolute(path, ec).parent_path();
  const std::filesystem::space_info room = std::filesystem::space(dir, ec);
  if (!ec && may_take != 0 && room.available < may_take) {
    out += fmt::format("{}: its file system has {} free, and the trace may take {}: it would stop when the disk is "
                       "full (the run goes on)\n",
                       path, describe_bytes(room.available), describe_bytes(may_take));
  }
  return out;
}

}  // namespace toonforce
