// SPDX-License-Identifier: Apache-2.0
#pragma once
// An independent reading of docs/spec/effects.md in plain double code, used as the oracle
// of the closed-form tests. It shares no code with effects/ or control/ (on purpose: a bug
// copied into both would pass unseen); it follows the spec's wording line by line, in the
// spec's own form (dt, not 1/dt), and favours clarity over speed.
#include <array>
#include <cmath>
#include <optional>
#include <vector>

namespace toonforce::oracle {

using V = std::array<double, 3>;
inline V add(V a, V b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
inline V sub(V a, V b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
inline V mul(V a, double k) { return {a[0] * k, a[1] * k, a[2] * k}; }
inline double dotp(V a, V b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
inline double len(V a) { return std::sqrt(dotp(a, a)); }
inline V unit(V a) { return mul(a, 1.0 / len(a)); }
inline bool finite(V a) { return std::isfinite(a[0]) && std::isfinite(a[1]) && std::isfinite(a[2]); }

struct Surface {
  V p0{};
  V n{0, 0, 1};  // unit
  double k = 0, b = 0;
  bool friction = false;
  double mu_v = 0, mu_c = 0, v_reg = 0.02;
  bool slippery = false;
  double mu = 0, max_t = 2;
  bool impact = false;
  double k_r = 0, k_osc = 0, d = 0, f = 0, v_min = 0.05, rearm = 0.001;
};
struct Cliff {
  V p0{};
  V n{0, 0, 1};
  V a{1, 0, 0};
  double gap_min = 0, gap_max = 0, k = 0, b = 0, threshold = 0, tau = 0.02, rearm_h = 0.001, fall = 0;
};
struct Scene {
  std::vector<Surface> surfaces;
  std::vector<Cliff> cliffs;
  bool surfaces_first = true;  // file order: all surfaces, then all cliffs (the tests' scenes)
  std::optional<double> max_force, max_rate;
  double f_c = 50.0;
};

struct Row {
  double t;
  V x;
  V v;  // used when given
};

// The force of every row, as spec §0-§6 say, for a replay (stamped time).
inline std::vector<V> replay(const Scene& scene, const std::vector<Row>& rows, bool velocity_given) {
  struct ImpactState {
    double prev_delta = 0;
    bool armed = true, running = false;
    double t0 = 0, v_i = 0;
  };
  std::vector<ImpactState> impacts(scene.surfaces.size());
  std::vector<double> s_f(scene.cliffs.size(), 0.0);
  std::vector<bool> fallen(scene.cliffs.size(), false);
  V v_est{}, x_prev{};
  double t_prev_good = 0;
  bool first_good = true;
  V f_prev{};
  std::vector<V> out;

  for (std::size_t k = 0; k < rows.size(); ++k) {
    const Row& r = rows[k];
    const double dt = k == 0 ? rows[1].t - rows[0].t : r.t - rows[k - 1].t;
    // §6.1 non-finite input: zero, previous output 0, no state update.
    if (!finite(r.x) || (velocity_given && !finite(r.v))) {
      out.push_back({0, 0, 0});
      f_prev = {0, 0, 0};
      continue;
    }
    // The effects' and the estimator's own dt: since their last update (hip_sensor.hpp).
    const double dt_state = first_good ? dt : r.t - t_prev_good;
    V v{};
    bool needs_velocity = !scene.cliffs.empty();
    for (const auto& s : scene.surfaces)
      needs_velocity = needs_velocity || s.b != 0 || s.friction || s.slippery || s.impact;
    auto impacts_next = impacts;
    auto s_f_next = s_f;
    auto fallen_next = fallen;
    V v_est_next = v_est;
    if (velocity_given) {
      v = r.v;
    } else if (needs_velocity) {
      if (!first_good) {
        const double a = dt_state / (dt_state + 1.0 / (2.0 * M_PI * scene.f_c));
        v_est_next = add(v_est, mul(sub(mul(sub(r.x, x_prev), 1.0 / dt_state), v_est), a));
      }
      v = v_est_next;
    }

    V total{};
    auto surface_force = [&](std::size_t i) {
      const Surface& s = scene.surfaces[i];
      const double delta = -dotp(s.n, sub(r.x, s.p0));
      const double nv = dotp(s.n, v);
      double fn = 0;
      if (delta > 0) fn = std::max(0.0, s.k * delta - s.b * nv);
      V f = mul(s.n, fn);
      if (delta > 0) {
        const V vt = sub(v, mul(s.n, nv));
        if (s.friction) {
          f = add(f, mul(vt, s.mu_v));
          f = add(f, mul(vt, -s.mu_c * fn / std::max(len(vt), s.v_reg)));
        }
        if (s.slippery) {
          V ft = mul(vt, s.mu);
          if (len(ft) > s.max_t) ft = mul(ft, s.max_t / len(ft));
          f = add(f, ft);
        }
      }
      if (s.impact) {
        ImpactState& st = impacts_next[i];
        const double prev = first_good ? delta : st.prev_delta;
        st.prev_delta = delta;
        if (!st.armed && delta <= -s.rearm) st.armed = true;
        const double v_i = -nv;
        if (prev <= 0 && delta > 0 && st.armed && v_i >= s.v_min) {
          st.running = true;
          st.armed = false;
          st.t0 = r.t;
          st.v_i = v_i;
        }
        if (st.running) {
          const double t = r.t - st.t0;
          if (t <= s.d) {
            f = add(f, mul(s.n, st.v_i * (s.d - t) * (s.k_r + s.k_osc * std::sin(2 * M_PI * s.f * t))));
          } else {
            st.running = false;
          }
        }
      }
      return f;
    };
    auto cliff_force = [&](std::size_t i) {
      const Cliff& c = scene.cliffs[i];
      const double delta = -dotp(c.n, sub(r.x, c.p0));
      const double nv = dotp(c.n, v);
      const double s = len(sub(v, mul(c.n, nv)));
      s_f_next[i] += dt_state / (c.tau + dt_state) * (s - s_f_next[i]);
      const double u = dotp(c.a, sub(r.x, c.p0));
      const bool strip = c.gap_min <= u && u <= c.gap_max;
      if (!fallen_next[i]) {
        if (strip && s_f_next[i] < c.threshold) fallen_next[i] = true;
      } else if (delta <= -c.rearm_h && (!strip || s_f_next[i] >= c.threshold)) {
        fallen_next[i] = false;
      }
      if (!fallen_next[i]) return delta > 0 ? mul(c.n, std::max(0.0, c.k * delta - c.b * nv)) : V{};
      if (strip) return mul(c.n, -c.fall);
      if (delta > 0) return u < c.gap_min ? mul(c.a, c.k * (c.gap_min - u)) : mul(c.a, -c.k * (u - c.gap_max));
      return V{};
    };
    for (std::size_t i = 0; i < scene.surfaces.size(); ++i) total = add(total, surface_force(i));
    for (std::size_t i = 0; i < scene.cliffs.size(); ++i) total = add(total, cliff_force(i));

    if (!finite(total)) {  // §6.1 non-finite scene force
      out.push_back({0, 0, 0});
      f_prev = {0, 0, 0};
      continue;
    }
    impacts = impacts_next;
    s_f = s_f_next;
    fallen = fallen_next;
    v_est = v_est_next;
    x_prev = r.x;
    t_prev_good = r.t;
    first_good = false;

    V f = total;
    if (scene.max_rate) {  // §6.2
      const V step = sub(f, f_prev);
      const double max_step = *scene.max_rate * dt;
      if (len(step) > max_step) f = add(f_prev, mul(step, max_step / len(step)));
    }
    if (scene.max_force && len(f) > *scene.max_force) f = mul(f, *scene.max_force / len(f));  // §6.3
    f_prev = f;
    out.push_back(f);
  }
  return out;
}

}  // namespace toonforce::oracle
