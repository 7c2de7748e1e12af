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
//   sizeof SCENE controller BYTES     the loop's state (Controller: scene, states, safety)
//   stack program BYTES               the whole program's high-water mark
//   done
#include <cstdint>

#include "board.hpp"
#include "image.hpp"
#include "stack_paint.hpp"

#ifndef TOONFORCE_MCU_ICOUNT_SHIFT
#error "TOONFORCE_MCU_ICOUNT_SHIFT: the -icount shift QEMU runs the image with"
#endif

namespace toonforce::mcu {
namespace {

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

/// Instructions run by f(), the counter's own reading excluded.
template <class F>
[[gnu::always_inline]] inline std::uint32_t count(F&& f) noexcept {
  const std::uint32_t before = board::systick_now();
  f();
  const std::uint32_t after = board::systick_now();
  return instructions_of(board::systick_elapsed(before, after)) - g_empty_window;
}

/// The stack below the caller painted before each counted tick [bytes]: more than a tick uses.
constexpr std::uint32_t kTickStackWindow = 1024;

struct Tally {
  std::uint64_t sum = 0;
  std::uint32_t max = 0;
  void add(std::uint32_t n) noexcept {
    sum += n;
    if (n > max) max = n;
  }
};

// ---- the device: plays a motion, takes forces -------------------------------------------------

/// Plays one motion file's rows as device samples, as replay turns rows into samples: the
/// row's time stamp, and dt from the previous row (the first tick's dt is the recording's
/// period, t of row 2 minus t of row 1).
class MotionDevice {
 public:
  explicit MotionDevice(const Motion& m) noexcept : motion_(m) {}

  void read(std::size_t k, Sample& s) const noexcept {
    const MotionRow& row = motion_.rows[k];
    s.position_m = row.position_m;
    s.has_velocity = motion_.velocity_m_per_s != nullptr;
    if (s.has_velocity) s.velocity_m_per_s = motion_.velocity_m_per_s[k];
    s.now = Instant{static_cast<std::int64_t>(k), row.t_s};
    s.dt_s = k == 0 ? motion_.rows[1].t_s - row.t_s : row.t_s - motion_.rows[k - 1].t_s;
  }
  template <class S>
  void write(const TickResult<S>& r) noexcept {
    force_[0] = raw_of(r.force_n.x);
    force_[1] = raw_of(r.force_n.y);
    force_[2] = raw_of(r.force_n.z);
    faults_ = r.faults.bits();
    limits_ = r.limits;
  }
  std::size_t rows() const noexcept { return motion_.count; }
  void print_last() const noexcept {
    out << "f " << force_[0] << ' ' << force_[1] << ' ' << force_[2] << ' ' << faults_ << ' '
        << static_cast<std::uint32_t>(limits_) << '\n';
  }

 private:
  const Motion& motion_;
  std::int64_t force_[3] = {};
  std::uint32_t faults_ = 0;
  std::uint8_t limits_ = 0;
};

// ---- one scene ------------------------------------------------------------------------------

template <class SceneDef>
struct Run {
  using SceneT = typename SceneDef::Type;
  using S = typename SceneT::Scalar;
  using Loop = Controller<SceneT>;

  // Built at compile time (constexpr constructors): no conversion from the double settings
  // runs on the target, and each motion starts from a copy of this.
  static constexpr Loop kFreshLoop{SceneDef::make(), SceneDef::kConfig};
  static constexpr SceneT kScene = SceneDef::make();
  static constexpr ForceSafety<S> kFreshSafety{SceneDef::kConfig.limits};

  // Static, not on the stack: the loop's state is the image's RAM (bss), as on a product.
  static inline Loop loop = kFreshLoop;
  // The same scene and safety stage run alone on the loop's own inputs, to count "effects plus
  // safety" apart from the rest of the tick (estimator, conversions, fault handling).
  static inline typename SceneT::State shadow_state{};
  static inline ForceSafety<S> shadow_safety = kFreshSafety;
  static inline TickInput<S> captured{};

  /// One whole loop tick: read the device, tick, write the force.
  [[gnu::noinline]] static void loop_tick(MotionDevice& device, std::size_t k) noexcept {
    Sample sample;
    device.read(k, sample);
    device.write(loop.tick(sample));
  }

  /// The effects plus the safety stage on the inputs the loop built for this tick.
  [[gnu::noinline]] static Vec3<S> effects_and_safety(const TickInput<S>& in) noexcept {
    const Vec3<S> f = kScene.force(in, shadow_state);
    return shadow_safety.limit(f, in.rate_hz).force_n;
  }

  /// The loop's stage hook, used only in the effects pass: it sees the tick's TickInput.
  struct Capture {
    constexpr Shaped<S> operator()(const Vec3<S>& force, const TickInput<S>& in,
                                   const typename SceneT::State&) const noexcept {
      captured = in;
      return {force, false};
    }
  };

  static bool play(const Motion& motion) noexcept {
    MotionDevice device(motion);
    const std::size_t rows = device.rows();

    // Pass 1: the whole loop tick, counted, its stack depth measured (a painted window below
    // this frame, repainted before each tick); its forces are the image's output.
    loop = kFreshLoop;
    Tally whole;
    out << "run " << SceneDef::kName << ' ' << motion.name << ' ' << rows << '\n';
    const std::uint32_t sp = board::stack_pointer();
    for (std::size_t k = 0; k < rows; ++k) {
      paint_window(sp, kTickStackWindow);
      whole.add(count([&] { loop_tick(device, k); }));
      const std::uint32_t depth = used_in_window(sp, kTickStackWindow);
      if (depth > tick_stack) tick_stack = depth;
      device.print_last();
    }
    out << "end\n";

    // Pass 2: the same ticks again; after each, effects plus safety alone on its inputs.
    loop = kFreshLoop;
    shadow_state = typename SceneT::State{};
    shadow_safety = kFreshSafety;
    Tally effects;
    bool agree = true;
    for (std::size_t k = 0; k < rows; ++k) {
      Sample sample;
      device.read(k, sample);
      const TickResult<S> r = loop.tick(sample, Capture{});
      if (r.faults.has(Fault::kNonFiniteInput) || r.faults.has(Fault::kNonFiniteForce)) continue;
      Vec3<S> f{};
      effects.add(count([&] { f = effects_and_safety(captured); }));
      agree = agree && f == r.force_n;  // the shadow is the loop's own computation
    }
    out << "count " << SceneDef::kName << ' ' << motion.name << ' ' << rows << " loop " << static_cast<std::int64_t>(whole.sum)
        << ' ' << whole.max << " effects " << static_cast<std::int64_t>(effects.sum) << ' ' << effects.max << '\n';
    if (!agree) out << "error " << SceneDef::kName << ' ' << motion.name << ": effects pass differs from the loop\n";
    return agree;
  }

  static inline std::uint32_t tick_stack = 0;  // deepest stack of one loop tick [bytes]

  static bool play_all() noexcept {
    bool ok = true;
    for (std::size_t m = 0; m < image::kMotionCount; ++m) ok = play(image::kMotions[m]) && ok;
    out << "stack " << SceneDef::kName << " tick " << tick_stack << '\n';
    if (tick_stack >= kTickStackWindow) out << "error: the tick's stack went past the painted window\n";
    out << "sizeof " << SceneDef::kName << " controller " << sizeof(Loop) << '\n';
    return ok && tick_stack < kTickStackWindow;
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
    MotionDevice device(image::kMotions[m]);
    R::loop = R::kFreshLoop;
    out << "run " << SceneDef::kName << ' ' << image::kMotions[m].name << ' ' << device.rows() << '\n';
    for (std::size_t k = 0; k < device.rows(); ++k) {
      R::loop_tick(device, k);
      device.print_last();
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
  if (nops != 100) out << "error: the instruction counter saw " << nops << " for 100 NOPs (is QEMU in -icount shift="
                       << static_cast<std::int32_t>(TOONFORCE_MCU_ICOUNT_SHIFT) << " mode?)\n";
  return nops == 100;
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
  ok = play_scenes(image::Scenes{}) && ok;
  out << "stack program " << stack_high_water() << '\n';
  out << (ok ? "done\n" : "failed\n");
  return ok ? 0 : 1;
}
