// SPDX-License-Identifier: Apache-2.0
#include "toonforce/report/scenario.hpp"

#include <utility>

namespace toonforce::report {

KeyframePath::KeyframePath(std::vector<Keyframe> keys) : keys_(std::move(keys)) {}

PathPoint KeyframePath::at(double phase_s) const noexcept {
  if (keys_.size() < 2) return {};
  if (cursor_ + 1 >= keys_.size() || phase_s < keys_[cursor_].t_s) cursor_ = 0;
  while (cursor_ + 2 < keys_.size() && phase_s >= keys_[cursor_ + 1].t_s) ++cursor_;
  const Keyframe& a = keys_[cursor_];
  const Keyframe& b = keys_[cursor_ + 1];
  const double h = b.t_s - a.t_s;
  const double u = (phase_s - a.t_s) / h;
  const double u2 = u * u;
  const double u3 = u2 * u;
  // Cubic Hermite basis and its derivative (per unit of u).
  const double h00 = 2 * u3 - 3 * u2 + 1;
  const double h10 = u3 - 2 * u2 + u;
  const double h01 = -2 * u3 + 3 * u2;
  const double h11 = u3 - u2;
  const double d00 = 6 * u2 - 6 * u;
  const double d10 = 3 * u2 - 4 * u + 1;
  const double d01 = -6 * u2 + 6 * u;
  const double d11 = 3 * u2 - 2 * u;
  PathPoint p;
  p.position_m =
      a.position_m * h00 + a.velocity_m_per_s * (h * h10) + b.position_m * h01 + b.velocity_m_per_s * (h * h11);
  p.velocity_m_per_s =
      (a.position_m * d00 + b.position_m * d01) * (1.0 / h) + a.velocity_m_per_s * d10 + b.velocity_m_per_s * d11;
  return p;
}

namespace {

Keyframe key(double t, double x, double y, double z, double vx = 0.0, double vy = 0.0, double vz = 0.0) {
  return {t, {x, y, z}, {vx, vy, vz}};
}

// Each path is commented with what its segments drive; positions in metres, speeds in m/s.
// The bundled scenes: a floor at z = 0 (normal +z), stiffness 1500 N/m, clamp 8 N, force rate
// 2000 N/s (so 2 N per 1 ms tick).

KeyframePath wall() {
  return KeyframePath({
      key(0.00, 0.00, 0, 0.003),         // out of contact
      key(0.20, 0.01, 0, -0.002, 0.05),  // in, 3 N
      key(0.50, 0.02, 0, -0.004),        // deeper, 6 N
      key(0.70, 0.01, 0, 0.003),         // out
      key(0.71, 0.01, 0, -0.007),        // a jab at up to 1.5 m/s: rate-limited, then
      key(0.75, 0.01, 0, -0.007),        //   10.5 N asked: clamped at 8 N
      key(0.76, 0.01, 0, 0.003),         // a fast exit: rate-limited on the way down
      key(1.00, 0.00, 0, 0.003),
  });
}

KeyframePath realistic_friction() {
  return KeyframePath({
      key(0.00, -0.020, 0, 0.002),                   // out of contact
      key(0.10, -0.020, 0, -0.001),                  // pressing 1.5 N
      key(0.30, -0.015, 0, -0.001, 0.01),            // creeping: |v_t| < v_reg (0.02 m/s)
      key(0.60, 0.015, 0, -0.0015, 0.15),            // stroking: |v_t| > v_reg
      key(0.80, 0.020, 0.005, -0.001, -0.05, 0.02),  // turning, in y too
      key(0.90, 0.000, 0, 0.002),                    // lifting off
      key(1.00, -0.020, 0, 0.002),
  });
}

KeyframePath slippery() {
  return KeyframePath({
      key(0.00, -0.04, 0, 0.002),        // out of contact
      key(0.10, -0.04, 0, -0.001),       // pressing
      key(0.25, -0.03, 0, -0.001, 0.1),  // below the 2 N cap (mu = 4: 0.4 N)
      key(0.40, 0.00, 0, -0.001, 0.7),   // above it (2.8 N asked): scaled to 2 N
      key(0.50, 0.04, 0, -0.001),        // slowing down
      key(0.60, 0.04, 0, 0.002),         // lifting off
      key(1.00, -0.04, 0, 0.002),        // back through the air
  });
}

KeyframePath cartoon_wall() {
  return KeyframePath({
      key(0.00, 0, 0, 0.005),                // armed, out of contact
      key(0.05, 0, 0, 0.002, 0, 0, -0.2),    // approaching at 0.2 m/s
      key(0.07, 0, 0, -0.002, 0, 0, -0.2),   // enters: triggers (6 N step: rate-limited)
      key(0.10, 0, 0, 0.0015),               // out by more than rearm_distance: re-armed
      key(0.12, 0, 0, -0.002, 0, 0, -0.15),  // enters again: re-triggers while running
      key(0.30, 0, 0, -0.002),               // held in contact while the transient runs
      key(0.40, 0, 0, 0.003),                // out, re-armed
      key(0.55, 0, 0, 0.0005, 0, 0, -0.01),
      key(0.65, 0, 0, -0.001, 0, 0, -0.01),  // a slow entry (0.01 m/s): no trigger
      key(0.80, 0, 0, -0.001),
      key(0.95, 0, 0, 0.004),
      key(1.00, 0, 0, 0.005),
  });
}

KeyframePath cliff() {
  // Gap x in [0, 0.02]; speed threshold 0.08 m/s; rearm height 1 mm.
  return KeyframePath({
      key(0.00, -0.040, 0, -0.001, 0.3),   // on the ledge, fast
      key(0.25, 0.035, 0, -0.001, 0.3),    // across the gap fast: supported (bridged)
      key(0.35, 0.045, 0, 0.003),          // lift off
      key(0.55, -0.015, 0, 0.003),         // back through the air
      key(0.60, -0.010, 0, -0.001, 0.05),  // down onto the ledge
      key(0.85, 0.004, 0, -0.001, 0.05),   // slowly into the gap: falls
      key(0.95, 0.010, 0, -0.005),         // down into the hole
      key(1.05, -0.003, 0, -0.005),        // under the left ledge: its face pushes +x
      key(1.20, 0.023, 0, -0.005),         // under the right ledge: pushes -x
      key(1.30, 0.010, 0, -0.005),
      key(1.40, 0.010, 0, 0.003),   // above rearm height, slow, in the gap: fallen
      key(1.50, 0.030, 0, 0.003),   // outside the gap: supported again
      key(1.70, -0.040, 0, 0.002),  // back over the gap in the air, fast
      key(1.80, -0.040, 0, -0.001, 0.3),
  });
}

}  // namespace

KeyframePath paper_scenario(std::string_view scene) {
  if (scene == "wall") return wall();
  if (scene == "realistic_friction") return realistic_friction();
  if (scene == "slippery") return slippery();
  if (scene == "cartoon_wall") return cartoon_wall();
  if (scene == "cliff") return cliff();
  return KeyframePath({});
}

std::string paper_scene_path(const std::string& root, std::string_view scene) {
  return root + "/scenes/" + std::string(scene) + ".toml";
}

}  // namespace toonforce::report
