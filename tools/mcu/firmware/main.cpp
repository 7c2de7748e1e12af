// SPDX-License-Identifier: Apache-2.0
// The image: each of its compile-time scenes runs each of its motions through the servo tick,
// the way `toonforce replay` does on the host (one row = one tick, stamped time), and writes
// the forces out for the host to compare bit for bit. Around the ticks it counts instructions
// (SysTick under QEMU -icount) and measures the stack (painted). Output, one line each:
//   calibration EMPTY NOPS            instructions the counter sees around nothing and 100 nops
//   run SCENE MOTION ROWS             then ROWS lines "f FX FY FZ FAULTS LIMITS" (raw Q16.16,
//                                     or a float's bits)
//   end
//   count SCENE MOTION TICKS loop SUM MAX effects SUM MAX     instructions per tick
//   stack SCENE tick BYTES            deepest stack one loop tick used (below its caller)
//   stackfn SCENE FUNCTION BYTES      the same per counted function (spec_tick, full_tick,
//                                     effects_and_safety), for the static stack bound
//   sizeof SCENE controller BYTES     replay's loop's state (scene, states, safety, estimator)
//   sizeof SCENE loop BYTES           the every-stage loop's state
//   stack program BYTES               the whole program's high-water mark
//   done
#include <array>
#include <cstdint>
#include <new>

#include "board.hpp"
#include "image.hpp"
#include "stack_paint.hpp"

#ifndef TOONFORCE_MCU_ICOUNT_SHIFT
#error "TOONFORCE_MCU_ICOUNT_SHIFT: the -icount shift QEMU runs the image with"
#endif

namespace toonforce::mcu {
namespace {

using image::Motion;

// ---- output -----------------------------------------------------------------------------------

/// Line-buffered text through semihosting: one trap per line, not per character.
class Out {
 public:
  Out& operator<<(const char* text) noexcept {
    while (*text != '\0') put(*text++);
    return *this;
  }
  Out& operator<<(std::int64_t value) noexcept {
    std::uint64_t magnitude = value < 0 ? 0 - static_cast<std::uint64_t>(value) : static_cast<std::uint64_t>(value);
    if (value < 0) put('-');
    char digits[20];
    int n = 0;
    do {
      digits[n++] = static_cast<char>('0' + magnitude % 10);
      magnitude /= 10;
    } while (magnitude != 0);
    while (n > 0) put(digits[--n]);
    return *this;
  }
  Out& operator<<(std::uint32_t value) noexcept { return *this << static_cast<std::int64_t>(value); }
  Out& operator<<(std::int32_t value) noexcept { return *this << static_cast<std::int64_t>(value); }
  Out& operator<<(std::size_t value) noexcept { return *this << static_cast<std::int64_t>(value); }
  Out& operator<<(char c) noexcept {
    put(c);
    return *this;
  }
  void flush() noexcept {
    buffer_[used_] = '\0';
    if (used_ != 0) board::write0(buffer_);
    used_ = 0;
  }

 private:
  void put(char c) noexcept {
    if (used_ + 1 >= sizeof buffer_) flush();
    buffer_[used_++] = c;
    if (c == '\n') flush();
  }
  char buffer_[128] = {};
  std::size_t used_ = 0;
};

Out out;

template <class S>
std::int64_t raw_of(S value) noexcept {
  if constexpr (kIsFixed<S>) {
    return value.raw();
  } else {
    std::uint32_t bits = 0;  // a float's bits, so the host can compare exactly
    static_assert(sizeof bits == sizeof value);
    __builtin_memcpy(&bits, &value, sizeof bits);
    return bits;
  }
}

// ---- instruction counting -------------------------------------------------------------------

/// Instructions from counter counts: each instruction advances QEMU's virtual clock by
/// 2^shift ns and the SysTick counts every 1/25 MHz = 40 ns, so one instruction is
/// 2^shift / 40 counts (3.2 at shift 7). Rounding recovers the exact number as long as one
/// instruction is more than 2 counts (shift >= 7): the two readings' flooring is less than
/// one count. The calibration in main() checks it on the image itself.
constexpr std::uint64_t kNsPerCount = 1'000'000'000ULL / board::kCoreClockHz;
static_assert(kNsPerCount * board::kCoreClockHz == 1'000'000'000ULL);
static_assert((1ULL << TOONFORCE_MCU_ICOUNT_SHIFT) > 2 * kNsPerCount, "shift too small to count exactly");
constexpr std::uint32_t instructions_of(std::uint32_t counts) noexcept {
  constexpr std::uint64_t kNsPerInstruction = 1ULL << TOONFORCE_MCU_ICOUNT_SHIFT;
  return static_cast<std::uint32_t>((counts * kNsPerCount + kNsPerInstruction / 2) / kNsPerInstruction);
}

std::uint32_t g_empty_window = 0;  // what two back-to-back readings count

/// The deepest the program went inside the painted windows below play()'s frame (they are
/// repainted before each measured call, which erases the paint's own record of it) [bytes].
std::uint32_t g_window_high_water = 0;

/// Instructions run by f(), the counter's own reading excluded.
template <class F>
[[gnu::always_inline]] inline std::uint32_t count(F&& f) noexcept {
  const std::uint32_t before = board::systick_now();
  f();
  const std::uint32_t after = board::systick_now();
  return instructions_of(board::systick_elapsed(before, after)) - g_empty_window;
}

/// The stack below the caller painted before each counted tick [bytes]: more than a tick uses
/// (the static per-tick bounds, stack_bound.py, were at most 532 bytes in any image when it
/// was set; a tick that went deeper than the window is reported as an error, below). Painting
/// and scanning it is most of what an image runs under QEMU besides the ticks, so it is that
/// with a margin, no more: the images' runs grew by 40-60 % when a 1 KiB window came in.
constexpr std::uint32_t kTickStackWindow = 768;
static_assert(kTickStackWindow % (4 * kPaintGroup) == 0, "paint_window paints whole groups");

struct Tally {
  std::uint64_t sum = 0;
  std::uint32_t max = 0;
  void add(std::uint32_t n) noexcept {
    sum += n;
    if (n > max) max = n;
  }
};

// ---- the device: plays a motion ----------------------------------------------------------------

/// Plays one motion file's rows as the device's readings, as replay's device does: row k is
/// what the device reads at tick k (its position, and its velocity when the file gives one).
/// It reads in the image's scalar (`Scalar`, hal/device.hpp), as a target's device would: the
/// generator converted the rows as replay's loop converts its double readings, so no tick
/// converts through floating point. What the loop writes is taken from the loop itself (its
/// force, bit for bit), so the write does nothing here.
struct MotionDevice {
  using Scalar = image::S;
  const Motion* motion;
  const std::size_t* row;
  DeviceStatus read(BasicDeviceReading<Scalar>& reading) const noexcept {
    reading.position_m = motion->rows[*row].position_m;
    reading.has_velocity = motion->velocity_m_per_s != nullptr;
    if (reading.has_velocity) reading.velocity_m_per_s = motion->velocity_m_per_s[*row];
    return DeviceStatus::kOk;
  }
  DeviceStatus write(const Vec3<Scalar>&) noexcept { return DeviceStatus::kOk; }
};

template <class S>
void print_tick(const Vec3<S>& f, const TickStatus& status) noexcept {
  out << "f " << raw_of(f.x) << ' ' << raw_of(f.y) << ' ' << raw_of(f.z) << ' ' << status.faults.bits() << ' '
      << static_cast<std::uint32_t>(status.limits) << '\n';
}

// ---- one scene ------------------------------------------------------------------------------

/// The servo period of the every-stage loop [s]: a product's fixed 1 kHz.
constexpr double kPeriodS = 0.001;
constexpr std::int64_t kPeriodNs = ns_from_seconds(kPeriodS);

template <class SceneDef>
struct Run {
  using SceneT = typename SceneDef::Type;
  using S = typename SceneT::Scalar;
  /// The loop as `toonforce replay` runs it: effects.md §6 stages, time from the rows' stamps.
  using SpecLoop = ServoLoop<MotionDevice, SceneT, NullPins, kSpecStages>;
  /// The whole loop with every stage (supervisor, engage and soft start, passivity, thermal,
  /// motion limits), on a fixed 1 kHz period: what a product runs, with settings that make
  /// every stage act on the scripted motions (SceneDef::every_config: a 0.1 s soft start, a
  /// quick thermal model, a 0.1 mJ passivity budget, a workspace), so that its counts reach
  /// each stage's expensive branch, as the static bound assumes.
  using FullLoop = ServoLoop<MotionDevice, SceneT, NullPins, kEveryStage>;

  static constexpr SceneT kScene = SceneDef::make();
  static constexpr ForceSafety<S> kFreshSafety{SceneDef::config(kPeriodS, true).limits};  // converted at compile time
  static inline ActiveForce<S> active[SceneT::kActiveCapacity > 0 ? SceneT::kActiveCapacity : 1]{};
  static inline std::size_t row = 0;
  static inline std::uint32_t tick_stack = 0;  // deepest stack of one loop tick [bytes]
  // The same per counted function [bytes]: below play()'s stack pointer, which is the one each
  // call is made from (play's frame is fixed after its prologue), so each is the function's own
  // depth, its frame and its callees', nothing of the caller's.
  static inline std::uint32_t spec_stack = 0, full_stack = 0, effects_stack = 0;

  // The loops' state in static storage (bss), as on a product, built in place per motion.
  alignas(SpecLoop) static inline unsigned char spec_storage[sizeof(SpecLoop)];
  alignas(FullLoop) static inline unsigned char full_storage[sizeof(FullLoop)];

  // The loops are built at compile time (their constructors are constexpr): the compiler
  // converts their double settings, and the target only copies them into place, so nothing
  // converts through floating point at run time either. The first tick's dt of replay's loop
  // is the recordings' period, as replay's (replay_config; the generator checks they share it).
  static constexpr SpecLoop kSpecLoop{MotionDevice{nullptr, &row}, kScene,
                                      SceneDef::config(image::kMotionPeriodS, true)};
  static constexpr FullLoop kFullLoop{MotionDevice{nullptr, &row}, kScene, SceneDef::every_config(kPeriodS)};

  static SpecLoop& make_spec(const Motion& motion) noexcept {
    SpecLoop& loop = *new (spec_storage) SpecLoop(kSpecLoop);
    loop.device().motion = &motion;
    return loop;
  }
  static FullLoop& make_full(const Motion& motion) noexcept {
    FullLoop& loop = *new (full_storage) FullLoop(kFullLoop);
    loop.device().motion = &motion;
    return loop;
  }

  /// One whole loop tick, read to write, in the replay's stamped time.
  [[gnu::noinline]] static TickStatus spec_tick(SpecLoop& loop, const Motion& motion, std::size_t k) noexcept {
    return loop.tick(Instant{static_cast<std::int64_t>(k), motion.rows[k].t_ns});
  }
  /// One whole loop tick with every stage, at integer tick k.
  [[gnu::noinline]] static TickStatus full_tick(FullLoop& loop, std::size_t k) noexcept {
    return loop.tick(static_cast<std::int64_t>(k));
  }

  /// The effects plus the safety stage on one tick's inputs.
  /// (`dt_ns` is the tick's: a fixed-point loop sizes its rate limit's step from it.)
  [[gnu::noinline]] static Vec3<S> effects_and_safety(const TickInput<S>& in, std::int64_t dt_ns,
                                                      typename SceneT::State& state, ForceSafety<S>& safety) noexcept {
    const Vec3<S> f = kScene.force(in, state, active);
    if constexpr (kIsFixed<S>) {
      return safety.limit_step(f, safety.max_step_for_ns(dt_ns)).force_n;
    } else {
      return safety.limit(f, in.rate_hz).force_n;
    }
  }

  static bool play(const Motion& motion) noexcept {
    const std::size_t rows = motion.count;

    // Pass 1: replay's loop, counted, its stack depth measured (a painted window below this
    // frame, repainted before each tick); its forces are the image's output.
    SpecLoop& spec = make_spec(motion);
    Tally whole;
    out << "run " << SceneDef::kName << ' ' << motion.name << ' ' << rows << '\n';
    const std::uint32_t sp = board::stack_pointer();
    for (row = 0; row < rows; ++row) {
      paint_window(sp, kTickStackWindow);
      TickStatus status;
      whole.add(count([&] { status = spec_tick(spec, motion, row); }));
      const std::uint32_t depth = used_in_window(sp, kTickStackWindow);
      if (depth > spec_stack) spec_stack = depth;
      print_tick(spec.force(), status);
    }
    out << "end\n";

    // Pass 2: the whole loop with every stage, at 1 kHz, each row at its own period (a motion
    // without a row for some period makes the next tick late, as a missed deadline would).
    FullLoop& full = make_full(motion);
    Tally every;
    for (row = 0; row < rows; ++row) {
      paint_window(sp, kTickStackWindow);
      const auto k = static_cast<std::size_t>(motion.rows[row].t_ns / kPeriodNs);
      every.add(count([&] { static_cast<void>(full_tick(full, k)); }));
      const std::uint32_t depth = used_in_window(sp, kTickStackWindow);
      if (depth > full_stack) full_stack = depth;
    }

    // Pass 3: the effects plus the safety stage alone, on the Q16.16 inputs replay's loop gave
    // its scene (position, velocity, rate, time), rebuilt here from the spec loop's tick by tick.
    SpecLoop& again = make_spec(motion);
    typename SceneT::State state{};
    ForceSafety<S> safety = kFreshSafety;
    Tally effects;
    bool agree = true;
    for (row = 0; row < rows; ++row) {
      const TickStatus status = spec_tick(again, motion, row);
      if (status.faults.has(Fault::kNonFiniteInput) || status.faults.has(Fault::kNonFiniteForce)) continue;
      TickInput<S> in{};
      in.position_m = motion.rows[row].position_m;
      in.velocity_m_per_s = again.velocity();
      const std::int64_t dt_ns = dt_ns_of(motion, row);
      in.rate_hz = rate_of(dt_ns);
      in.now = Instant{static_cast<std::int64_t>(row), motion.rows[row].t_ns};
      Vec3<S> f{};
      paint_window(sp, kTickStackWindow);
      effects.add(count([&] { f = effects_and_safety(in, dt_ns, state, safety); }));
      const std::uint32_t depth = used_in_window(sp, kTickStackWindow);
      if (depth > effects_stack) effects_stack = depth;
      agree = agree && f == again.force();  // the shadow is the loop's own computation
    }
    const std::uint32_t deepest = spec_stack > full_stack ? spec_stack : full_stack;
    const std::uint32_t from_top = static_cast<std::uint32_t>(reinterpret_cast<std::uintptr_t>(&__stack_top)) - sp +
                                   (effects_stack > deepest ? effects_stack : deepest);
    if (from_top > g_window_high_water) g_window_high_water = from_top;
    out << "count " << SceneDef::kName << ' ' << motion.name << ' ' << rows << " loop "
        << static_cast<std::int64_t>(whole.sum) << ' ' << whole.max << " every " << static_cast<std::int64_t>(every.sum)
        << ' ' << every.max << " effects " << static_cast<std::int64_t>(effects.sum) << ' ' << effects.max << '\n';
    if (!agree) out << "error " << SceneDef::kName << ' ' << motion.name << ": effects pass differs from the loop\n";
    return agree;
  }

  /// dt as the loop takes it with stamps: the first tick's is the recording's period (every
  /// motion here has whole rows, so the last tick that counted is the row before).
  static std::int64_t dt_ns_of(const Motion& motion, std::size_t k) noexcept {
    return k == 0 ? ns_from_seconds(image::kMotionPeriodS) : motion.rows[k].t_ns - motion.rows[k - 1].t_ns;
  }
  /// 1/dt as the loop computes it.
  static S rate_of(std::int64_t dt_ns) noexcept {
    if constexpr (kIsFixed<S>) {
      return S::from_ratio(kNsPerS, dt_ns);
    } else {
      return scalar_cast<S>(1.0 / (static_cast<double>(dt_ns) / static_cast<double>(kNsPerS)));
    }
  }

  static bool play_all() noexcept {
    bool ok = true;
    for (std::size_t m = 0; m < image::kMotionCount; ++m) ok = play(image::kMotions[m]) && ok;
    tick_stack = spec_stack > full_stack ? spec_stack : full_stack;
    out << "stack " << SceneDef::kName << " tick " << tick_stack << '\n';
    out << "stackfn " << SceneDef::kName << " spec_tick " << spec_stack << '\n';
    out << "stackfn " << SceneDef::kName << " full_tick " << full_stack << '\n';
    out << "stackfn " << SceneDef::kName << " effects_and_safety " << effects_stack << '\n';
    if (tick_stack >= kTickStackWindow || effects_stack >= kTickStackWindow) {
      out << "error: the tick's stack went past the painted window\n";
    }
    out << "sizeof " << SceneDef::kName << " controller " << sizeof(SpecLoop) << '\n';
    out << "sizeof " << SceneDef::kName << " loop " << sizeof(FullLoop) << '\n';
    return ok && tick_stack < kTickStackWindow && effects_stack < kTickStackWindow;
  }
};

template <class... Scenes>
bool play_scenes(SceneList<Scenes...>) noexcept {
  bool ok = true;
  ((ok = Run<Scenes>::play_all() && ok), ...);
  return ok;
}

/// The size images (TOONFORCE_MCU_SIZE_ONLY): each motion through the loop and its forces out,
/// nothing else (no counting, no second pass, no stack probes), so that what the size figures
/// show is the loop, its scene, the device and the start-up code.
template <class SceneDef>
void play_plain() noexcept {
  using R = Run<SceneDef>;
  for (std::size_t m = 0; m < image::kMotionCount; ++m) {
    const Motion& motion = image::kMotions[m];
    auto& loop = R::make_spec(motion);
    out << "run " << SceneDef::kName << ' ' << motion.name << ' ' << motion.count << '\n';
    for (R::row = 0; R::row < motion.count; ++R::row) {
      const TickStatus status = R::spec_tick(loop, motion, R::row);
      print_tick(loop.force(), status);
    }
    out << "end\n";
  }
}
template <class... Scenes>
void play_scenes_plain(SceneList<Scenes...>) noexcept {
  (play_plain<Scenes>(), ...);
}

/// Checks the counter on blocks of known length: nothing, and 100 NOPs.
bool calibrate() noexcept {
  board::start_systick();
  g_empty_window = 0;
  const std::uint32_t empty = count([] {});
  g_empty_window = empty;
  const std::uint32_t nops = count([] { asm volatile(".rept 100\n nop\n .endr" ::: "memory"); });
  out << "calibration " << empty << ' ' << nops << '\n';
  if (nops != 100)
    out << "error: the instruction counter saw " << nops
        << " for 100 NOPs (is QEMU in -icount shift=" << static_cast<std::int32_t>(TOONFORCE_MCU_ICOUNT_SHIFT)
        << " mode?)\n";
  return nops == 100;
}

/// Checks the saturation flag on the target (in a Q image the APSR's Q bit, math/fixed.hpp):
/// an operation in range leaves it clear, one past the range sets it, reading it clears it.
/// The operands are volatile, so the target computes them. Every fault the image reports of a
/// saturated tick relies on this.
template <class Q>
bool check_saturation_flag() noexcept {
  if constexpr (kIsFixed<Q>) {
    volatile std::int32_t big = 30000 << 16;
    volatile std::int32_t small = 3 << 16;
    static_cast<void>(take_fixed_saturated());
    const Q in_range = Q::from_raw(small) * Q::from_raw(small) + Q::from_raw(big);
    const bool clear_after_in_range = !fixed_saturated();
    const Q past = Q::from_raw(big) + Q::from_raw(big);
    const bool set_after_past = fixed_saturated();
    const bool taken = take_fixed_saturated();
    const bool clear_after_take = !fixed_saturated();
    const bool ok = clear_after_in_range && set_after_past && taken && clear_after_take &&
                    in_range.raw() == 30009 << 16 && past == Q::max();
    out << "saturation flag " << (ok ? "ok" : "wrong") << '\n';
    return ok;
  } else {
    return true;
  }
}

/// The operators the tick saturates with, as this core runs them (on the Cortex-M3, single-path
/// in asm: math/fixed.hpp), against the same operations evaluated by the compiler, which takes
/// the portable C++ of the host: on every pair of edge values (the limits, one off them, the
/// signs, products that round to the edge or just past it), the same value, and the flag
/// exactly when the operation leaves the range. Bit-for-bit agreement with replay on the
/// motions cannot show this: no motion saturates.
template <class Q>
bool check_saturating_operators() noexcept {
  if constexpr (kIsFixed<Q>) {
    using Raw = std::int32_t;
    constexpr Raw kEdges[] = {0,
                              1,
                              -1,
                              2,
                              -2,
                              0x7FFF'FFFF,
                              -0x7FFF'FFFF - 1,
                              0x7FFF'FFFE,
                              -0x7FFF'FFFF,
                              0x4000'0000,
                              -0x4000'0000,
                              0x1'0000,
                              -0x1'0000,
                              0xB5'04F3,
                              -0xB5'04F3,
                              0xB5'04F4,
                              -0xB5'04F4,
                              0x7FFF'8000,
                              12'345'678,
                              -87'654'321};
    constexpr std::size_t kN = sizeof kEdges / sizeof kEdges[0];
    struct Expected {
      Raw sum, difference, product, negation;
      bool sum_saturates, difference_saturates, product_saturates, negation_saturates;
    };
    static constexpr auto kExpected = [&] {
      std::array<Expected, kN * kN> e{};
      for (std::size_t i = 0; i < kN; ++i) {
        for (std::size_t j = 0; j < kN; ++j) {
          const Q a = Q::from_raw(kEdges[i]);
          const Q b = Q::from_raw(kEdges[j]);
          const std::int64_t p = std::int64_t{kEdges[i]} * kEdges[j];
          const std::int64_t rounded = (p + ((std::int64_t{1} << 15) + (p >> 63))) >> 16;
          Raw ignored = 0;
          e[i * kN + j] = {(a + b).raw(),
                           (a - b).raw(),
                           (a * b).raw(),
                           (-a).raw(),
                           __builtin_add_overflow(kEdges[i], kEdges[j], &ignored),
                           __builtin_sub_overflow(kEdges[i], kEdges[j], &ignored),
                           rounded != static_cast<Raw>(rounded),
                           __builtin_sub_overflow(0, kEdges[i], &ignored)};
        }
      }
      return e;
    }();
    constexpr std::int64_t kWideEdges[] = {0,
                                           1,
                                           -1,
                                           INT64_MAX,
                                           -INT64_MAX,
                                           INT64_MAX - 1,
                                           std::int64_t{1} << 62,
                                           -(std::int64_t{1} << 62),
                                           0xFFFF'FFFF,
                                           -0xFFFF'FFFFLL,
                                           0x1'0000'0000};
    constexpr std::size_t kWideN = sizeof kWideEdges / sizeof kWideEdges[0];
    std::size_t wrong = 0;
    static_cast<void>(take_fixed_saturated());
    for (std::size_t i = 0; i < kN; ++i) {
      for (std::size_t j = 0; j < kN; ++j) {
        volatile Raw va = kEdges[i];
        volatile Raw vb = kEdges[j];
        const Q a = Q::from_raw(va);
        const Q b = Q::from_raw(vb);
        const Expected& e = kExpected[i * kN + j];
        const Raw sum = (a + b).raw();
        wrong += sum != e.sum || take_fixed_saturated() != e.sum_saturates;
        const Raw difference = (a - b).raw();
        wrong += difference != e.difference || take_fixed_saturated() != e.difference_saturates;
        const Raw product = (a * b).raw();
        wrong += product != e.product || take_fixed_saturated() != e.product_saturates;
      }
      volatile Raw va = kEdges[i];
      const Q a = Q::from_raw(va);  // -a, the same way
      const Raw negation = (-a).raw();
      wrong += negation != kExpected[i * kN].negation || take_fixed_saturated() != kExpected[i * kN].negation_saturates;
    }
    for (const std::int64_t a : kWideEdges) {
      for (const std::int64_t b : kWideEdges) {
        std::int64_t exact = 0;
        const bool overflows = __builtin_add_overflow(a, b, &exact);
        const std::int64_t expected = overflows ? (b > 0 ? INT64_MAX : -INT64_MAX) : exact;
        volatile std::int64_t va = a;
        volatile std::int64_t vb = b;
        const Wide<Q> sum = Wide<Q>::from_raw(va) + Wide<Q>::from_raw(vb);
        wrong += sum.raw() != expected || take_fixed_saturated() != overflows;
      }
    }
    out << "saturating operators " << (wrong == 0 ? "ok" : "wrong") << ' ' << kN * kN * 3 + kN + kWideN * kWideN
        << " cases, " << wrong << " wrong\n";
    return wrong == 0;
  } else {
    return true;
  }
}

}  // namespace
}  // namespace toonforce::mcu

int run_image() {
  using namespace toonforce::mcu;
#if defined(TOONFORCE_MCU_SIZE_ONLY)
  play_scenes_plain(image::Scenes{});
  out << "done\n";
  return 0;
#endif
  bool ok = calibrate();
  ok = check_saturation_flag<image::S>() && ok;
  ok = check_saturating_operators<image::S>() && ok;
  ok = play_scenes(image::Scenes{}) && ok;
  const std::uint32_t painted_high_water = stack_high_water();
  out << "stack program " << (painted_high_water > g_window_high_water ? painted_high_water : g_window_high_water)
      << '\n';
  out << (ok ? "done\n" : "failed\n");
  return ok ? 0 : 1;
}
