// SPDX-License-Identifier: Apache-2.0
#include "toonforce/report/precision_reference.hpp"

#include <algorithm>
#include <limits>

namespace toonforce::report {

double observed_order(double error_at_rate, double error_at_double_rate) noexcept {
  if (!(error_at_rate > 0.0) || !(error_at_double_rate > 0.0) || !std::isfinite(error_at_rate) ||
      !std::isfinite(error_at_double_rate)) {
    return std::numeric_limits<double>::quiet_NaN();
  }
  return std::log2(error_at_rate / error_at_double_rate);
}

double richardson_error(double difference, double order) noexcept {
  if (!(order > 0.0)) return difference;
  return difference / (std::exp2(order) - 1.0);
}

double ladder_error(double difference, double previous_order, double order) noexcept {
  if (!(std::abs(order - previous_order) <= 0.5)) return difference;  // NaN too
  return richardson_error(difference, order);
}

std::string_view event_kind_name(EventKind kind) noexcept {
  switch (kind) {
    case EventKind::kContactOnset: return "contact onset";
    case EventKind::kContactEnd: return "contact end";
    case EventKind::kImpactTrigger: return "impact trigger";
    case EventKind::kCliffFall: return "cliff fall";
  }
  return "?";
}

std::vector<Event> find_events(const std::vector<TickState>& ticks, double t0_s, double rate_hz) {
  std::vector<Event> events;
  for (std::size_t k = 1; k < ticks.size(); ++k) {
    const TickState& a = ticks[k - 1];
    const TickState& b = ticks[k];
    const double t = t0_s + static_cast<double>(k) / rate_hz;
    if (!a.in_contact && b.in_contact) events.push_back({EventKind::kContactOnset, t});
    if (a.in_contact && !b.in_contact) events.push_back({EventKind::kContactEnd, t});
    // A restart: none running before, or the time since trigger went back.
    if (!std::isnan(b.impact_t_s) && (std::isnan(a.impact_t_s) || b.impact_t_s < a.impact_t_s)) {
      events.push_back({EventKind::kImpactTrigger, t});
    }
    if (b.cliffs_fallen > a.cliffs_fallen) events.push_back({EventKind::kCliffFall, t});
  }
  return events;
}

std::vector<Lateness> event_lateness(const std::vector<Event>& reference, const std::vector<Event>& run, double early_s,
                                     double late_s) {
  std::vector<Lateness> out;
  for (const EventKind kind :
       {EventKind::kContactOnset, EventKind::kContactEnd, EventKind::kImpactTrigger, EventKind::kCliffFall}) {
    Lateness l;
    l.kind = kind;
    double sum = 0.0;
    bool any = false;
    for (const Event& r : reference) {
      if (r.kind != kind) continue;
      double best = std::numeric_limits<double>::infinity();
      for (const Event& e : run) {  // in time order: the first one in the window
        if (e.kind == kind && e.t_s >= r.t_s - early_s) {
          best = e.t_s - r.t_s;
          break;
        }
      }
      if (!(best <= late_s)) {
        ++l.unmatched;
        continue;
      }
      ++l.matched;
      sum += best;
      l.max_late_s = any ? std::max(l.max_late_s, best) : best;
      l.min_late_s = any ? std::min(l.min_late_s, best) : best;
      any = true;
    }
    l.mean_late_s = l.matched > 0 ? sum / static_cast<double>(l.matched) : 0.0;
    if (l.matched + l.unmatched > 0) out.push_back(l);
  }
  return out;
}

bool near_event(const std::vector<Event>& events, double t_s, double before_s, double after_s) noexcept {
  // The first event later than t - after: only it and the ones up to t + before can cover t.
  auto it =
      std::lower_bound(events.begin(), events.end(), t_s - after_s, [](const Event& e, double t) { return e.t_s < t; });
  for (; it != events.end() && it->t_s <= t_s + before_s; ++it) {
    if (t_s >= it->t_s - before_s && t_s <= it->t_s + after_s) return true;
  }
  return false;
}

}  // namespace toonforce::report
