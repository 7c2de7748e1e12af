// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Parameters of a simulated haptic device, lumped at the handle in the scene frame: the
/// effective mass the hand feels, viscous and Coulomb friction, the force it can produce, how
/// finely it measures position and sets force, and the delay of one I/O exchange.
///
/// The presets cite their sources (docs/FALCON.md and docs/OMNI.md, section "Sources", for the
/// devices' facts); a value no source gives is marked ESTIMATE with its reasoning. Simplifications,
/// on purpose: the device is isotropic (the real linkages are not: mass, friction and force limits
/// vary over the workspace and with direction), the encoder grid is Cartesian (the real one is in
/// joint space), and gravity is left out (the arm carries the handle's weight as part of its
/// posture).

#include <cstdint>
#include <optional>
#include <string_view>

#include "toonforce/math/vec3.hpp"

namespace toonforce::host_sim {

struct DeviceParams {
  std::string_view name = "device";
  double mass_kg = 0.1;            ///< effective mass at the handle
  double damping_n_s_per_m = 0.0;  ///< viscous friction
  double coulomb_n = 0.0;          ///< Coulomb (dry) friction magnitude
  /// [m/s] Coulomb friction is smoothed below this speed, F = -f_c v / sqrt(|v|^2 + v_s^2),
  /// so the integrators see a smooth force (a step would cost RK4 its order). 2 mm/s is a
  /// tenth of the Falcon's one-count-per-tick speed (20 um per 1 ms): slower than anything
  /// its controller can resolve, yet its damping (f_c / v_s, 100 N s/m) stays integrable
  /// with a 0.25 ms step.
  double coulomb_smoothing_m_per_s = 0.002;
  double max_force_n = 0.0;     ///< force saturation (magnitude); 0: none
  double encoder_step_m = 0.0;  ///< position quantisation per axis; 0: none
  double force_step_n = 0.0;    ///< force DAC quantisation per axis; 0: none
  int io_delay_ticks = 1;       ///< a reading reports the state this many ticks ago
  double sensor_noise_m = 0.0;  ///< std. dev. of Gaussian noise added before quantising
  double nominal_rate_hz = 1000.0;
  Vec3<double> workspace_min_m{-0.05, -0.05, -0.05};  ///< scene frame (informative)
  Vec3<double> workspace_max_m{0.05, 0.05, 0.05};
};

/// The largest I/O delay a simulated device supports (its delay line is sized at compile time).
inline constexpr int kMaxIoDelayTicks = 8;

enum class DevicePreset : std::uint8_t { kFalcon, kOmni };

std::string_view device_preset_name(DevicePreset preset) noexcept;
std::optional<DevicePreset> parse_device_preset(std::string_view name) noexcept;

/// Novint Falcon class. Sources (docs/FALCON.md unless said otherwise):
/// - max force 8 N: CHAI3D's nominal Falcon maximum (CHAI3D 3.3.0, src/devices/
///   CDeltaDevices.cpp; the often quoted ~9 N, FALCON.md §5, is unverified);
/// - encoder step 20 um: "1 count ~ 20 um along z at the centre" (FALCON.md §8, derived from
///   the delta Jacobian); it grows toward the workspace edges;
/// - force step 8 N / 4095 ~ 2 mN: ESTIMATE. Motor words are 16-bit but Novint's driver
///   stayed within +-4095 (§3); we spread that range over the 8 N maximum, ignoring the
///   pose-dependent Jacobian (libnifalcon's own scale differs 2-6x, §8);
/// - one tick of I/O delay: libnifalcon computes the force from the previous exchange's
///   position, then does the I/O (§5, runIOLoop), and the device answers one reply per
///   command (§3); 1 kHz (§0);
/// - workspace about a 10 cm cube (§0);
/// - mass 0.15 kg: ESTIMATE, no source gives it. Three arms and a grip (heavier than the
///   Omni's stylus) plus motor inertia reflected through the 7.7:1 capstans (§5): about
///   three times the Omni's quoted 45 g;
/// - damping 0.1 N s/m: ESTIMATE, the order of a capstan-driven device's own damping; it is
///   the b for which Colgate and Brown's bound b > K T / 2 (ICRA 1994) allows 200 N/m at
///   1 kHz, and tiny next to the hand's (a few N s/m), which is what keeps stiff walls passive;
/// - Coulomb 0.2 N: ESTIMATE, a capstan drive like the Omni's, whose back-drive friction is
///   quoted below 0.26 N (OMNI.md §3, unverified).
DeviceParams falcon_params() noexcept;

/// Phantom Omni / Touch class. Sources (docs/OMNI.md §3 unless said otherwise):
/// - max force 3.3 N: peak at the arms-orthogonal pose (datasheet figure, unverified; CHAI3D
///   3.3.0 uses the same nominal value);
/// - encoder step 56 um: 15 000 counts per joint revolution (verified, raw FireWire drivers)
///   on a 133.35 mm link (§4.2): 2 pi x 0.13335 / 15000 = 55.9 um, matching the quoted
///   0.055 mm resolution;
/// - mass 0.045 kg: the quoted apparent inertia of about 45 g (unverified);
/// - Coulomb 0.26 N: the quoted back-drive friction "< 0.26 N" (unverified), taken at its
///   bound;
/// - force step 3.3 N / 2047 ~ 1.6 mN: ESTIMATE, no public DAC scale exists (§4.3); a 12-bit
///   signed DAC over the peak force;
/// - damping 0.05 N s/m: ESTIMATE, a lighter capstan drive than the Falcon's;
/// - one tick of I/O delay: ESTIMATE; hdBeginFrame latches the state and hdEndFrame writes the
///   force in the same 1 kHz tick (§2.2), plus the transport;
/// - workspace about 160 x 120 x 70 mm (quoted, unverified);
/// - no velocity in the reading: OpenHaptics does report a smoothed velocity (OMNI.md §2.2),
///   but its filter is not documented, so the controller estimates velocity as for the Falcon.
DeviceParams omni_params() noexcept;

DeviceParams device_params(DevicePreset preset) noexcept;

}  // namespace toonforce::host_sim
