// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Hand scripts in memory: where the simulated hand starts, its arm impedance, and a list of
/// segments (move, stroke, strike, cross, hold, release) it performs one after the other. The
/// file format and its parser live in tools/config (hand_script_file.hpp, docs/HAND_SCRIPTS.md);
/// host_sim only needs these plain types, so it never depends on tools/.
/// Frame: the scene frame of effects.md §0 (x right, y away from the user, z up), SI units.

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "toonforce/math/vec3.hpp"

namespace toonforce::host_sim {

/// The arm as a mass-spring-damper about the point it intends to be at (the equilibrium-point
/// view of arm control: Feldman 1966; Flash & Hogan 1985; Hogan 1985). The hand grasps the
/// handle rigidly, so its mass moves with the device's.
///
/// Default values, from the human-arm literature as we recall it (we could not open the papers
/// here: treat them as order-of-magnitude figures, each uncertain by a factor of about two).
/// People set their arm's impedance by co-contraction (Hogan, IEEE T-AC 29(8), 1984), so a
/// script may change them: a relaxed stroke is softer, a firm tap stiffer and more damped.
/// - stiffness 200 N/m: the low end of the static endpoint stiffness of the arm in the
///   horizontal plane, a few hundred to about a thousand N/m (Mussa-Ivaldi, Hogan & Bizzi,
///   J. Neurosci. 5(10), 1985; Tsuji, Morasso, Goto & Ito, Biol. Cybern. 72, 1995), because
///   stiffness during movement is lower than in posture (Gomi & Kawato, Biol. Cybern. 76, 1997)
///   and a pen grasp adds finger compliance in series.
/// - damping 8 N s/m: endpoint viscosities of a few to about 20 N s/m (Tsuji et al. 1995;
///   Dolan, Friedman & Nagurka, IEEE T-SMC 23(3), 1993). With the Falcon-class device this
///   gives a damping ratio of about 0.55: well damped, not sluggish.
/// - mass 0.1 kg: what moves with a stylus held in a pen grasp is mostly fingers and hand
///   rotating at the wrist, far less than the 1-2 kg endpoint inertia of the whole arm
///   (Tsuji et al. 1995); Kuchenbecker, Park & Niemeyer (Haptics Symp. 2003) model the wrist
///   holding a stylus with tens to a few hundred grams. An estimate.
struct HandImpedance {
  double mass_kg = 0.1;
  double stiffness_n_per_m = 200.0;
  double damping_n_s_per_m = 8.0;
};

enum class SegmentKind : std::uint8_t {
  kMove,     ///< free motion to a point, minimum-jerk, from rest to rest
  kStroke,   ///< along a surface at a speed, pressing with a force; stops at `to` by default
  kStrike,   ///< toward a point beyond a wall at a speed; arrives at speed (no press force)
  kCross,    ///< a stroke that does not stop: across a gap at its speed, or slowing to it
  kHold,     ///< stay where the last segment ended (keeps pressing unless told otherwise)
  kRelease,  ///< let go of the handle: from then on the device moves on its own (last segment)
};

std::string_view segment_kind_name(SegmentKind kind) noexcept;
std::optional<SegmentKind> parse_segment_kind(std::string_view name) noexcept;

/// One segment as written. Which fields apply depends on the kind (docs/HAND_SCRIPTS.md).
struct HandSegment {
  SegmentKind kind = SegmentKind::kHold;
  Vec3<double> to_m;                    ///< move, stroke, strike, cross: end point of the intent
  std::optional<double> speed_m_per_s;  ///< cruise speed (move: mean speed, if no duration)
  std::optional<double> duration_s;     ///< move (if no speed), hold, release
  double ramp_s = 0.1;                  ///< [s] length of each speed change (stroke, strike, cross)
  bool stop = true;                     ///< the intent comes to rest at `to` (stroke/strike/cross)
  std::optional<double> force_n;        ///< press force along -normal (stroke, cross, hold)
  Vec3<double> normal{0.0, 0.0, 1.0};   ///< unit; out of the surface pressed on
  double force_ramp_s = 0.05;           ///< [s] how long the press force takes to change
  std::string label;                    ///< optional name for the reader; quoted in plan errors
  std::uint32_t line = 0;               ///< where it was written (for messages)
};

struct HandScript {
  std::string name;
  std::string source;    ///< file it came from (messages)
  Vec3<double> start_m;  ///< where the hand holds the handle at t = 0 (at rest)
  HandImpedance impedance;
  std::vector<HandSegment> segments;
};

}  // namespace toonforce::host_sim
