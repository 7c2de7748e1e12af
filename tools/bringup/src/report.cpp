// SPDX-License-Identifier: Apache-2.0
// Bring-up reports (see report.hpp).
#include "toonforce/bringup/report.hpp"

#include <algorithm>
#include <cmath>
#include <ctime>
#include <fstream>

#include <fmt/format.h>

#include "toonforce/trace/json.hpp"

namespace toonforce::bringup {

std::string_view to_string(Outcome o) noexcept {
  switch (o) {
    case Outcome::kPass: return "pass";
    case Outcome::kWarn: return "warn";
    case Outcome::kFail: return "FAIL";
    case Outcome::kSkipped: return "skipped";
  }
  return "?";
}

HistogramBuilder::HistogramBuilder(double bucket_width, std::size_t buckets, std::string unit)
    : width_(bucket_width), buckets_(std::max<std::size_t>(buckets, 1)), unit_(std::move(unit)) {}

Histogram HistogramBuilder::build() const {
  Histogram h;
  h.unit = unit_;
  h.bucket_width = width_;
  h.counts.assign(buckets_ + 1, 0);
  h.samples = values_.size();
  if (values_.empty()) return h;
  std::vector<double> sorted = values_;
  std::sort(sorted.begin(), sorted.end());
  const auto at = [&](double q) {
    const auto i = static_cast<std::size_t>(std::ceil(q * static_cast<double>(sorted.size()))) - 1;
    return sorted[std::min(i, sorted.size() - 1)];
  };
  h.min = sorted.front();
  h.max = sorted.back();
  h.p50 = at(0.50);
  h.p99 = at(0.99);
  for (const double v : values_) {
    const double bucket = std::floor(std::max(v, 0.0) / width_);
    const auto i = bucket >= static_cast<double>(buckets_) ? buckets_ : static_cast<std::size_t>(bucket);
    ++h.counts[i];
  }
  return h;
}

bool Report::passed() const noexcept {
  return std::none_of(steps.begin(), steps.end(), [](const StepReport& s) { return s.outcome == Outcome::kFail; });
}

const StepReport* Report::step(std::string_view id) const noexcept {
  for (const auto& s : steps) {
    if (s.id == id) return &s;
  }
  return nullptr;
}

namespace {

std::string md_escape(std::string_view text) {
  std::string out;
  for (const char c : text) {
    if (c == '|')
      out += "\\|";
    else if (c == '\n')
      out += "<br>";
    else
      out += c;
  }
  return out;
}

std::string histogram_markdown(const Histogram& h) {
  std::string out = fmt::format("\n{} samples: min {:.1f}, median {:.1f}, p99 {:.1f}, max {:.1f} {}\n\n", h.samples,
                                h.min, h.p50, h.p99, h.max, h.unit);
  out += fmt::format("| {} | count | |\n| --- | --- | --- |\n", h.unit);
  const std::uint64_t peak = h.counts.empty() ? 0 : *std::max_element(h.counts.begin(), h.counts.end());
  for (std::size_t i = 0; i < h.counts.size(); ++i) {
    if (h.counts[i] == 0) continue;
    const std::string range = i + 1 == h.counts.size()
                                  ? fmt::format(">= {:.0f}", static_cast<double>(i) * h.bucket_width)
                                  : fmt::format("{:.0f}-{:.0f}", static_cast<double>(i) * h.bucket_width,
                                                static_cast<double>(i + 1) * h.bucket_width);
    const std::size_t bar = peak == 0 ? 0 : static_cast<std::size_t>(40 * h.counts[i] / peak);
    out += fmt::format("| {} | {} | {} |\n", range, h.counts[i], std::string(std::max<std::size_t>(bar, 1), '#'));
  }
  return out;
}

std::string number(double v) { return std::isfinite(v) ? fmt::format("{:.17g}", v) : "null"; }

}  // namespace

std::string to_markdown(const Report& r) {
  std::string out = fmt::format("# Bring-up of the {}\n\n", r.device);
  out += fmt::format("- device: {}\n- started: {}\n- toonforce: {}\n- result: **{}**\n\n",
                     r.target.empty() ? "?" : r.target, r.started_utc, r.toonforce_version,
                     r.passed() ? "no step failed" : "a step FAILED");
  out += "| step | result | finding |\n| --- | --- | --- |\n";
  for (const auto& s : r.steps) {
    out += fmt::format("| {} | {} | {} |\n", s.title, to_string(s.outcome), md_escape(s.finding));
  }
  for (const auto& s : r.steps) {
    out += fmt::format("\n## {} ({})\n\n**{}**: {}\n", s.title, s.id, to_string(s.outcome), s.finding);
    if (!s.next.empty()) out += fmt::format("\nWhat to do: {}\n", s.next);
    if (!s.measurements.empty()) {
      out += "\n| measurement | value |\n| --- | --- |\n";
      for (const auto& m : s.measurements) {
        out += fmt::format("| {} | {}{}{} |\n", m.name, md_escape(m.value), m.unit.empty() ? "" : " ", m.unit);
      }
    }
    if (s.histogram) out += histogram_markdown(*s.histogram);
  }
  return out;
}

std::string to_json(const Report& r) {
  std::string out = "{\n";
  out += fmt::format("  \"device\": {},\n  \"target\": {},\n  \"started_utc\": {},\n  \"toonforce_version\": {},\n",
                     json_string(r.device), json_string(r.target), json_string(r.started_utc),
                     json_string(r.toonforce_version));
  out += fmt::format("  \"passed\": {},\n  \"steps\": [", r.passed() ? "true" : "false");
  for (std::size_t i = 0; i < r.steps.size(); ++i) {
    const StepReport& s = r.steps[i];
    out += fmt::format(
        "{}\n    {{\"id\": {}, \"title\": {}, \"outcome\": {}, \"finding\": {}, \"next\": {}, \"measurements\": {{",
        i == 0 ? "" : ",", json_string(s.id), json_string(s.title),
        json_string(s.outcome == Outcome::kFail ? "fail" : to_string(s.outcome)), json_string(s.finding),
        json_string(s.next));
    for (std::size_t m = 0; m < s.measurements.size(); ++m) {
      const Measurement& x = s.measurements[m];
      out += fmt::format("{}{}: {{\"value\": {}, \"unit\": {}}}", m == 0 ? "" : ", ", json_string(x.name),
                         json_string(x.value), json_string(x.unit));
    }
    out += "}";
    if (s.histogram) {
      const Histogram& h = *s.histogram;
      out += fmt::format(", \"histogram\": {{\"unit\": {}, \"bucket_width\": {}, \"samples\": {}, \"min\": {}, "
                         "\"p50\": {}, \"p99\": {}, \"max\": {}, \"counts\": [",
                         json_string(h.unit), number(h.bucket_width), h.samples, number(h.min), number(h.p50),
                         number(h.p99), number(h.max));
      for (std::size_t c = 0; c < h.counts.size(); ++c) out += fmt::format("{}{}", c == 0 ? "" : ", ", h.counts[c]);
      out += "]}";
    }
    out += "}";
  }
  out += "\n  ]\n}\n";
  return out;
}

Result<std::vector<std::string>> write_report(const Report& report, const std::string& base) {
  std::vector<std::string> written;
  for (const auto& [extension, text] : {std::pair{".md", to_markdown(report)}, std::pair{".json", to_json(report)}}) {
    const std::string path = base + extension;
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out << text;
    out.close();
    if (!out) return Error{fmt::format("{}: cannot write the bring-up report", path)};
    written.push_back(path);
  }
  return written;
}

std::string utc_now() {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%dT%H:%M:%SZ", &utc);
  return text;
}

}  // namespace toonforce::bringup
