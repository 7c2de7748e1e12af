#pragma once
/// Scene files (spec interfaces.md "Scene files"): a TOML description of surfaces and cliffs,
/// checked completely at load time, then turned into a RuntimeScene<S> and a ControllerConfig.
/// Every error names the file, the line and the key, and nothing runs while there is one.

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "toonforce/common/result.hpp"
#include "toonforce/config/toml_reader.hpp"
#include "toonforce/control/controller.hpp"
#include "toonforce/control/servo_config.hpp"
#include "toonforce/effects/scene.hpp"

namespace toonforce {

/// A scene as the file says, in double, validated; defaults filled in (effects.md).
struct SceneDescription {
  struct Plane {
    Vec3<double> point_m;
    Vec3<double> normal;  ///< normalised
  };
  struct Friction {
    double viscous_n_s_per_m = 0.0;
    double coulomb = 0.0;
    double regularization_speed_m_per_s = 0.02;
  };
  struct Slippery {
    double mu_n_s_per_m = 0.0;
    double max_tangential_force_n = 2.0;
  };
  struct Impact {
    double recoil_gain_n_per_m = 0.0;
    double oscillation_gain_n_per_m = 0.0;
    double duration_s = 0.0;
    double frequency_hz = 0.0;
    double min_impact_speed_m_per_s = 0.05;
    double rearm_distance_m = 0.001;
    std::optional<SineMethod> sine;  ///< unset: the scalar type's default
  };
  struct Surface {
    Plane plane;
    double stiffness_n_per_m = 0.0;
    double damping_n_s_per_m = 0.0;
    std::optional<Friction> friction;
    std::optional<Slippery> slippery;
    std::optional<Impact> impact;
    std::uint32_t line = 0;
  };
  struct Cliff {
    Plane ground;
    Vec3<double> axis;  ///< normalised
    double gap_min_m = 0.0;
    double gap_max_m = 0.0;
    double stiffness_n_per_m = 0.0;
    double damping_n_s_per_m = 0.0;
    double speed_threshold_m_per_s = 0.0;
    double tau_s = 0.02;
    double rearm_height_m = 0.001;
    double fall_force_n = 0.0;
    std::uint32_t line = 0;
  };
  enum class Kind : std::uint8_t { kSurface, kCliff };
  struct Entry {
    Kind kind;
    std::size_t index;  ///< into surfaces or cliffs
  };

  std::string name;    ///< `name`, or the file's stem
  std::string source;  ///< the file it came from
  /// [device]
  ForceLimits limits;
  double velocity_cutoff_hz = VelocityEstimator<double>::kDefaultCutoffHz;
  /// [device] keys of the servo loop's safety layer (toonforce extensions, interfaces.md),
  /// defaults filled in; replay ignores them. Workspace and continuous force stay unset
  /// (has_workspace false, continuous_force_n 0) unless the file sets them: the device fills them.
  SafetyConfig safety;
  std::vector<Surface> surfaces;
  std::vector<Cliff> cliffs;
  std::vector<Entry> order;  ///< all effects in file order (their forces add in this order)
};

/// Loads and checks a scene file for the given scalar type (a value must fit it).
Result<SceneDescription> load_scene_file(const std::string& path, ScalarKind scalar = ScalarKind::kDouble);
/// The same from text; `source_name` stands for the file in messages.
Result<SceneDescription> parse_scene(std::string_view text, std::string_view source_name,
                                     ScalarKind scalar = ScalarKind::kDouble);

/// The controller settings a scene asks for ([device] table), for a run at `period_s` (0: stamped time).
ControllerConfig controller_config(const SceneDescription& scene, double period_s);

/// The servo loop's settings a scene asks for, at servo period `period_s` > 0 (before the
/// device fills what the file leaves open: see with_device).
ServoConfig servo_config(const SceneDescription& scene, double period_s);

/// Builds the run-time scene; `sine` overrides every impact's sine method when set. The
/// description must have been loaded for S (the loader checked its values fit S).
template <Scalar S>
RuntimeScene<S> make_runtime_scene(const SceneDescription& scene, std::optional<SineMethod> sine = std::nullopt);

extern template RuntimeScene<double> make_runtime_scene<double>(const SceneDescription&, std::optional<SineMethod>);
extern template RuntimeScene<float> make_runtime_scene<float>(const SceneDescription&, std::optional<SineMethod>);
extern template RuntimeScene<Q16_16> make_runtime_scene<Q16_16>(const SceneDescription&, std::optional<SineMethod>);

std::optional<SineMethod> parse_sine_method(std::string_view name);

}  // namespace toonforce
