// SPDX-License-Identifier: Apache-2.0
#pragma once
/// What the latency report and the benchmarks time and count: one servo tick of an effect, of
/// the safety stage, of a paper scene (its effects plus the safety stage, ForceSafety), or of
/// the servo loop (ServoLoop on a scripted device: with the spec's stages, velocity estimate,
/// non-finite guard, scene and safety stage; or with every safety stage on), each for
/// double, float and Q16.16, with inputs that drive a chosen branch (effects) or every branch
/// in turn (the scenes' scripted scenarios, report/scenario.hpp).
///
/// A case runs its ticks in two ways that execute the same machine code for the tick:
///   - time(): each tick between two reads of the time-stamp counter (tsc_clock.hpp);
///   - run_counted(): each tick inside measured_tick(), a non-inlined function that callgrind
///     counts alone (`--toggle-collect=*measured_tick*`); everything else is not counted.
/// Both are compiled with every call inside them inlined (gnu::flatten) and with -O3 in every
/// build type (tools/report/CMakeLists.txt), so a debug build counts the same instructions as
/// a release build, and no out-of-line copy from another translation unit can slip in.
/// Per-tick bookkeeping (restoring an effect's state for a branch case, stamping the tick
/// number) happens before the first counter read and outside measured_tick().

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "toonforce/common/result.hpp"
#include "toonforce/config/toml_reader.hpp"
#include "toonforce/math/scalar_kind.hpp"
#include "toonforce/math/sine.hpp"
#include "toonforce/math/vec3.hpp"

namespace toonforce::report {

enum class Level : std::uint8_t {
  kHarness,   ///< an empty tick: what the measurement itself costs
  kEffect,    ///< one law, one branch, its state restored before every tick
  kSafety,    ///< the safety stage (ForceSafety::limit) alone
  kScene,     ///< a paper scene's tick: scene.force() then ForceSafety::limit(), scenario inputs
  kSpecLoop,  ///< ServoLoop::tick() with effects.md §6's stages only (replay's loop), scenario positions
  kLoop,      ///< ServoLoop::tick(): the whole loop tick, every safety stage on, scripted device
};
std::string_view level_name(Level level) noexcept;

struct CaseInfo {
  std::string id;  ///< unique and stable, e.g. "scene/cartoon_wall/double/runtime"
  Level level = Level::kEffect;
  std::string subject;  ///< the effect or the scene
  std::string branch;   ///< the branch driven, or "scenario"
  ScalarKind scalar = ScalarKind::kDouble;
  std::string form;                  ///< scenes: "compile-time" (Scene<...>) or "runtime" (RuntimeScene); else ""
  std::uint64_t ticks_per_pass = 0;  ///< inputs in one pass (a scenario's period in ticks)
};

/// 1-cycle bins up to kBins cycles, the exact maximum beyond.
class CycleHistogram {
 public:
  static constexpr std::size_t kBins = std::size_t{1} << 17;  // 131072 cycles, ~50 us at 2.6 GHz
  CycleHistogram() : counts_(kBins, 0) {}
  void add(std::uint64_t cycles) noexcept {
    ++count_;
    if (cycles > max_) max_ = cycles;
    if (cycles < kBins) {
      ++counts_[cycles];
    } else {
      ++overflow_;
    }
  }
  /// The smallest value v with at least ceil(p * count) samples <= v (p in [0, 1]).
  std::uint64_t percentile(double p) const noexcept;
  /// The mean of the samples inside the bins (the overflow, preemptions of 50 us and more, left out).
  double mean_in_bins() const noexcept;
  std::uint64_t max() const noexcept { return max_; }
  std::uint64_t count() const noexcept { return count_; }
  std::uint64_t overflow() const noexcept { return overflow_; }

 private:
  std::vector<std::uint64_t> counts_;
  std::uint64_t count_ = 0;
  std::uint64_t max_ = 0;
  std::uint64_t overflow_ = 0;
};

/// Called by run_counted() after each tick (outside the counted function).
using AfterTick = void (*)(std::uint64_t tick, void* context);

class TickCase {
 public:
  explicit TickCase(CaseInfo info) : info_(std::move(info)) {}
  virtual ~TickCase() = default;
  TickCase(const TickCase&) = delete;
  TickCase& operator=(const TickCase&) = delete;

  const CaseInfo& info() const noexcept { return info_; }
  /// `ticks` ticks cycling over the inputs, each timed alone (raw TSC cycles, overhead included).
  virtual void time(std::uint64_t ticks, CycleHistogram& histogram) noexcept = 0;
  /// `ticks` ticks, each through measured_tick(); `after` (may be null) after each.
  virtual void run_counted(std::uint64_t ticks, AfterTick after, void* context) noexcept = 0;
  /// `ticks` ticks as fast as they go, untimed (Google Benchmark's loop times the batch).
  virtual void run(std::uint64_t ticks) noexcept = 0;
  /// Back to the initial state and the first input.
  virtual void restart() noexcept = 0;

 private:
  CaseInfo info_;
};

/// Every case, in a fixed order: the harness, then per effect and branch, the safety stage,
/// the paper scenes (compile-time and runtime) and the servo loop, each for double, float and
/// Q16.16. `root` holds scenes/ (the bundled paper scenes). Start-up code.
Result<std::vector<std::unique_ptr<TickCase>>> make_cases(const std::string& root);

/// Replay's servo loop (effects.md §6 stages, RuntimeScene of a paper scene's file, velocity
/// estimated) on that scene's scenario at `rate_hz`, with the impacts' sine method overridden
/// when `sine` is set: what the precision report times for each of its configurations.
Result<std::unique_ptr<TickCase>> make_spec_loop_case(const std::string& root, std::string_view scene,
                                                      ScalarKind scalar, double rate_hz,
                                                      std::optional<SineMethod> sine);

/// The search cases ("scene/NAME/SCALAR/search", "loop/NAME/SCALAR/search";
/// workloads.cpp, search_path): a pass is kSearchStrikes strikes of kSearchStrikeTicks ticks
/// at 1 kHz, a fresh loop at the start of each.
inline constexpr std::size_t kSearchStrikes = 8;
inline constexpr std::size_t kSearchStrikeTicks = 300;

/// The search path of `scene` (a paper scene's name) as device readings, strike by strike:
/// kSearchStrikes strikes of kSearchStrikeTicks positions at 1 kHz, each for a fresh loop. The
/// microcontroller images play them as motions (toonforce_mcu_gen strikes), so the searched
/// inputs run on the target too.
std::vector<std::vector<Vec3<double>>> search_strikes(std::string_view scene);

/// What one tick of a loop search case did: its Limit bits and fault bits.
struct SearchTick {
  std::uint8_t limits = 0;
  std::uint32_t faults = 0;
};
/// Every tick of one pass of "loop/SCENE/SCALAR/search", run natively (the same ticks callgrind
/// counts, in the same order): which stages limited the force on each.
Result<std::vector<SearchTick>> search_loop_ticks(const std::string& root, std::string_view scene, ScalarKind scalar);

/// Whether `id` is selected by `filter`: empty selects all; otherwise any of its
/// comma-separated parts is a substring of `id`.
bool selected(const std::string& id, const std::string& filter);

}  // namespace toonforce::report
