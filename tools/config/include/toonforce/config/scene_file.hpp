// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Scene files (spec interfaces.md "Scene files"): a TOML description of effects, checked
/// completely at load time, then turned into a run-time scene and a ServoConfig. Every error
/// names the file, the line and the key, and nothing runs while there is one.
///
/// The reader knows no effect: it reads each `[[KEY]]` table of the effect kinds it is given by
/// that effect's schema (effects/schema.hpp), runs the effect's own checks, and keeps the
/// parameters as written (in double) until `make_runtime_scene<S>` converts them. The
/// library's kinds are surfaces and cliffs (`SceneDescription`); a program reads its own effects
/// beside them with `read_scene_file<RuntimeSurface, CartoonCliff, MyEffect>(path)`
/// (scene_reader.hpp).

#include <cstdint>
#include <string>
#include <string_view>
#include <tuple>
#include <vector>

#include "toonforce/common/result.hpp"
#include "toonforce/config/toml_reader.hpp"
#include "toonforce/control/servo_config.hpp"
#include "toonforce/effects/scene.hpp"

namespace toonforce {

/// One effect of a scene file: which kind, which of that kind (from 0), where it was written.
struct SceneEntry {
  std::size_t kind = 0;
  std::size_t index = 0;
  std::uint32_t line = 0;
};

/// What a scene file says outside its effects: its name and the [device] table.
struct SceneSettings {
  std::string name;    ///< `name`, or the file's stem
  std::string source;  ///< the file it came from
  ForceLimits limits;  ///< [device] max_force, max_force_rate
  double velocity_cutoff_hz = VelocityEstimator<double>::kDefaultCutoffHz;
  /// [device] keys of the servo loop's safety layer (toonforce extensions, interfaces.md),
  /// defaults filled in; replay ignores them. Workspace and continuous force stay unset
  /// (has_workspace false, continuous_force_n 0) unless the file sets them: the device fills them.
  SafetyConfig safety;
};

/// A scene file read against the effect kinds `Kinds<double>`, validated, defaults filled in.
template <template <class> class... Kinds>
struct SceneFileOf : SceneSettings {
  using Effects = std::tuple<Kinds<double>...>;
  template <std::size_t I>
  using Kind = std::tuple_element_t<I, Effects>;
  static constexpr std::size_t kKinds = sizeof...(Kinds);

  /// Each kind's effects, as written, in file order within the kind.
  std::tuple<std::vector<typename Kinds<double>::Params>...> params;
  /// Every effect in file order: their forces add in this order (spec §0).
  std::vector<SceneEntry> order;

  template <std::size_t I>
  const std::vector<typename Kind<I>::Params>& all() const noexcept {
    return std::get<I>(params);
  }
  template <std::size_t I>
  std::vector<typename Kind<I>::Params>& all() noexcept {
    return std::get<I>(params);
  }
  /// The effects of kind K (one of Kinds), e.g. `scene.of<CartoonCliff>()`.
  template <template <class> class K>
  const std::vector<typename K<double>::Params>& of() const noexcept {
    return std::get<std::vector<typename K<double>::Params>>(params);
  }
  template <template <class> class K>
  std::vector<typename K<double>::Params>& of() noexcept {
    return std::get<std::vector<typename K<double>::Params>>(params);
  }
  /// The line of the `n`-th effect of kind I.
  template <std::size_t I>
  std::uint32_t line_of(std::size_t n) const noexcept {
    for (const SceneEntry& e : order) {
      if (e.kind == I && e.index == n) return e.line;
    }
    return 0;
  }
};

/// The library's scene files: the built-in kinds (effects/builtin.hpp: surfaces and cliffs).
using SceneDescription = SceneFileOf<TOONFORCE_BUILTIN_EFFECTS>;

/// Loads and checks a scene file of the library's kinds for the given scalar type (every value
/// must fit it).
Result<SceneDescription> load_scene_file(const std::string& path, ScalarKind scalar = ScalarKind::kDouble);
/// The same from text; `source_name` stands for the file in messages.
Result<SceneDescription> parse_scene(std::string_view text, std::string_view source_name,
                                     ScalarKind scalar = ScalarKind::kDouble);

/// A scene without one effect renders zero force everywhere: far more often a wrong or
/// truncated file than a wish, so `run`, `sim`, `replay` and `check` refuse it unless asked
/// (--allow-empty). The message for `path`, or empty when the scene has an effect.
std::string empty_scene_problem(const SceneDescription& scene, std::string_view path);

/// The servo loop's settings a scene asks for, at servo period `period_s` > 0 (before the
/// device fills what the file leaves open: see with_device).
ServoConfig servo_config(const SceneSettings& scene, double period_s);
/// What replay applies (effects.md §6 only: the clamp and rate limit of [device], the velocity
/// estimator's cut-off), with time from the rows' stamps; `first_dt_s` is the first tick's dt.
ServoConfig replay_config(const SceneSettings& scene, double first_dt_s);

/// The run-time scene in scalar S. The file must have been read for S (the reader checked that
/// every value fits S).
template <Scalar S, template <class> class... Kinds>
RuntimeSceneOf<S, Kinds...> make_runtime_scene(const SceneFileOf<Kinds...>& file) {
  RuntimeSceneOf<S, Kinds...> scene;
  for (const SceneEntry& e : file.order) {
    [&]<std::size_t... I>(std::index_sequence<I...>) {
      ((e.kind == I ? void(scene.template add<I>(
                          schema::convert_params<Kinds<double>, Kinds<S>>(std::get<I>(file.params)[e.index])))
                    : void()),
       ...);
    }
    (std::make_index_sequence<sizeof...(Kinds)>{});
  }
  return scene;
}

extern template RuntimeScene<double> make_runtime_scene<double>(const SceneDescription&);
extern template RuntimeScene<float> make_runtime_scene<float>(const SceneDescription&);
extern template RuntimeScene<Q16_16> make_runtime_scene<Q16_16>(const SceneDescription&);

/// Q16.16 guards (spec effects.md §7; docs/performance/fixed-point.md). A Q16.16
/// value saturates at (2^31 - 1) / 2^16 = 32767.99998; every sum, product and quotient of the
/// loop saturates there and the loop faults (Fault::kFixedSaturation). The guards refuse, before
/// anything runs, rates and scenes whose quantities reach that in normal use: the HIP inside the
/// workspace and no faster than the safety layer's max_velocity.
namespace fixed_point {
/// The largest Q16.16 value.
inline constexpr double kMaxValue = 2147483647.0 / 65536.0;
/// What a product of the loop may reach: one unit below kMaxValue, because its operands are
/// themselves rounded (by up to 2^-17 each) and a product computed near the maximum could round
/// over it.
inline constexpr double kMaxProduct = 32767.0;
/// The workspace the scene rule assumes when the scene sets none: it holds every device this
/// program drives (Falcon HDAL box in the scene frame x, z +-0.06, y -0.065..0.035 m; Omni x
/// +-0.08, y +-0.035, z +-0.06 m; host_sim's presets lie inside both), so a device fills
/// nothing larger in with_device.
inline constexpr Vec3<double> kDefaultWorkspaceMinM{-0.08, -0.065, -0.06};
inline constexpr Vec3<double> kDefaultWorkspaceMaxM{0.08, 0.065, 0.06};

/// The highest servo rate [Hz] at which every quantity a Q16.16 loop computes from the rate
/// fits, for this scene, and what sets it.
struct RateLimit {
  double max_rate_hz = 0.0;
  std::string reason;
};
RateLimit max_rate(const SceneSettings& settings, const std::vector<CartoonCliff<double>::Params>& cliffs);
/// Empty if a Q16.16 loop may run `scene` at `rate_hz` (any rate for another scalar), else why
/// not, with the allowed range. `run`, `sim`, `check` (their --rate) and `replay` (each row's
/// 1/dt) call this.
std::string check_rate(double rate_hz, ScalarKind scalar, const SceneDescription& scene);
}  // namespace fixed_point

/// Sets the sine method of every impact transient of a library scene (`--sine`).
void override_sine(SceneDescription& scene, SineMethod method);

}  // namespace toonforce
