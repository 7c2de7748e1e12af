// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Q-format fixed point for FPU-less targets: a signed 32-bit integer with `FracBits` fraction
/// bits. Every operation rounds to nearest and saturates instead of wrapping; saturation sets a
/// sticky flag (like the Q bit of an ARM core's APSR) that the safety stage reports as a fault
/// (spec effects.md §7). Values are built only explicitly (`from_double`, `from_raw`).
///
/// Why not Debian's libfixmath (libfixmath-dev, read before writing this): its `fix16_t` is a
/// bare `int32_t`, so nothing stops a raw integer from being mixed with a Q value; its C++
/// wrapper converts from `int` and `float` implicitly; on overflow it returns the sentinel
/// 0x80000000, which is also the valid value -32768.0, instead of saturating; the plain
/// `fix16_mul`/`fix16_add` are not saturating; and its trig keeps 80 KB of static caches unless
/// rebuilt with FIXMATH_NO_CACHE, which Debian's binary is not. We need constexpr, a type of its
/// own, saturation with a flag, and 64-bit dot products and norms, so this header is ours
/// (about 200 lines); the tests use libfixmath as an independent oracle for multiplication.
///
/// Scaling and overflow: a product or quotient is formed in 64 bits, rounded to nearest
/// (half away from zero) and saturated to [lowest(), max()]. Sums saturate the same way.

#include <array>
#include <bit>
#include <compare>
#include <cstdint>
#include <limits>
#include <type_traits>

#include "toonforce/math/loop_bound.hpp"

namespace toonforce {

/// Where the sticky flag lives. On a host it is per thread (one servo loop per thread, and
/// tests tick loops on several threads at once). A bare-metal target defines
/// TOONFORCE_SINGLE_THREADED: it runs one loop and has no thread-local storage (arm-none-eabi
/// compiles `thread_local` into calls of __aeabi_read_tp, which only an operating system
/// provides), so there the flag is a plain global, or on an Armv7-M core the Q bit (below).
#if defined(TOONFORCE_SINGLE_THREADED)
#define TOONFORCE_FIXED_FLAG_STORAGE inline
#else
#define TOONFORCE_FIXED_FLAG_STORAGE inline thread_local
#endif

#if defined(TOONFORCE_SINGLE_THREADED) && defined(__ARM_FEATURE_SAT) && defined(__thumb2__)
#define TOONFORCE_FIXED_FLAG_IN_Q_BIT 1
#endif

namespace detail {
/// Leaves `word` (or the two operands of one product) as it is, with where it came from hidden
/// from the optimiser. GCC 12 keeps a 32-bit operand that it knows came from a wider value (a
/// 64-bit quotient or product, a sign-extended raw value) as that value and multiplies its high
/// word too, always 0 or a copy of the sign there (an MLA, or a MOV and an MLA, per product on
/// a 32-bit core); an empty asm that may change the register leaves it only the word. The
/// tick's static bound counts each of those. Two operands go through one asm: two
/// separate ones changed what GCC keeps in registers around them (the slippery surface's bound
/// +119 cycles).
template <typename Word>
[[gnu::always_inline]] constexpr void make_opaque(Word& word) noexcept {
  if (!std::is_constant_evaluated()) asm("" : "+r"(word));
}
template <typename A, typename B>
[[gnu::always_inline]] constexpr void make_opaque(A& a, B& b) noexcept {
  if (!std::is_constant_evaluated()) asm("" : "+r"(a), "+r"(b));
}

// The flag's four operations, on whichever storage the target has. `raise_saturation_flag`
// takes the saturated value, which sets the Q bit (below) and is ignored elsewhere.
#if defined(TOONFORCE_FIXED_FLAG_IN_Q_BIT)
/// A bare-metal Arm core with SSAT (Armv7-M: the Cortex-M3 images) keeps the flag where the
/// hardware keeps its own: the APSR's sticky Q bit, which an exception saves and restores with
/// the rest of the xPSR. Setting it is one SSAT of the saturated value (never in [-1, 0]) to
/// one bit, no load or store, in every operation's saturation path (the tick's static bound
/// counts that path for each operation). Nothing else in an image may touch Q: a
/// compiler emits SSAT/USAT for clamps, so tools/mcu/check_q_bit.cmake fails an image with any
/// SSAT, USAT or flag-writing MSR but these.
inline void raise_saturation_flag(std::int32_t saturated_value) noexcept {
  std::int32_t ignored;
  asm volatile("ssat %0, #1, %1" : "=r"(ignored) : "r"(saturated_value));
}
inline bool saturation_flag() noexcept {
  std::uint32_t apsr;
  asm volatile("mrs %0, apsr" : "=r"(apsr));
  return (apsr >> 27) & 1U;
}
inline void clear_saturation_flag() noexcept {
  std::uint32_t apsr;
  asm volatile("mrs %0, apsr" : "=r"(apsr));
  asm volatile("msr apsr_nzcvq, %0" : : "r"(apsr & ~(1U << 27)) : "cc");
}
/// Clears Q with N, Z, C and V, all at once: one MSR of zero and no MRS (MRS and MSR take up to
/// 2 cycles each, Cortex-M3 TRM r2p1 table 3-1). The condition flags are clobbered ("cc"), so
/// the compiler keeps nothing in them across it. The move of zero is in the same asm, so that
/// tools/mcu/check_q_bit.cmake can tell this write of Q from any other.
inline void reset_saturation_flag() noexcept {
  std::uint32_t zero;
  asm volatile("movs %0, #0\n\tmsr apsr_nzcvq, %0" : "=&r"(zero) : : "cc");
}
// Single-path saturation: the test, the limit and the flag in one IT block, the
// same instructions whether or not the value saturates. A branch around the saturation path
// costs as many cycles when not taken (a taken branch refills the pipeline) and as many
// instructions when taken, and out of line it costs a second taken branch; so the tick's static
// bound does not grow, and every tick now runs what the bound counts for each operation
// (their saturation paths were most of the gap between the bound and the dearest tick run).
// Always inlined, as are the operators that use them: GCC's inliner prices an asm statement
// by its lines, and left these one-instruction-path operators out of line where a scene's
// code calls them often (the image with all five scenes), adding a call to each.
// The limit is max() or lowest() by the sign of the true result (the high word's for a
// narrowing, the first operand's for a sum or difference): MVN of 0x80000000 gives max(), and
// EOR with that sign's all-ones (ASR #31) flips it to lowest().
/// `low` when `high:low` is a 32-bit value (high is low's sign extension), else the limit
/// toward high's sign, with the flag.
[[gnu::always_inline]] inline std::int32_t saturate_words(std::int32_t low, std::int32_t high) noexcept {
  std::int32_t ignored;
  asm volatile("cmp %[high], %[low], asr #31\n\t"
               "ittt ne\n\t"
               "mvnne %[low], #0x80000000\n\t"
               "eorne %[low], %[low], %[high], asr #31\n\t"
               "ssatne %[ignored], #1, %[low]"
               : [low] "+r"(low), [ignored] "=&r"(ignored)
               : [high] "r"(high)
               : "cc");
  return low;
}
// After a flag-setting ADDS or SUBS into %[result] from %[a]: on overflow (V) the limit toward
// a's sign, which is the true result's, in its place, and the flag.
#define TOONFORCE_FIXED_LIMIT_ON_OVERFLOW         \
  "ittt vs\n\t"                                   \
  "mvnvs %[result], #0x80000000\n\t"              \
  "eorvs %[result], %[result], %[a], asr #31\n\t" \
  "ssatvs %[ignored], #1, %[result]"
/// a + b (a - b with kSubtract), or the limit toward a's sign when it overflows, with the flag.
template <bool kSubtract>
[[gnu::always_inline]] inline std::int32_t saturating_words(std::int32_t a, std::int32_t b) noexcept {
  std::int32_t result, ignored;
  if constexpr (kSubtract) {
    asm volatile("subs %[result], %[a], %[b]\n\t" TOONFORCE_FIXED_LIMIT_ON_OVERFLOW
                 : [result] "=&r"(result), [ignored] "=&r"(ignored)
                 : [a] "r"(a), [b] "r"(b)
                 : "cc");
  } else {
    asm volatile("adds %[result], %[a], %[b]\n\t" TOONFORCE_FIXED_LIMIT_ON_OVERFLOW
                 : [result] "=&r"(result), [ignored] "=&r"(ignored)
                 : [a] "r"(a), [b] "r"(b)
                 : "cc");
  }
  return result;
}
#undef TOONFORCE_FIXED_LIMIT_ON_OVERFLOW
/// a + b in 64 bits, or on overflow +-(2^63 - 1) toward b's sign with the flag (Wide<S>'s
/// accumulators: math/wide.hpp).
[[gnu::always_inline]] inline std::int64_t saturating_add_doublewords(std::int64_t a, std::int64_t b) noexcept {
  auto low = static_cast<std::uint32_t>(a);
  auto high = static_cast<std::uint32_t>(static_cast<std::uint64_t>(a) >> 32);
  const auto b_low = static_cast<std::uint32_t>(b);
  const auto b_high = static_cast<std::uint32_t>(static_cast<std::uint64_t>(b) >> 32);
  std::int32_t ignored;
  asm volatile("adds %[low], %[low], %[b_low]\n\t"
               "adcs %[high], %[high], %[b_high]\n\t"
               "itttt vs\n\t"
               "mvnvs %[low], %[b_high], asr #31\n\t"  // all ones, or 0 toward a negative b
               "orrvs %[low], %[low], #1\n\t"          // low word of 2^63 - 1, or of -(2^63 - 1)
               "mvnvs %[high], #0x80000000\n\t"
               "eorvs %[high], %[high], %[b_high], asr #31\n\t"
               "it vs\n\t"
               "ssatvs %[ignored], #1, %[high]"
               : [low] "+&r"(low), [high] "+&r"(high), [ignored] "=&r"(ignored)
               : [b_low] "r"(b_low), [b_high] "r"(b_high)
               : "cc");
  return static_cast<std::int64_t>((std::uint64_t{high} << 32) | low);
}
#else
/// The sticky saturation flag of the calling thread (of the program when single-threaded).
TOONFORCE_FIXED_FLAG_STORAGE bool fixed_saturated_flag = false;
inline void raise_saturation_flag(std::int32_t) noexcept { fixed_saturated_flag = true; }
inline bool saturation_flag() noexcept { return fixed_saturated_flag; }
inline void clear_saturation_flag() noexcept { fixed_saturated_flag = false; }
inline void reset_saturation_flag() noexcept { fixed_saturated_flag = false; }
#endif
}  // namespace detail

namespace detail {
/// Whether the target divides 64-bit integers in hardware (a 64-bit host: one instruction).
/// There the exact quotient and root take the target's cheapest methods; the routines below
/// without loop or library call are for a 32-bit core (tools/mcu), whose tick is bounded by
/// its structure. Both give the same results, exactly (math_test checks each).
inline constexpr bool kWideHardware = sizeof(void*) >= 8;

/// floor(n / d) for 0 < d < 2^32, exactly, when the quotient fits 32 bits; 2^32 when it does not
/// (every caller saturates such a quotient). On a 32-bit core a 64-bit division is a library
/// call of about a hundred instructions (__aeabi_uldivmod); this is two 32-bit divisions (UDIV
/// on a Cortex-M3) of 16-bit digits, and no loop (the tick's bound is its structure):
/// Hacker's Delight's divlu (Warren, 2nd ed., 9-4), with each digit's estimate (un / vn1, at
/// most 2 too large for a normalised divisor: Knuth, TAOCP vol. 2, 4.3.1 theorem B) corrected
/// by the sign of the remainder rather than by branches: 42 instructions on the Cortex-M3 on
/// every path but the overflow's, where the branching corrections' longest path took 60.
constexpr std::uint64_t div_u64_u32_digits(std::uint64_t n, std::uint32_t d) noexcept {
  const auto hi = static_cast<std::uint32_t>(n >> 32);
  const auto lo = static_cast<std::uint32_t>(n);
  if (hi >= d) return std::uint64_t{1} << 32;
  const int s = std::countl_zero(d);  // normalise d: its top bit set
  const std::uint32_t v = d << s;
  const std::uint32_t vn1 = v >> 16;
  const std::uint32_t un32 = (hi << s) | ((lo >> 1) >> (31 - s));  // hi < d: no bit lost; s = 0 adds nothing
  const std::uint32_t un10 = lo << s;
  // One quotient digit of (un 2^16 + next) / v for un < v, and its remainder (< v).
  const auto digit = [v, vn1](std::uint32_t un, std::uint32_t next, std::uint32_t& remainder) {
    std::uint32_t q = un / vn1;
    // (un 2^16 + next) - q v, in (-2v, v): each negative remainder takes one off q, adds v back.
    auto r =
        static_cast<std::int64_t>((std::uint64_t{un} << 16) | next) - static_cast<std::int64_t>(std::uint64_t{q} * v);
    const auto correct = [&] {
      const auto negative = static_cast<std::uint32_t>(static_cast<std::uint64_t>(r) >> 63);
      q -= negative;
      r += static_cast<std::int64_t>(v & (0U - negative));
    };
    correct();
    correct();
    remainder = static_cast<std::uint32_t>(r);
    return q;
  };
  std::uint32_t rest = 0;
  const std::uint32_t q1 = digit(un32, un10 >> 16, rest);
  const std::uint32_t q0 = digit(rest, un10 & 0xFFFFU, rest);
  return (q1 << 16) + q0;  // q1 < 2^16: fits 32 bits
}

/// std::countl_zero of a 64-bit value from its two words without a branch: the high word's
/// count, plus the low word's when the high word is 0 (its count is then 32, bit 5 set).
/// GCC's 64-bit count on a 32-bit core tests the high word and branches out of line and
/// back for the low word's count: two pipeline refills on a path the tick's bound takes.
/// (Each word's count is Arm's CLZ, which gives 32 for 0: std::countl_zero's own test for 0
/// stays a branch in GCC's code.)
constexpr int countl_zero_word(std::uint32_t v) noexcept {
#if defined(__arm__)
  if (!std::is_constant_evaluated()) {
    std::uint32_t n;
    asm("clz %[n], %[v]" : [n] "=r"(n) : [v] "r"(v));
    return static_cast<int>(n);
  }
#endif
  return std::countl_zero(v);
}
constexpr int countl_zero_words(std::uint64_t v) noexcept {
  const int high = countl_zero_word(static_cast<std::uint32_t>(v >> 32));
  const int low = countl_zero_word(static_cast<std::uint32_t>(v));
  return high + (low & -(high >> 5));
}

/// n / d for 0 <= n <= d and d > 0, as a fraction in units of 2^-16 (so 1 is 2^16), within 2
/// of the exact n 2^16 / d: one 32-bit division of the top bits of both, normalised so that
/// d's top bit is set (16 bits of divisor: the quotient's relative error is under 2^-15).
/// For a share in [0, 1] of two exact 64-bit sums (the passivity stage's applied share), where
/// the library-free 64/32 division and the sign handling of a Q16.16 quotient cost three times
/// as much.
constexpr std::uint32_t fraction_q16(std::uint64_t n, std::uint64_t d) noexcept {
  const int s = countl_zero_words(d);
  const auto divisor = static_cast<std::uint32_t>((d << s) >> 48);   // in [2^15, 2^16)
  const auto dividend = static_cast<std::uint32_t>((n << s) >> 32);  // n <= d: below 2^32
  const std::uint32_t q = dividend / divisor;                        // at most 2^16 + 2
  return q < (1U << 16) ? q : 1U << 16;
}

/// floor(u / v) for v > 0 when the quotient fits 32 bits (always so for v >= 2^32); 2^32 when
/// it does not. A divisor of 2^32 or more: divided by its top 32 bits, normalised, the
/// estimate is at most one too large or too small after the step down (Hacker's Delight
/// 9-5, divdu), again without a loop or the library.
constexpr std::uint64_t div_u64_digits(std::uint64_t u, std::uint64_t v) noexcept {
  const auto vh = static_cast<std::uint32_t>(v >> 32);
  if (vh == 0) return div_u64_u32_digits(u, static_cast<std::uint32_t>(v));
  const int s = std::countl_zero(vh);
  const auto vl = static_cast<std::uint32_t>(v);
  const std::uint32_t v1 = (vh << s) | (s == 0 ? 0U : vl >> (32 - s));         // v's top 32 bits
  const auto q1 = static_cast<std::uint32_t>(div_u64_u32_digits(u >> 1, v1));  // (u / 2) >> 32 < v1
  std::uint64_t q = q1 >> (31 - s);
  if (q != 0) --q;
  if (u - q * v >= v) ++q;
  return q;
}

/// floor(u / v) for v > 0, capped at 2^32: the hardware's division on a 64-bit host, the
/// routines above on a 32-bit core.
constexpr std::uint64_t div_u64(std::uint64_t u, std::uint64_t v) noexcept {
  if constexpr (kWideHardware) {
    const std::uint64_t q = u / v;
    return q < (std::uint64_t{1} << 32) ? q : std::uint64_t{1} << 32;
  } else {
    return div_u64_digits(u, v);
  }
}
constexpr std::uint64_t div_u64_u32(std::uint64_t n, std::uint32_t d) noexcept {
  if constexpr (kWideHardware) {
    return div_u64(n, d);
  } else {
    return div_u64_u32_digits(n, d);
  }
}

/// (n + d / 2) / d for n >= 0, d > 0 and n + d / 2 < 2^63 (a magnitude rounded half up);
/// 2^32 when the quotient does not fit 32 bits (every caller saturates it).
constexpr std::int64_t div_round(std::int64_t n, std::int64_t d) noexcept {
  const auto half = static_cast<std::uint64_t>(d / 2);
  return static_cast<std::int64_t>(div_u64(static_cast<std::uint64_t>(n) + half, static_cast<std::uint64_t>(d)));
}
/// The same for a divisor known to fit 32 bits (no test of its high word).
constexpr std::int64_t div_round_u32(std::int64_t n, std::uint32_t d) noexcept {
  return static_cast<std::int64_t>(div_u64_u32(static_cast<std::uint64_t>(n) + d / 2, d));
}

/// A 32-bit divisor made ready for several divisions: normalised (top bit set) and its
/// reciprocal floor((2^64 - 1) / d_norm) - 2^32, one 64/32 division, after which each quotient
/// is a multiplication and at most two corrections (Moller and Granlund, "Improved division by
/// invariant integers", IEEE Trans. Computers 60(2), 2011, algorithm 4). A limit scales three
/// components by one norm, and the rate limit divides by 1e9, a constant.
struct Divisor {
  std::uint32_t d;  ///< the divisor as given, 0 < d
  std::uint32_t normalized;
  std::uint32_t reciprocal;
  int shift;
};
constexpr Divisor divisor_of(std::uint32_t d) noexcept {
  const int s = std::countl_zero(d);
  const std::uint32_t dn = d << s;
  // (2^64 - 1 - dn 2^32) / dn: its quotient is below 2^32 because dn >= 2^31.
  const std::uint64_t top = (std::uint64_t{~dn} << 32) | 0xFFFF'FFFFU;
  return {d, dn, static_cast<std::uint32_t>(div_u64_u32(top, dn)), s};
}
/// floor(n / d.d) when the quotient fits 32 bits, 2^32 when it does not: div_u64_u32's contract.
constexpr std::uint64_t div_u64_by_digits(std::uint64_t n, const Divisor& d) noexcept {
  if ((n >> 32) >= d.d) return std::uint64_t{1} << 32;
  const std::uint64_t u = n << d.shift;  // n < d 2^32: nothing shifts out
  const auto u1 = static_cast<std::uint32_t>(u >> 32);
  const auto u0 = static_cast<std::uint32_t>(u);
  const std::uint64_t q = std::uint64_t{d.reciprocal} * u1 + ((std::uint64_t{u1} + 1) << 32) + u0;  // mod 2^64
  auto q1 = static_cast<std::uint32_t>(q >> 32);
  const auto q0 = static_cast<std::uint32_t>(q);
  std::uint32_t r = u0 - q1 * d.normalized;  // mod 2^32
  if (r > q0) {
    --q1;
    r += d.normalized;
  }
  if (r >= d.normalized) ++q1;
  return q1;
}
/// The same: the hardware's division on a 64-bit host, the reciprocal's on a 32-bit core.
constexpr std::uint64_t div_u64_by(std::uint64_t n, const Divisor& d) noexcept {
  if constexpr (kWideHardware) {
    return div_u64(n, d.d);
  } else {
    return div_u64_by_digits(n, d);
  }
}
/// (n + d / 2) / d, rounded half up as div_round_u32, by a prepared divisor.
constexpr std::uint64_t div_round_by(std::uint64_t n, const Divisor& d) noexcept { return div_u64_by(n + d.d / 2, d); }
}  // namespace detail

/// True if any fixed-point operation on this thread saturated since the last clear.
inline bool fixed_saturated() noexcept { return detail::saturation_flag(); }
/// Clears the sticky saturation flag unconditionally (a servo loop's tick does this first, and
/// reads the flag with fixed_saturated() last: its own saturations only, one write and one read).
/// On an Armv7-M image it clears the condition flags too, which no C++ code keeps across a call.
inline void clear_fixed_saturated() noexcept { detail::reset_saturation_flag(); }
/// Reads and clears the sticky saturation flag.
inline bool take_fixed_saturated() noexcept {
  const bool was = detail::saturation_flag();
  if (was) detail::clear_saturation_flag();
  return was;
}

template <int IntBits, int FracBits>
class Fixed {
  static_assert(IntBits + FracBits == 32, "Fixed is a 32-bit Q format");
  static_assert(FracBits > 0 && FracBits < 31);

 public:
  using Raw = std::int32_t;
  using Wide = std::int64_t;
  static constexpr int kFracBits = FracBits;
  static constexpr Raw kOneRaw = Raw{1} << FracBits;

  constexpr Fixed() noexcept = default;  // zero

  static constexpr Fixed from_raw(Raw raw) noexcept {
    Fixed f;
    f.raw_ = raw;
    return f;
  }
  /// Rounds to nearest; out of range saturates and NaN gives 0, both setting the flag.
  static constexpr Fixed from_double(double value) noexcept {
    if (value != value) {  // NaN (std::isnan is not constexpr in C++20)
      flag_saturation();
      return Fixed{};
    }
    const double scaled = value * static_cast<double>(kOneRaw);
    if (scaled >= static_cast<double>(std::numeric_limits<Raw>::max())) return saturated(true);
    if (scaled <= static_cast<double>(std::numeric_limits<Raw>::min())) return saturated(false);
    const double rounded = scaled >= 0 ? scaled + 0.5 : scaled - 0.5;
    return from_raw(static_cast<Raw>(rounded));  // truncation after +-0.5 = round half away
  }
  /// True if `value` converts without saturating (used by scene loading, spec §7).
  static constexpr bool representable(double value) noexcept {
    const double scaled = value * static_cast<double>(kOneRaw);
    return value == value && scaled < static_cast<double>(std::numeric_limits<Raw>::max()) + 0.5 &&
           scaled > static_cast<double>(std::numeric_limits<Raw>::min()) - 0.5;
  }
  static constexpr Fixed max() noexcept { return from_raw(std::numeric_limits<Raw>::max()); }
  static constexpr Fixed lowest() noexcept { return from_raw(std::numeric_limits<Raw>::min()); }
  /// The resolution, 2^-FracBits.
  static constexpr Fixed epsilon() noexcept { return from_raw(1); }

  constexpr Raw raw() const noexcept { return raw_; }
  constexpr double to_double() const noexcept { return static_cast<double>(raw_) / static_cast<double>(kOneRaw); }

  /// num / den in this format, rounded to nearest (half away from zero), saturating with the
  /// flag; den <= 0 saturates toward num's sign. Integers only: a fixed-point loop takes its
  /// times and rates from integer nanoseconds this way (seconds = ns / 1e9, 1/dt = 1e9 / ns),
  /// so a Q image links no floating point (tools/mcu).
  static constexpr Fixed from_ratio(Wide num, Wide den) noexcept {
    constexpr Wide kLimit = Wide{1} << (62 - FracBits);  // num * 2^FracBits stays within 2^62
    if (den <= 0) return num == 0 ? (flag_saturation(), Fixed{}) : saturated(num > 0);
    if (num >= kLimit) return saturated(true);
    if (num <= -kLimit) return saturated(false);
    const Wide scaled = num * kOneRaw;
    const Wide magnitude = scaled < 0 ? -scaled : scaled;
    const Wide q = detail::div_round(magnitude, den);  // magnitude + den / 2 < 2^63: both < 2^62
    return from_wide(scaled < 0 ? -q : q);
  }
  /// `ns` nanoseconds in seconds, as from_ratio(ns, 1e9) rounds it, for a time whose value is
  /// in range (below 2^(31 - FracBits) s; the caller knows it: an impact's time since its
  /// trigger, tested against its duration first): by the reciprocal of 1e9 prepared at compile
  /// time (detail::Divisor), a multiplication and two corrections, where from_ratio's 64/32
  /// division took about 50 instructions of the tick's bound and the limits and the sign 20
  /// more.
  static constexpr Fixed from_ns_in_range(std::uint64_t ns) noexcept {
    constexpr detail::Divisor kSecond = detail::divisor_of(1'000'000'000);
    return from_raw(static_cast<Raw>(detail::div_round_by(ns << FracBits, kSecond)));
  }
  /// This value (a rate, per second) times `ns` nanoseconds: rounded toward zero, so a limit
  /// it sizes is never exceeded, and saturating with the flag. `ns` >= 0, any size: whole
  /// seconds and the rest are multiplied apart, each product exact in 64 bits. No reciprocal:
  /// 1e9 / ns itself would not fit Q16.16 above 32,767 Hz.
  constexpr Fixed times_ns(std::int64_t ns) const noexcept {
    constexpr std::uint32_t kNsPerSecond = 1'000'000'000;
    constexpr detail::Divisor kSecond = detail::divisor_of(kNsPerSecond);
    const auto ns_u = static_cast<std::uint64_t>(ns < 0 ? 0 : ns);
    const std::uint64_t seconds = detail::div_u64_by(ns_u, kSecond);  // 2^32 when it does not fit
    const Wide sign = raw_ < 0 ? -1 : 1;
    const auto magnitude = static_cast<std::uint64_t>(raw_ < 0 ? -Wide{raw_} : Wide{raw_});  // <= 2^31
    if (magnitude == 0) return Fixed{};
    if (seconds >= (std::uint64_t{1} << 31)) return saturated(raw_ > 0);  // past any raw value
    const std::uint64_t rest_ns = ns_u - seconds * kNsPerSecond;          // < 1e9 < 2^30
    // magnitude * seconds < 2^62, magnitude * rest_ns < 2^61: neither overflows.
    const std::uint64_t whole = magnitude * seconds + detail::div_u64_by(magnitude * rest_ns, kSecond);
    return from_wide(sign * static_cast<Wide>(whole));
  }
  /// Whether num / den <= this value, exactly (den > 0, |num| < 2^(62 - FracBits), den < 2^31).
  constexpr bool ratio_at_most(Wide num, Wide den) const noexcept { return num * kOneRaw <= Wide{raw_} * den; }

  /// Saturates a wide intermediate into range, setting the flag when it had to.
  /// (Every operation of the tick ends here, so its worst path is what the tick's static bound
  /// counts most often: the test is one comparison of the high word with the low
  /// word's sign, and the limit is picked from the high word's sign without a branch.)
  [[gnu::always_inline]] static constexpr Fixed from_wide(Wide wide) noexcept {
#if defined(TOONFORCE_FIXED_FLAG_IN_Q_BIT)
    if constexpr (sizeof(Raw) == 4) {
      if (!std::is_constant_evaluated() && !__builtin_constant_p(wide)) {
        return from_raw(detail::saturate_words(static_cast<Raw>(wide), static_cast<Raw>(wide >> 32)));
      }
    }
#endif
    const auto low = static_cast<Raw>(wide);
    if (low != wide) return saturated_toward(static_cast<Raw>(wide >> 32));
    return from_raw(low);
  }
  /// Rounds a wide value carrying `shift` (>= 1) extra fraction bits to nearest, half away
  /// from zero, for any 64-bit value: the floor plus one when the remainder passes half (or
  /// reaches it, for a value >= 0). The remainder's test is a few 32-bit steps; nothing is
  /// added to the whole value, so nothing overflows, and no branch on the sign.
  static constexpr Wide round_shift(Wide wide, int shift) noexcept {
    const Wide remainder = wide & ((Wide{1} << shift) - 1);
    const Wide up = (remainder + (Wide{1} << (shift - 1)) + (wide >> 63)) >> shift;  // 0 or 1
    return (wide >> shift) + up;
  }
  /// A product of two raw values rounded to this format's units, half away from zero (below).
  [[gnu::always_inline]] static constexpr Wide rounded_product(Wide product) noexcept {
    static_assert(FracBits >= 1 && FracBits <= 31);
    const auto half =
        static_cast<std::uint32_t>((std::int32_t{1} << (FracBits - 1)) + static_cast<std::int32_t>(product >> 63));
    return (product + Wide{half}) >> FracBits;
  }
  /// A product of two raw values, or a sum of such (|product| <= 2^62), back to this format: round_shift by
  /// FracBits in fewer steps, because half can be added to it without overflow. Half away from
  /// zero is floor((p + half - 1) / 2^F) for p < 0 and floor((p + half) / 2^F) otherwise.
  /// half + (product >> 63) is half or half - 1, never negative: added as an unsigned word it
  /// is one 32-bit add and a carry into the high word, where GCC added it as a 64-bit value
  /// (an instruction more per product on a 32-bit core; the same value).
  [[gnu::always_inline]] static constexpr Fixed from_product(Wide product) noexcept {
    return from_wide(rounded_product(product));
  }
  /// from_product for a product that cannot leave the range (a value times a share in [0, 1],
  /// a unit vector times a push: times_in_range): the same rounding, without the saturation test.
  [[gnu::always_inline]] static constexpr Fixed from_product_in_range(Wide product) noexcept {
    return from_raw(static_cast<Raw>(rounded_product(product)));
  }

  // Sums and differences overflow only past the 32-bit range, toward the first operand's sign.
  // An operand the compiler knows to be 0 (a component a vector along an axis does not have:
  // effects/tick.hpp's AxisPlane) takes the plain form, which it folds to the other operand;
  // the asm statement it cannot fold (two of a slippery surface's three sums).
  [[gnu::always_inline]] friend constexpr Fixed operator+(Fixed a, Fixed b) noexcept {
#if defined(TOONFORCE_FIXED_FLAG_IN_Q_BIT)
    if constexpr (sizeof(Raw) == 4) {
      if (!std::is_constant_evaluated() && !(__builtin_constant_p(a.raw_) && __builtin_constant_p(b.raw_)) &&
          !known_zero(a.raw_) && !known_zero(b.raw_)) {
        return from_raw(detail::saturating_words<false>(a.raw_, b.raw_));
      }
    }
#endif
    Raw sum = 0;
    if (__builtin_add_overflow(a.raw_, b.raw_, &sum)) return saturated_toward(a.raw_);
    return from_raw(sum);
  }
  [[gnu::always_inline]] friend constexpr Fixed operator-(Fixed a, Fixed b) noexcept {
#if defined(TOONFORCE_FIXED_FLAG_IN_Q_BIT)
    if constexpr (sizeof(Raw) == 4) {  // a - 0 is a; 0 - b may overflow (-lowest())
      if (!std::is_constant_evaluated() && !(__builtin_constant_p(a.raw_) && __builtin_constant_p(b.raw_)) &&
          !known_zero(b.raw_)) {
        return from_raw(detail::saturating_words<true>(a.raw_, b.raw_));
      }
    }
#endif
    Raw difference = 0;
    if (__builtin_sub_overflow(a.raw_, b.raw_, &difference)) return saturated_toward(a.raw_);
    return from_raw(difference);
  }
  [[gnu::always_inline]] friend constexpr Fixed operator-(Fixed a) noexcept {
#if defined(TOONFORCE_FIXED_FLAG_IN_Q_BIT)
    if constexpr (sizeof(Raw) == 4) {  // 0 - a, single-path as the difference
      if (!std::is_constant_evaluated() && !__builtin_constant_p(a.raw_)) {
        return from_raw(detail::saturating_words<true>(0, a.raw_));
      }
    }
#endif
    Raw negated = 0;
    if (__builtin_sub_overflow(Raw{0}, a.raw_, &negated)) return saturated_toward(0);  // -lowest()
    return from_raw(negated);
  }
  [[gnu::always_inline]] friend constexpr Fixed operator*(Fixed a, Fixed b) noexcept {
    return from_product(Wide{a.raw_} * b.raw_);
  }
  /// Division by zero saturates toward the sign of the dividend (0/0 gives 0), with the flag.
  friend constexpr Fixed operator/(Fixed a, Fixed b) noexcept {
    if (b.raw_ == 0) {
      if (a.raw_ == 0) {
        flag_saturation();
        return Fixed{};
      }
      return saturated(a.raw_ > 0);
    }
    // Round half away from zero on magnitudes, then restore the sign.
    const Wide num = Wide{a.raw_} * kOneRaw;  // exact: |a| < 2^31, shifted by FracBits < 31
    const Wide den = b.raw_;
    const Wide num_abs = num < 0 ? -num : num;
    const Wide den_abs = den < 0 ? -den : den;
    const Wide q_abs = detail::div_round_u32(num_abs, static_cast<std::uint32_t>(den_abs));  // den_abs <= 2^31
    const Wide q = ((num < 0) != (den < 0)) ? -q_abs : q_abs;
    return from_wide(q);
  }
  /// 1 / x for x >= 1 (a smaller x counts as 1): `Fixed{1} / x` exactly, with one 32-bit
  /// division where the format allows (FracBits <= 16), none of the 64-bit one's steps. The
  /// quotient round(2^2F / x) is at most 2^F, so it needs no saturation.
  static constexpr Fixed reciprocal_of_at_least_one(Fixed x) noexcept {
    const Fixed d = x.raw_ < kOneRaw ? from_raw(kOneRaw) : x;
    if constexpr (2 * FracBits <= 32) {
      return from_raw(static_cast<Raw>(rounded_reciprocal_raw(d)));
    } else {
      return from_raw(kOneRaw) / d;
    }
  }
  /// 1 / x for x > 0 (x <= 0 counts as the smallest positive value): `Fixed{1} / x` exactly,
  /// the same way; a quotient past max() (x below 2^-(IntBits - 1) or so) saturates with the
  /// flag, as the division does.
  static constexpr Fixed reciprocal_of_positive(Fixed x) noexcept {
    const Fixed d = x.raw_ < 1 ? from_raw(1) : x;
    if constexpr (2 * FracBits <= 32) {
      return from_wide(rounded_reciprocal_raw(d));
    } else {
      return from_raw(kOneRaw) / d;
    }
  }

  constexpr Fixed& operator+=(Fixed o) noexcept { return *this = *this + o; }
  constexpr Fixed& operator-=(Fixed o) noexcept { return *this = *this - o; }
  constexpr Fixed& operator*=(Fixed o) noexcept { return *this = *this * o; }
  constexpr Fixed& operator/=(Fixed o) noexcept { return *this = *this / o; }

  friend constexpr bool operator==(Fixed, Fixed) noexcept = default;
  // No pointer here: clang-tidy 14 flags the 0 the defaulted <=> compares its result with.
  // NOLINTNEXTLINE(modernize-use-nullptr): a false positive of that version
  friend constexpr auto operator<=>(Fixed, Fixed) noexcept = default;

  /// Sets the sticky flag: for math functions whose result left the domain (sqrt of < 0).
  static constexpr void note_saturation() noexcept { flag_saturation(); }

 private:
  static constexpr void flag_saturation() noexcept {
    if (!std::is_constant_evaluated()) detail::raise_saturation_flag(std::numeric_limits<Raw>::max());
  }
  /// round(2^2F / d) for d > 0 and 2F <= 32, in raw units (up to 2^32, unsaturated): taking d
  /// once off the dividend first, floor((2^2F + d/2) / d) = floor((2^2F - d + d/2) / d) + 1
  /// keeps the dividend below 2^32, one 32-bit division.
  static constexpr Wide rounded_reciprocal_raw(Fixed d) noexcept {
    const auto divisor = static_cast<std::uint32_t>(d.raw_);
    const std::uint32_t below =
        static_cast<std::uint32_t>((std::uint64_t{1} << (2 * FracBits)) - divisor) + divisor / 2;
    return static_cast<Wide>(below / divisor) + 1;
  }
  /// `raw` is 0 and the compiler knows it (after inlining: a component set to 0).
  [[gnu::always_inline]] static constexpr bool known_zero(Raw raw) noexcept {
    return __builtin_constant_p(raw) && raw == 0;
  }
  /// max() when `sign` >= 0, lowest() when it is negative, with the flag: no branch.
  static constexpr Fixed saturated_toward(Raw sign) noexcept {
    const Raw limit = (sign >> 31) ^ std::numeric_limits<Raw>::max();
    if (!std::is_constant_evaluated()) detail::raise_saturation_flag(limit);  // the limit itself sets Q
    return from_raw(limit);
  }
  static constexpr Fixed saturated(bool positive) noexcept {
    flag_saturation();
    return positive ? max() : lowest();
  }

  Raw raw_ = 0;
};

/// Q16.16: +-32768 with a resolution of 2^-16 (about 1.5e-5).
using Q16_16 = Fixed<16, 16>;

template <class T>
inline constexpr bool kIsFixed = false;
template <int I, int F>
inline constexpr bool kIsFixed<Fixed<I, F>> = true;

// ---- math on Fixed, found by ordinary lookup inside namespace toonforce ---------------------

template <int I, int F>
constexpr Fixed<I, F> abs(Fixed<I, F> x) noexcept {
  return x.raw() < 0 ? -x : x;
}
template <int I, int F>
constexpr bool is_finite(Fixed<I, F>) noexcept {
  return true;  // saturation, not infinity, is how a Q value overflows
}

namespace detail {
/// floor(sqrt(v) + 0.5) by the bitwise method, one round per two bits of v, in the unsigned
/// type U of v (32 or 64 bits).
template <class U>
constexpr U isqrt_round_bitwise(U v) noexcept {
  if (v == 0) return 0;
  U result = 0;
  // Start at the largest power of four <= v: found from the leading zeros, not by shifting
  // down from the top (up to 31 extra rounds of 64-bit shifts on a 32-bit core).
  U bit = U{1} << ((std::numeric_limits<U>::digits - 1 - std::countl_zero(v)) & ~1);
  while (bit != 0) {
    TOONFORCE_LOOP_BOUND(std::numeric_limits<U>::digits / 2);  // bit: a power of four, shifted by 2
    if (v >= result + bit) {
      v -= result + bit;
      result = (result >> 1) + bit;
    } else {
      result >>= 1;
    }
    bit >>= 2;
  }
  // v now holds the remainder r = n - result^2; round up when r > result (n > (result+1/2)^2).
  return v > result ? result + 1 : result;
}

/// floor(sqrt(v) + 0.5) for a 64-bit value of 2^32 or more, by the digit-by-digit method
/// (one root bit per two bits of v, from the top): after each step q is the root of the bits
/// taken so far and r = those bits - q^2 <= 2q. The high word's steps leave q < 2^16, and
/// while q < 2^29 r fits 32 bits, so all but the last three steps run in 32-bit arithmetic
/// (and no step shifts a 64-bit value by a variable amount, a library call on a 32-bit core).
/// The same result as isqrt_round_bitwise.
constexpr std::uint64_t isqrt_round_wide(std::uint64_t v) noexcept {
  std::uint32_t q = 0;
  std::uint32_t r = 0;
  const auto step = [&q, &r](std::uint32_t two_bits) {
    r = (r << 2) | two_bits;
    const std::uint32_t t = (q << 2) | 1U;
    q <<= 1;
    if (r >= t) {
      r -= t;
      q |= 1U;
    }
  };
  const auto high = static_cast<std::uint32_t>(v >> 32);  // nonzero here
  const int leading = std::countl_zero(high) & ~1;        // whole pairs of leading zeros
  std::uint32_t word = high << leading;
  constexpr int kWordPairs = std::numeric_limits<std::uint32_t>::digits / 2;
  constexpr int kWidePairs = 3;  // the low word's last pairs, where r may pass 32 bits
  for (int pairs = kWordPairs - leading / 2; pairs > 0; --pairs, word <<= 2) {
    TOONFORCE_LOOP_BOUND(kWordPairs);
    step(word >> 30);
  }
  word = static_cast<std::uint32_t>(v);
  for (int pairs = kWordPairs - kWidePairs; pairs > 0; --pairs, word <<= 2) {
    TOONFORCE_LOOP_BOUND(kWordPairs - kWidePairs);
    step(word >> 30);
  }
  std::uint64_t q_wide = q;
  std::uint64_t r_wide = r;
  for (int pairs = kWidePairs; pairs > 0; --pairs, word <<= 2) {
    TOONFORCE_LOOP_BOUND(kWidePairs);
    r_wide = (r_wide << 2) | (word >> 30);
    const std::uint64_t t = (q_wide << 2) | 1U;
    q_wide <<= 1;
    if (r_wide >= t) {
      r_wide -= t;
      q_wide |= 1U;
    }
  }
  // r = v - q^2; round up when r > q (v > (q + 1/2)^2).
  return r_wide > q_wide ? q_wide + 1 : q_wide;
}

/// floor(sqrt(v) + 0.5) for a 64-bit value, from two 32-bit divisions and no loop (a
/// bound by structure; one path for every v but 0). The digit-by-digit method it replaces took
/// 16 or 32 steps, 330 instructions in the bound for any force's norm. Here v is first
/// normalised to m = v 4^k with its top two bits not both 0, so that m's high word H is in
/// [2^30, 2^32); then
///  1. floor(sqrt(H)) from a seed of H's top byte (the root of its midpoint, table below) and
///     one Newton step: the step never lands under the root (the arithmetic-geometric mean
///     inequality survives the integer floors) and, the seed being within 129 of it while the
///     root is at least 2^15, lands at most one above (the error is (seed - root)^2 / (2 seed)
///     < 1/3), which a comparison takes back;
///  2. one step of Zimmermann's Karatsuba square root (Algorithm SqrtRem, INRIA RR-3805, 1999)
///     with base 2^16 gives floor(sqrt(m)) and its remainder, with at most one correction;
///  3. the root of v is that of m shifted by k, rounded from the bits shifted out (or, when
///     k = 0, from the remainder).
/// math_test checks it over the whole 64-bit range against the definition of the rounded root.
inline constexpr auto kRootSeeds = [] {
  // Entry i: the root of (i + 64 + 1/2) 2^24, rounded; a normalised H has a top byte of 64..255.
  std::array<std::uint16_t, 192> seeds{};
  for (std::uint32_t i = 0; i < seeds.size(); ++i) {
    seeds[i] = static_cast<std::uint16_t>(isqrt_round_bitwise(std::uint64_t{2 * (i + 64) + 1} << 23));
  }
  return seeds;
}();
constexpr std::uint64_t isqrt_round_divided(std::uint64_t v) noexcept {
  if (v == 0) return 0;
  auto high = static_cast<std::uint32_t>(v >> 32);
  auto low = static_cast<std::uint32_t>(v);
  // Normalise in 32-bit words (a 64-bit shift by a variable amount is a library call on a
  // 32-bit core): k pairs of zero bits shifted in.
  std::uint32_t k = 0;
  if (high == 0) {
    high = low;
    low = 0;
    k = 16;
  }
  const int c = std::countl_zero(high) & ~1;  // whole pairs
  high = (high << c) | (c == 0 ? 0U : low >> (32 - c));
  low <<= c;
  k += static_cast<std::uint32_t>(c) / 2;
  // 1. s1 = floor(sqrt(H)), e = H - s1^2 <= 2 s1.
  const std::uint32_t seed = kRootSeeds[(high >> 24) - 64];  // >= 2^15: no quotient passes 2^17
  std::uint32_t s1 = (seed + high / seed) >> 1;              // floor(sqrt(H)) or one more
  s1 -= std::uint64_t{s1} * s1 > high ? 1U : 0U;             // s1 <= 2^16 before this
  const std::uint32_t e = high - s1 * s1;
  // 2. m = H 2^32 + a1 2^16 + a0. (q, u) = divmod(e 2^16 + a1, 2 s1), a 33-bit dividend: halved
  // with the divisor (floor((x + 1/2) / s1) = floor(x / s1) for integers x, s1).
  const std::uint32_t a1 = low >> 16;
  const std::uint32_t a0 = low & 0xFFFFU;
  const std::uint32_t x = (e << 15) | (a1 >> 1);  // e < 2^17: fits
  const std::uint32_t q = x / s1;                 // <= 2^16
  const std::uint32_t u = ((x - q * s1) << 1) | (a1 & 1U);
  std::uint64_t s = (std::uint64_t{s1} << 16) + q;
  std::int64_t r = (std::int64_t{u} << 16) + a0 - static_cast<std::int64_t>(std::uint64_t{q} * q);
  const bool over = r < 0;  // s one too large: r + 2 s - 1 is the remainder of s - 1
  r += over ? static_cast<std::int64_t>(2 * s - 1) : 0;
  s -= over ? 1U : 0U;
  // 3. s = floor(sqrt(v) 2^k) < 2^32, r = m - s^2 <= 2 s. For k >= 1, floor(sqrt(v) + 1/2) =
  // floor((s + 2^(k-1)) / 2^k): s's bit k - 1 is the carry into bit k.
  const auto s32 = static_cast<std::uint32_t>(s);
  if (k == 0) return s + (r > static_cast<std::int64_t>(s) ? 1U : 0U);
  return std::uint64_t{s32 >> k} + ((s32 >> (k - 1)) & 1U);
}

/// The leading-bit method, the 32-bit one for a value that fits 32 bits (the method before
/// the loop-free one): fewer rounds for small values, and a branch in each. A 64-bit host's root.
constexpr std::uint64_t isqrt_round_leading(std::uint64_t v) noexcept {
  if (v <= std::numeric_limits<std::uint32_t>::max()) return isqrt_round_bitwise(static_cast<std::uint32_t>(v));
  return isqrt_round_wide(v);
}

/// floor(sqrt(v) + 0.5) for a 64-bit value: on a 32-bit core the divided root (its bound is its
/// cost), on a 64-bit host the leading-bit method (cheaper there on the small values a tick
/// mostly has; the same root).
constexpr std::uint64_t isqrt_round(std::uint64_t v) noexcept {
  if constexpr (kWideHardware) {
    return isqrt_round_leading(v);
  } else {
    return isqrt_round_divided(v);
  }
}

/// 1 / sqrt(v) for v > 0 without a root or a division (scaling a vector to a limit
/// took a root and a 64/32 division, about 125 instructions of a tick's bound each time, and
/// four UDIVs): v = m 2^(32 - 2 shift) with m its top 32 bits, normalised to [2^30, 2^32) (the
/// bits below them dropped, under 2^-30 of v), and `y` 1 / sqrt(m 2^-32), in (1, 2], in units
/// of 2^-30, so that 1 / sqrt(v) = y 2^(shift - 62). The seed is a straight line through m's
/// segment (its top byte, 192 of them over [1/4, 1)), within 2^-16 of the inverse root; one
/// Newton step y (3 - x y^2) / 2 of three 32x32 products squares that error (1.5 2^-32, from
/// below) and leaves the truncations'. A table of seeds at the segments' midpoints, within
/// 2^-8, took a second step (three products more on each of a tick's roots). y is
/// never above 1 / sqrt(v) and within 2^-26 of it (math_test checks both against long double).
struct InverseRoot {
  std::uint32_t y = 0;  ///< in units of 2^-30
  int shift = 0;        ///< 0..31
};
/// Segment i of x = m 2^-32 (its top byte i + 64, x in [(i + 64) / 256, (i + 65) / 256)): the
/// seed at offset u / 2^16 of the segment is `at_start` - (`drop` u) >> 8, in units of 2^-30.
struct InverseRootLine {
  std::uint32_t at_start;
  std::uint16_t drop;  ///< the line's fall over the segment, in units of 2^-22
};
inline constexpr auto kInverseRootLines = [] {
  // 1 / sqrt(x) by a constexpr Newton iteration in double (no <cmath> in a constant
  // expression). The secant through the segment's ends lies above the convex curve, most near
  // the middle; the line is the secant lowered by half that, so it errs both ways by about as
  // much (under 2^-16 of the value: 1.5 2^-16 h^2 / x^2 at h = 2^-8, x >= 1/4, halved).
  const auto inverse_root_of = [](double x) {
    double y = 1.0;
    for (int k = 0; k < 60; ++k) y = y * (3.0 - x * y * y) / 2.0;
    return y;
  };
  std::array<InverseRootLine, 192> lines{};
  for (std::uint32_t i = 0; i < lines.size(); ++i) {
    const double x0 = (i + 64.0) / 256.0;
    const double f0 = inverse_root_of(x0);
    const double f1 = inverse_root_of(x0 + 1.0 / 256.0);
    const double bulge = (f0 + f1) / 2.0 - inverse_root_of(x0 + 0.5 / 256.0);  // > 0
    const double drop_units = (f0 - f1) * 0x1p22;                              // < 2^16
    // Both are > 0, so adding 1/2 and truncating rounds to nearest (and std::lround is not
    // constexpr in C++20): the check's concern, negative values, cannot arise.
    // NOLINTBEGIN(bugprone-incorrect-roundings)
    lines[i].at_start = static_cast<std::uint32_t>((f0 - bulge / 2.0) * 0x1p30 + 0.5);
    lines[i].drop = static_cast<std::uint16_t>(drop_units + 0.5);
    // NOLINTEND(bugprone-incorrect-roundings)
  }
  return lines;
}();
constexpr InverseRoot inverse_root(std::uint64_t v) noexcept {
  auto high = static_cast<std::uint32_t>(v >> 32);
  auto low = static_cast<std::uint32_t>(v);
  // Pairs of zero bits shifted in (in 32-bit words: no 64-bit variable shift). A high word of
  // 0 takes the low word's place by a mask, not a branch (GCC made selects branches, and the
  // bound took them out of line and back).
  const std::uint32_t small = 0U - static_cast<std::uint32_t>(high == 0);  // all ones: high is 0
  int shift = static_cast<int>(small & 16U);
  high |= low & small;
  low &= ~small;
  const int c = std::countl_zero(high) & ~1;
  const std::uint32_t m = (high << c) | ((low >> 1) >> (31 - c));  // c even, 0..30 (v > 0): low >> (32 - c)
  shift += c / 2;
  // x = m 2^-32 in [1/4, 1); y in units of 2^-30, y^2 and 3 - x y^2 in units of 2^-28.
  const InverseRootLine& line = kInverseRootLines[(m >> 24) - 64];
  const std::uint32_t seed = line.at_start - ((std::uint32_t{line.drop} * ((m >> 8) & 0xFFFFU)) >> 8);
  const auto y2 = static_cast<std::uint32_t>((std::uint64_t{seed} * seed) >> 32);
  const auto xy2 = static_cast<std::uint32_t>((std::uint64_t{m} * y2) >> 32);
  const std::uint32_t t = (3U << 28) - xy2;  // x y^2 <= 1 + 2^-15 here: t > 0
  // The truncations leave y up to 8 units over the inverse root (the products' floors make
  // 3 - x y^2 too large); taking 8 off puts it under, within 2^-26: a scaling to a limit
  // never ends past it but by its components' rounding.
  return {static_cast<std::uint32_t>((std::uint64_t{seed} * t) >> 29) - 8U, shift};
}
/// n 2^32 / sqrt(v) for 0 <= n < 2^31 and v > 0 (a scaling's factor n / |x| as a fraction in
/// units of 2^-32 when v is |x|^2 in raw units; 1 / |x| in Q16.16 for n = 1), from its inverse
/// root r: n y 2^(shift - 30), capped at 2^32 - 1.
constexpr std::uint32_t times_inverse_root(std::uint32_t n, InverseRoot r) noexcept {
  make_opaque(n);                                  // cast from a signed raw value: GCC would multiply its sign word too
  const std::uint64_t p = std::uint64_t{n} * r.y;  // < 2^62
  const auto p_high = static_cast<std::uint32_t>(p >> 32);
  const auto p_low = static_cast<std::uint32_t>(p);
  // p >> (30 - shift), shift 0..31, as (2p) >> (31 - shift) (2p < 2^63): one shift by 0..31
  // in 32-bit words, and no branch (shift 31, v <= 3, and shift 30 were cases of
  // their own, branches the bound took out of line and back).
  const int down = 31 - r.shift;  // 0..31
  const std::uint32_t twice_high = (p_high << 1) | (p_low >> 31);
  const std::uint32_t twice_low = p_low << 1;
  const std::uint32_t high = twice_high >> down;
  const std::uint32_t low = (twice_low >> down) | ((twice_high << 1) << (31 - down));
  return high != 0 ? 0xFFFF'FFFFU : low;
}
/// n 2^F / sqrt(v) rounded to nearest (half up), for n <= 2^31 and v > 0: n / |x| as a raw
/// value of a Q format with F fraction bits, when n is a raw value and v is |x|^2 in raw units
/// (a gain over a speed: the friction's mu_c N / |v_t|), from v's inverse root r: n y 2^(shift
/// + F - 62). Below 2^48; from_wide saturates what passes the format's range. Within one unit
/// and 2^-26 of the quotient (the inverse root's error).
template <int F>
constexpr std::uint64_t over_root(std::uint32_t n, InverseRoot r) noexcept {
  static_assert(F >= 1 && F <= 30);
  const std::uint64_t p = std::uint64_t{n} * r.y;  // <= 2^62
  const int down = 62 - F - r.shift;               // 31 - F .. 62 - F, >= 1
  return ((p >> (down - 1)) + 1) >> 1;
}
}  // namespace detail

/// Square root; a negative argument gives 0 and sets the saturation flag.
template <int I, int F>
constexpr Fixed<I, F> sqrt(Fixed<I, F> x) noexcept {
  using Q = Fixed<I, F>;
  if (x.raw() <= 0) {
    if (x.raw() < 0) Q::note_saturation();
    return Q{};
  }
  // sqrt(raw * 2^-F) * 2^F = sqrt(raw * 2^F): take the integer root of raw << F.
  const auto shifted = static_cast<std::uint64_t>(x.raw()) << F;
  return Q::from_wide(static_cast<std::int64_t>(detail::isqrt_round(shifted)));
}

}  // namespace toonforce
