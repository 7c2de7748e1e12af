// SPDX-License-Identifier: Apache-2.0
// The Q16.16 type, vectors and the sine methods.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <tuple>
#include <vector>

extern "C" {
#include <libfixmath/fix16.h>
}

#include "toonforce/math/sine.hpp"
#include "toonforce/math/vec3.hpp"
#include "toonforce/math/wide.hpp"

namespace toonforce {
namespace {

using Q = Q16_16;
constexpr double kLsb = 1.0 / 65536.0;

TEST(Fixed, ConvertsFromDoubleRoundingToNearest) {
  EXPECT_EQ(Q::from_double(1.0).raw(), 65536);
  EXPECT_EQ(Q::from_double(0.4 * kLsb).raw(), 0);
  EXPECT_EQ(Q::from_double(0.6 * kLsb).raw(), 1);
  EXPECT_EQ(Q::from_double(-0.6 * kLsb).raw(), -1);
  EXPECT_EQ(Q::from_double(-2.5 * kLsb).raw(), -3);  // half away from zero
  EXPECT_FALSE(take_fixed_saturated());
}

TEST(Fixed, SaturatesInsteadOfWrappingAndRaisesTheStickyFlag) {
  static_cast<void>(take_fixed_saturated());
  const Q big = Q::from_double(30000.0);
  EXPECT_FALSE(fixed_saturated());
  EXPECT_EQ(big + big, Q::max());
  EXPECT_TRUE(fixed_saturated());
  EXPECT_TRUE(take_fixed_saturated());
  EXPECT_FALSE(fixed_saturated());
  EXPECT_EQ(-big - big, Q::lowest());
  EXPECT_EQ(big * Q::from_double(-2.0), Q::lowest());
  EXPECT_EQ(Q::from_double(1e9), Q::max());
  EXPECT_EQ(Q::from_double(std::nan("")), Q{});
  EXPECT_TRUE(take_fixed_saturated());
}

TEST(Fixed, DivisionRoundsAndSaturatesOnZero) {
  EXPECT_EQ((Q::from_double(1.0) / Q::from_double(3.0)).raw(), 21845);  // 0.33333 -> 21845.33
  EXPECT_EQ((Q::from_double(2.0) / Q::from_double(3.0)).raw(), 43691);  // 43690.67 rounds up
  EXPECT_EQ((Q::from_double(-2.0) / Q::from_double(3.0)).raw(), -43691);
  EXPECT_FALSE(take_fixed_saturated());
  EXPECT_EQ(Q::from_double(1.0) / Q{}, Q::max());
  EXPECT_TRUE(take_fixed_saturated());
}

TEST(Fixed, RatiosOfIntegersRoundOnceAsTheExactQuotientWould) {
  // The fixed-point loop's time: seconds from nanoseconds, and 1/dt from nanoseconds, in
  // integers only (a Q16.16 image links no floating point). Checked against the exact quotient
  // rounded half away from zero, over periods a servo loop uses and beyond.
  for (const std::int64_t ns :
       {1LL, 999LL, 15259LL, 125000LL, 333333LL, 1000000LL, 1000001LL, 2000000LL, 100000000LL, 30000000000000LL}) {
    const double seconds = static_cast<double>(ns) / 1e9;
    EXPECT_EQ(Q::from_ratio(ns, 1'000'000'000).raw(), Q::from_double(seconds).raw()) << ns;
    EXPECT_EQ(Q::from_ratio(-ns, 1'000'000'000).raw(), Q::from_double(-seconds).raw()) << ns;
    if (ns >= 31000) {
      EXPECT_EQ(Q::from_ratio(1'000'000'000, ns).raw(), Q::from_double(1e9 / static_cast<double>(ns)).raw()) << ns;
    }
  }
  EXPECT_FALSE(take_fixed_saturated());
  EXPECT_EQ(Q::from_ratio(1'000'000'000, 30000), Q::max()) << "40 kHz's rate is past Q16.16";
  EXPECT_TRUE(take_fixed_saturated());
  EXPECT_EQ(Q::from_ratio(std::int64_t{1} << 50, 1), Q::max()) << "a huge numerator saturates, it does not wrap";
  EXPECT_TRUE(take_fixed_saturated());
  EXPECT_EQ(Q::from_ratio(1, 0), Q::max()) << "a zero denominator saturates toward the sign";
  EXPECT_TRUE(take_fixed_saturated());
  // t <= d exactly: 0.1 s is 6553.6 LSB, so d = 6554 LSB = 0.100006103515625 s.
  const Q d = Q::from_raw(6554);
  EXPECT_TRUE(d.ratio_at_most(100'006'103, 1'000'000'000));
  EXPECT_FALSE(d.ratio_at_most(100'006'104, 1'000'000'000));
}

TEST(Fixed, ARateTimesNanosecondsIsTheExactProductRoundedTowardZero) {
  // The rate limit's step, max_force_rate * dt, from integer time: checked against the exact
  // product in 128 bits, for rates from one LSB to the format's largest and dt from 1 ns past
  // 2^32 ns (where the whole seconds are split off) to where the step saturates.
  // The exact step, clamped into int64 (C++ division truncates toward zero).
  const auto exact = [](std::int32_t raw, std::int64_t ns) -> std::int64_t {
    __extension__ using Int128 = __int128;
    const Int128 q = Int128{raw} * ns / 1'000'000'000;
    const Int128 lo = std::numeric_limits<std::int64_t>::min();
    const Int128 hi = std::numeric_limits<std::int64_t>::max();
    return static_cast<std::int64_t>(q < lo ? lo : (q > hi ? hi : q));
  };
  static_cast<void>(take_fixed_saturated());
  for (const std::int32_t raw : {1, 3, 65536, 131072000, 2'000 * 65536 + 7, std::numeric_limits<std::int32_t>::max(),
                                 -65536 * 5 - 3, std::numeric_limits<std::int32_t>::min()}) {
    for (const std::int64_t ns : {0LL, 1LL, 10'000LL, 30'517LL, 999'999LL, 1'000'000LL, 333'333LL, 999'999'999LL,
                                  1'000'000'000LL, 4'294'967'295LL, 4'294'967'296LL, 7'500'000'001LL}) {
      const std::int64_t want = exact(raw, ns);
      const Q got = Q::from_raw(raw).times_ns(ns);
      if (want > std::numeric_limits<std::int32_t>::max() || want < std::numeric_limits<std::int32_t>::min()) {
        EXPECT_EQ(got, want > 0 ? Q::max() : Q::lowest()) << raw << " " << ns;
        EXPECT_TRUE(take_fixed_saturated()) << raw << " " << ns;
      } else {
        EXPECT_EQ(got.raw(), want) << raw << " " << ns;
        EXPECT_FALSE(take_fixed_saturated()) << raw << " " << ns;
      }
    }
  }
  // 2,000 N/s over 10 us is 0.02 N: 1,310.72 LSB, down to 1,310. Through 1/dt (100 kHz, past
  // Q16.16's 32,767) the step would have been 2000 / 32768 N, three times too large.
  EXPECT_EQ(Q::from_double(2000.0).times_ns(10'000).raw(), 1310);
  EXPECT_EQ(Q::from_raw(1).times_ns(std::numeric_limits<std::int64_t>::max()), Q::max()) << "seconds past 2^32";
  EXPECT_TRUE(take_fixed_saturated());
  EXPECT_EQ(Q::lowest().times_ns(std::numeric_limits<std::int64_t>::max()), Q::lowest()) << "2^31 LSB times 2^32 s";
  EXPECT_TRUE(take_fixed_saturated());
  std::mt19937_64 random(29);
  for (int i = 0; i < 100000; ++i) {
    const auto raw = static_cast<std::int32_t>(random());
    const auto ns = static_cast<std::int64_t>(random() >> (1 + random() % 63));
    const std::int64_t want = exact(raw, ns);
    const Q got = Q::from_raw(raw).times_ns(ns);
    if (want <= std::numeric_limits<std::int32_t>::max() && want >= std::numeric_limits<std::int32_t>::min()) {
      ASSERT_EQ(got.raw(), want) << raw << " " << ns;
    } else {
      ASSERT_EQ(got, want > 0 ? Q::max() : Q::lowest()) << raw << " " << ns;
    }
  }
  static_cast<void>(take_fixed_saturated());
}

TEST(Fixed, WideValuesRoundHalfAwayFromZeroAndSaturateIntoRange) {
  // round_shift and from_wide end every product, dot and conversion: against the exact rational
  // rounding (in 128 bits) at the ties, around zero, at the 64-bit limits and at random, for
  // every shift the code uses and more.
  __extension__ using Int128 = __int128;
  const auto rounded = [](std::int64_t w, int shift) {
    const Int128 d = Int128{1} << shift;
    const Int128 m = w < 0 ? -Int128{w} : Int128{w};
    const Int128 q = (m + d / 2) / d;  // half away from zero, on the magnitude
    return static_cast<std::int64_t>(w < 0 ? -q : q);
  };
  std::vector<std::int64_t> values = {0,
                                      1,
                                      -1,
                                      std::numeric_limits<std::int64_t>::max(),
                                      std::numeric_limits<std::int64_t>::min(),
                                      std::numeric_limits<std::int64_t>::min() + 1};
  for (int shift = 1; shift < 63; ++shift) {
    const std::int64_t half = std::int64_t{1} << (shift - 1);
    for (const std::int64_t k : {0LL, 1LL, 2LL, 3LL, 12345LL}) {
      for (const std::int64_t off : {-1LL, 0LL, 1LL}) {
        if (k > (std::numeric_limits<std::int64_t>::max() >> shift) - 1) continue;
        const std::int64_t w = (k << shift) + half + off;  // a tie and either side of it
        values.push_back(w);
        values.push_back(-w);
      }
    }
  }
  std::mt19937_64 random(16);
  for (int i = 0; i < 20000; ++i) values.push_back(static_cast<std::int64_t>(random()) >> (random() % 64));
  for (int shift = 1; shift < 63; ++shift) {
    for (const std::int64_t w : values) ASSERT_EQ(Q::round_shift(w, shift), rounded(w, shift)) << w << " >> " << shift;
  }
  static_cast<void>(take_fixed_saturated());
  for (const std::int64_t w : values) {
    const Q got = Q::from_wide(w);
    if (w > std::numeric_limits<std::int32_t>::max()) {
      EXPECT_EQ(got, Q::max()) << w;
      EXPECT_TRUE(take_fixed_saturated()) << w;
    } else if (w < std::numeric_limits<std::int32_t>::min()) {
      EXPECT_EQ(got, Q::lowest()) << w;
      EXPECT_TRUE(take_fixed_saturated()) << w;
    } else {
      EXPECT_EQ(got.raw(), w);
      EXPECT_FALSE(take_fixed_saturated()) << w;
    }
  }
  for (const std::int64_t w : {std::int64_t{INT32_MAX}, std::int64_t{INT32_MAX} + 1, std::int64_t{INT32_MIN},
                               std::int64_t{INT32_MIN} - 1, std::int64_t{1} << 32, -(std::int64_t{1} << 32)}) {
    EXPECT_EQ(Q::from_wide(w),
              w > INT32_MAX ? Q::max() : (w < INT32_MIN ? Q::lowest() : Q::from_raw(static_cast<std::int32_t>(w))))
        << w;
  }
  static_cast<void>(take_fixed_saturated());
}

TEST(Fixed, MultiplicationAgreesWithLibfixmath) {
  // libfixmath (Debian's libfixmath-dev) as an independent oracle: it rounds to nearest too;
  // the two may differ by one LSB only on exact ties, which they round differently.
  std::mt19937_64 rng(42);
  std::uniform_int_distribution<std::int32_t> raw(-(1 << 23), 1 << 23);
  for (int i = 0; i < 100000; ++i) {
    const std::int32_t a = raw(rng);
    const std::int32_t b = raw(rng);
    const std::int64_t product = std::int64_t{a} * b;
    const std::int32_t ours = (Q::from_raw(a) * Q::from_raw(b)).raw();
    const fix16_t theirs = fix16_smul(a, b);
    const bool tie = (std::llabs(product) & 0xFFFF) == 0x8000;
    if (tie) {
      EXPECT_LE(std::abs(ours - theirs), 1);
    } else {
      ASSERT_EQ(ours, theirs) << a << " * " << b;
    }
  }
  EXPECT_EQ((Q::max() * Q::from_double(2.0)).raw(), fix16_smul(fix16_maximum, fix16_from_int(2)));
  static_cast<void>(take_fixed_saturated());
}

TEST(Fixed, ProductsRoundTiesAwayFromZeroAndSaturateExactlyPastTheRange) {
  // Where libfixmath cannot say (ties, the range's edges): the exact product's magnitude
  // rounded half up, the sign put back, and the flag exactly when that leaves the range.
  const auto expected = [](std::int32_t a, std::int32_t b, bool& saturates) {
    const std::int64_t product = std::int64_t{a} * b;
    const std::uint64_t magnitude = static_cast<std::uint64_t>(product < 0 ? -product : product);
    const auto rounded = static_cast<std::int64_t>((magnitude + 0x8000U) >> 16);
    const std::int64_t value = product < 0 ? -rounded : rounded;
    saturates = value > INT32_MAX || value < INT32_MIN;
    return static_cast<std::int32_t>(value > INT32_MAX ? INT32_MAX : value < INT32_MIN ? INT32_MIN : value);
  };
  std::mt19937_64 rng(29);
  std::uniform_int_distribution<std::int32_t> any(INT32_MIN, INT32_MAX);
  std::uniform_int_distribution<std::int32_t> odd_half(-(1 << 14), 1 << 14);
  std::vector<std::pair<std::int32_t, std::int32_t>> cases = {{1, 0x8000},
                                                              {-1, 0x8000},
                                                              {3, 0x8000},
                                                              {-3, 0x8000},
                                                              {1, 0x7FFF},
                                                              {-1, 0x7FFF},
                                                              {1, 0x8001},
                                                              {-1, 0x8001},
                                                              {INT32_MAX, 1 << 16},
                                                              {INT32_MIN, 1 << 16},
                                                              {INT32_MIN, -(1 << 16)},
                                                              {INT32_MAX, -(1 << 16)},
                                                              {INT32_MIN, INT32_MIN},
                                                              {INT32_MAX, INT32_MIN},
                                                              {INT32_MAX, (1 << 16) + 1},
                                                              {INT32_MIN, (1 << 16) + 1}};
  for (int i = 0; i < 100000; ++i) {
    cases.emplace_back(any(rng), any(rng));                                       // mostly saturating
    cases.emplace_back(any(rng) >> 16, any(rng) >> 15);                           // near the range's edge
    cases.emplace_back(2 * odd_half(rng) + 1, 0x8000 * (2 * odd_half(rng) + 1));  // exact ties
  }
  for (const auto& [a, b] : cases) {
    static_cast<void>(take_fixed_saturated());
    bool saturates = false;
    const std::int32_t want = expected(a, b, saturates);
    ASSERT_EQ((Q::from_raw(a) * Q::from_raw(b)).raw(), want) << a << " * " << b;
    ASSERT_EQ(take_fixed_saturated(), saturates) << a << " * " << b;
  }
}

TEST(Fixed, SumsDifferencesAndNegationsSaturateExactlyPastTheRange) {
  std::mt19937_64 rng(30);
  std::uniform_int_distribution<std::int32_t> any(INT32_MIN, INT32_MAX);
  std::vector<std::pair<std::int32_t, std::int32_t>> cases = {
      {INT32_MAX, 1},         {INT32_MAX, 0},         {INT32_MIN, -1}, {INT32_MIN, 0},  {INT32_MIN, INT32_MIN},
      {INT32_MAX, INT32_MAX}, {INT32_MAX, INT32_MIN}, {0, INT32_MIN},  {-1, INT32_MIN}, {0, 0}};
  for (int i = 0; i < 100000; ++i) cases.emplace_back(any(rng), any(rng));
  const auto clamp = [](std::int64_t v, bool& saturates) {
    saturates = v > INT32_MAX || v < INT32_MIN;
    return static_cast<std::int32_t>(v > INT32_MAX ? INT32_MAX : v < INT32_MIN ? INT32_MIN : v);
  };
  for (const auto& [a, b] : cases) {
    bool saturates = false;
    static_cast<void>(take_fixed_saturated());
    ASSERT_EQ((Q::from_raw(a) + Q::from_raw(b)).raw(), clamp(std::int64_t{a} + b, saturates)) << a << " + " << b;
    ASSERT_EQ(take_fixed_saturated(), saturates) << a << " + " << b;
    ASSERT_EQ((Q::from_raw(a) - Q::from_raw(b)).raw(), clamp(std::int64_t{a} - b, saturates)) << a << " - " << b;
    ASSERT_EQ(take_fixed_saturated(), saturates) << a << " - " << b;
    ASSERT_EQ((-Q::from_raw(b)).raw(), clamp(-std::int64_t{b}, saturates)) << "-" << b;
    ASSERT_EQ(take_fixed_saturated(), saturates) << "-" << b;
  }
}

TEST(Fixed, SquareRootIsWithinHalfAnLsbAndAgreesWithLibfixmath) {
  for (const double v : {0.0, 1e-4, 0.25, 2.0, 1234.5678, 32767.0}) {
    const Q q = Q::from_double(v);
    const double exact = std::sqrt(q.to_double());
    EXPECT_LE(std::abs(sqrt(q).to_double() - exact), 0.5 * kLsb + 1e-12) << v;
    EXPECT_LE(std::abs(sqrt(q).raw() - fix16_sqrt(q.raw())), 1) << v;
  }
  EXPECT_EQ(sqrt(Q::from_double(-1.0)), Q{});
  EXPECT_TRUE(take_fixed_saturated());
}

/// True when r = floor(sqrt(v) + 1/2), i.e. (r - 1/2)^2 <= v < (r + 1/2)^2; in integers
/// r^2 - r < v <= r^2 + r (a tie cannot occur: (r + 1/2)^2 is never an integer).
__extension__ typedef unsigned __int128 Uint128;  // r^2 + r can exceed 64 bits (g++ extension)
bool rounds_to_nearest_root(std::uint64_t v, std::uint64_t r) {
  const Uint128 r2 = static_cast<Uint128>(r) * r;
  return (r == 0 || r2 - r < v) && v <= r2 + r;
}

TEST(Fixed, IntegerRootRoundsToNearestOverTheWholeSixtyFourBitRange) {
  // norm() takes the root of a sum of three raw squares: any 64-bit value. Around the 32-bit
  // boundary (where the root changes method), at powers of four (where it starts), at the
  // rounding boundaries r^2 + r and r^2 + r + 1, at the top, and at random.
  std::vector<std::uint64_t> values = {0,
                                       1,
                                       2,
                                       3,
                                       4,
                                       5,
                                       0xFFFF'FFFFULL,
                                       0x1'0000'0000ULL,
                                       0x1'0000'0001ULL,
                                       0xFFFF'FFFF'FFFF'FFFFULL,
                                       0xFFFF'FFFF'0000'0000ULL,
                                       0xFFFF'FFFE'0000'0001ULL};
  for (int shift = 0; shift < 64; ++shift) {
    const std::uint64_t p = std::uint64_t{1} << shift;
    values.insert(values.end(), {p - 1, p, p + 1});
  }
  for (const std::uint64_t r : {1ULL, 2ULL, 65535ULL, 65536ULL, 65537ULL, 0xFFFF'FFFEULL, 3037000499ULL}) {
    values.insert(values.end(), {r * r - 1, r * r, r * r + r, r * r + r + 1});
  }
  // The divided root's seeds: each top byte of a normalised high word (64..255), at its ends,
  // with and without a low word.
  for (std::uint64_t byte = 64; byte <= 256; ++byte) {
    const std::uint64_t h = byte << 24;
    values.insert(values.end(), {h - 1, h, (h - 1) << 32 | 0xFFFF'FFFFULL, h << 32, (h << 32) | 0x8000'0000ULL});
    // And inside each seed's segment: its middle and quarters.
    for (const std::uint64_t quarter : {std::uint64_t{1} << 22, std::uint64_t{2} << 22, std::uint64_t{3} << 22}) {
      values.insert(values.end(), {h + quarter, (h + quarter) << 32});
    }
  }
  std::mt19937_64 random(18);
  for (int i = 0; i < 200000; ++i) values.push_back(random() >> (random() % 64));
  for (const std::uint64_t v : values) {
    // Both methods (a 32-bit core's divided root, a 64-bit host's leading-bit one), and this target's.
    ASSERT_TRUE(rounds_to_nearest_root(v, detail::isqrt_round_divided(v)))
        << v << " gave " << detail::isqrt_round_divided(v);
    ASSERT_TRUE(rounds_to_nearest_root(v, detail::isqrt_round_leading(v)))
        << v << " gave " << detail::isqrt_round_leading(v);
    ASSERT_TRUE(rounds_to_nearest_root(v, detail::isqrt_round(v))) << v << " gave " << detail::isqrt_round(v);
  }
  static_assert(detail::isqrt_round(0) == 0 && detail::isqrt_round(2) == 1 && detail::isqrt_round(3) == 2);
  static_assert(detail::isqrt_round(0xFFFF'FFFF'FFFF'FFFFULL) == 0x1'0000'0000ULL);
  static_assert(detail::isqrt_round_divided(0xFFFF'FFFF'FFFF'FFFFULL) == 0x1'0000'0000ULL &&
                detail::isqrt_round_divided(3) == 2);
}

/// The values the inverse root is checked at: powers of two and their neighbours, the ends,
/// middle and quarters of each seed's segment (a normalised top byte of 64..255, in either
/// word), squares and their
/// neighbours, and random values of every length.
std::vector<std::uint64_t> inverse_root_values() {
  std::vector<std::uint64_t> values = {1, 2, 3, 4, 5, 0xFFFF'FFFFULL, 0x1'0000'0000ULL, 0xFFFF'FFFF'FFFF'FFFFULL};
  for (int shift = 1; shift < 64; ++shift) {
    const std::uint64_t p = std::uint64_t{1} << shift;
    values.insert(values.end(), {p - 1, p, p + 1});
  }
  for (std::uint64_t byte = 64; byte <= 256; ++byte) {
    const std::uint64_t h = byte << 24;
    values.insert(values.end(), {h - 1, h, (h - 1) << 32 | 0xFFFF'FFFFULL, h << 32, (h << 32) | 0x8000'0000ULL});
    // Across each segment of the seed's line: its middle and quarters, where it errs most.
    for (const std::uint64_t quarter : {std::uint64_t{1} << 22, std::uint64_t{2} << 22, std::uint64_t{3} << 22}) {
      values.insert(values.end(), {h + quarter, (h + quarter) << 32});
    }
  }
  for (const std::uint64_t r : {2ULL, 3ULL, 1000ULL, 65535ULL, 65536ULL, 0xFFFF'FFFEULL, 0xFFFF'FFFFULL}) {
    values.insert(values.end(), {r * r - 1, r * r, r * r + 1});
  }
  std::mt19937_64 random(29);
  for (int i = 0; i < 300000; ++i) values.push_back((random() >> (random() % 64)) | 1U);
  std::erase(values, 0U);  // 2^64 wrapped: v > 0 is the precondition
  return values;
}

TEST(FixedMath, FromNsInRangeIsFromRatioByOneBillion) {
  // The impact transient's time since its trigger: from_ratio(ns, 1e9)'s value, by the
  // prepared reciprocal, for every time in range (its precondition; from_ratio does not
  // saturate). At the ties (5e8 ns), up to the range's last value, and at random.
  std::vector<std::uint64_t> values = {0,
                                       1,
                                       7'629,
                                       7'630,
                                       15'258,
                                       499'999'999,
                                       500'000'000,
                                       500'000'001,
                                       1'000'000'000,
                                       32'767'999'992'370ULL,
                                       32'767'999'992'371ULL};
  const std::uint64_t last = ((std::uint64_t{1} << 31) * 1'000'000'000 - 500'000'000) >> 16;  // rounds to max()
  for (std::uint64_t d = 0; d <= 6; ++d) values.push_back(last - d);
  std::mt19937_64 random(34);
  for (int i = 0; i < 200000; ++i) values.push_back(random() >> (18 + random() % 46));
  int in_range = 0;
  bool reached_max = false;
  for (const std::uint64_t ns : values) {
    static_cast<void>(take_fixed_saturated());
    const Q want = Q::from_ratio(static_cast<std::int64_t>(ns), 1'000'000'000);
    if (take_fixed_saturated()) continue;  // past the range: not this function's
    ASSERT_EQ(Q::from_ns_in_range(ns), want) << ns;
    ASSERT_FALSE(take_fixed_saturated()) << ns;
    ++in_range;
    reached_max = reached_max || want == Q::max();
  }
  EXPECT_GT(in_range, 150000);
  EXPECT_TRUE(reached_max);
}

TEST(FixedMath, InverseRootIsNeverAboveOneOverTheRootAndWithinTwoToTheMinus26OfIt) {
  // y 2^(shift - 62) against 1 / sqrt(v) in long double (64-bit mantissa): never above it (a
  // scaling by it never passes its limit) and at most 2^-26 under it. Without the final
  // correction the truncations leave it above for many values.
  for (const std::uint64_t v : inverse_root_values()) {
    const detail::InverseRoot r = detail::inverse_root(v);
    ASSERT_TRUE(r.shift >= 0 && r.shift <= 31) << v;
    const long double exact = 1.0L / std::sqrt(static_cast<long double>(v));
    const long double got = std::ldexp(static_cast<long double>(r.y), r.shift - 62);
    ASSERT_LE(got, exact) << v;
    ASSERT_GE(got, exact * (1.0L - 0x1p-26L)) << v;
  }
}

TEST(FixedMath, TimesInverseRootIsTheFractionRoundedDownWithinTwoToTheMinus26) {
  // n 2^32 / sqrt(v) for n < sqrt(v) (a limit that bites, the factor below 1), in units of
  // 2^-32: at most its floor, at least (1 - 2^-26) of it less one unit; n = 1 is 1 / |x| in
  // Q16.16 for v = |x|^2 in raw units. Past 2^32 (n >= sqrt(v)) it is capped at 2^32 - 1.
  // (n = sqrt(v) is checked too: the floor there is 2^32, the result just under it.)
  std::mt19937_64 random(30);
  for (const std::uint64_t v : inverse_root_values()) {
    const long double root = std::sqrt(static_cast<long double>(v));
    const auto largest = static_cast<std::uint64_t>(std::min(root, 2147483647.0L));
    for (const std::uint64_t n64 : {std::uint64_t{1}, largest, random() % (largest + 1), random() % (largest + 1)}) {
      const auto n = static_cast<std::uint32_t>(n64);
      const std::uint32_t got = detail::times_inverse_root(n, detail::inverse_root(v));
      const long double exact = std::ldexp(static_cast<long double>(n), 32) / root;
      ASSERT_LE(static_cast<long double>(got), std::floor(exact)) << n << " / sqrt(" << v << ")";
      ASSERT_GE(static_cast<long double>(got), std::min(exact * (1.0L - 0x1p-26L) - 1.0L, 0x1p32L - 1.0L))
          << n << " / sqrt(" << v << ")";
    }
  }
  // 1 / |v| of the longest Q16.16 vector, |v|^2 = 3 (2^31)^2 raw: still 1 LSB, not 0 (the
  // passivity controller takes 0 for "too slow to damp").
  EXPECT_EQ(detail::times_inverse_root(1U, detail::inverse_root(3 * (std::uint64_t{1} << 62))), 1U);
  // Past 2^32 the cap, for each of the inverse root's shifts (v = 1..3 is shift 31): n well
  // past sqrt(v) (within 2^-26 of it the factor may stay under 2^32, as above).
  for (int shift = 0; shift < 32; ++shift) {
    const std::uint64_t v = std::uint64_t{1} << (62 - 2 * shift);  // sqrt(v) = 2^(31 - shift)
    for (const std::uint64_t n : {(std::uint64_t{3} << (31 - shift)) / 2 + 1, std::uint64_t{0x7FFF'FFFF}}) {
      if (n > 0x7FFF'FFFF || n * n <= v + (v >> 19)) continue;
      ASSERT_EQ(detail::inverse_root(v).shift, shift) << v;
      EXPECT_EQ(detail::times_inverse_root(static_cast<std::uint32_t>(n), detail::inverse_root(v)), 0xFFFF'FFFFU)
          << n << " / sqrt(" << v << ")";
    }
  }
}

TEST(FixedMath, OverRootIsTheQuotientRoundedWithinTwoToTheMinus26) {
  // n 2^16 / sqrt(v), the friction's Coulomb gain mu_c N / max(|v_t|, v_reg) in Q16.16 raw
  // units: the quotient through an inverse root never above it and within 2^-26, rounded half
  // up, so within half a unit of a value in [q (1 - 2^-26), q] (rounded down instead, the
  // lower bound fails).
  std::mt19937_64 random(31);
  for (const std::uint64_t v : inverse_root_values()) {
    const long double root = std::sqrt(static_cast<long double>(v));
    for (const std::uint64_t n64 : {std::uint64_t{1}, std::uint64_t{1} << 31, random() >> 33, random() >> 48}) {
      const auto n = static_cast<std::uint32_t>(n64);
      const std::uint64_t got = detail::over_root<16>(n, detail::inverse_root(v));
      const long double exact = std::ldexp(static_cast<long double>(n), 16) / root;
      ASSERT_LE(static_cast<long double>(got), exact + 0.5L) << n << " / sqrt(" << v << ")";
      ASSERT_GE(static_cast<long double>(got), exact * (1.0L - 0x1p-26L) - 0.5L) << n << " / sqrt(" << v << ")";
    }
  }
}

TEST(Fixed, DivisionWithoutTheLibraryIsTheExactQuotient) {
  // detail::div_u64 replaces the 64-bit division (a library call on a 32-bit core) in every
  // Q quotient: the same quotient whenever it fits 32 bits, 2^32 (saturating) when not. Values
  // where the digit estimates need their corrections: divisors just over a power of two, at
  // the 32-bit boundary, dividends at multiples and one below, and at random.
  const auto check = [](std::uint64_t u, std::uint64_t v) {
    const std::uint64_t quotient = u / v;
    const std::uint64_t expected = quotient < (std::uint64_t{1} << 32) ? quotient : std::uint64_t{1} << 32;
    // The routine a 32-bit core runs, and what this target runs (the hardware's on a 64-bit host).
    ASSERT_EQ(detail::div_u64_digits(u, v), expected) << u << " / " << v;
    ASSERT_EQ(detail::div_u64(u, v), expected) << u << " / " << v;
    if (v <= UINT32_MAX) {
      ASSERT_EQ(detail::div_u64_u32_digits(u, static_cast<std::uint32_t>(v)), expected) << u << " / " << v;
      // By the reciprocal of an invariant divisor (scale_to_norm's root, the rate limit's 1e9).
      const detail::Divisor d = detail::divisor_of(static_cast<std::uint32_t>(v));
      ASSERT_EQ(detail::div_u64_by_digits(u, d), expected) << u << " / " << v;
      ASSERT_EQ(detail::div_u64_by(u, d), expected) << u << " / " << v;
    }
  };
  std::vector<std::uint64_t> divisors = {1,
                                         2,
                                         3,
                                         0x8000ULL,
                                         0xFFFFULL,
                                         0x10000ULL,
                                         0x10001ULL,
                                         0x7FFF'FFFFULL,
                                         0x8000'0000ULL,
                                         0x8000'0001ULL,
                                         0xFFFF'FFFFULL,
                                         0x1'0000'0000ULL,
                                         0x1'0000'0001ULL,
                                         0x1'FFFF'FFFFULL,
                                         0xFFFF'FFFF'FFFF'FFFFULL,
                                         1'000'000'000ULL};
  std::mt19937_64 random(29);
  for (int i = 0; i < 2000; ++i) divisors.push_back((random() >> (random() % 64)) | 1U);
  for (const std::uint64_t v : divisors) {
    for (const std::uint64_t q : {0ULL, 1ULL, 2ULL, 0xFFFFULL, 0x10000ULL, 0xFFFF'FFFEULL, 0xFFFF'FFFFULL}) {
      if (q != 0 && v > UINT64_MAX / q) continue;
      check(q * v, v);
      if (q * v != 0) check(q * v - 1, v);
      if (q * v + v - 1 >= q * v) check(q * v + v - 1, v);
    }
    for (int i = 0; i < 100; ++i) check(random() >> (random() % 64), v);
  }
  static_assert(detail::div_u64_digits(0xFFFF'FFFF'FFFF'FFFFULL, 0xFFFF'FFFFULL) == std::uint64_t{1}
                                                                                        << 32);  // 2^32 + 1: capped
  static_assert(detail::div_u64_digits(0xFFFF'FFFE'FFFF'FFFFULL, 0xFFFF'FFFFULL) == 0xFFFF'FFFFULL);
  static_assert(detail::div_round(std::int64_t{5}, std::int64_t{2}) == 3 && detail::div_round_u32(7, 3U) == 2);
  static_assert(detail::div_u64_by_digits(0xFFFF'FFFE'FFFF'FFFFULL, detail::divisor_of(0xFFFF'FFFFU)) ==
                0xFFFF'FFFFULL);
  static_assert(detail::div_u64_by_digits(0xFFFF'FFFFULL << 32, detail::divisor_of(0xFFFF'FFFFU)) == std::uint64_t{1}
                                                                                                         << 32);
}

// The passivity controller's 1 / |v| (one 32-bit division for two quotients): the
// quotient the 64-bit division gives, saturating as it does, for every small raw value (where
// the quotient is large and saturates) and at random over the whole positive range.
TEST(Fixed, ReciprocalOfAPositiveValueIsTheExactQuotient) {
  const Q one = Q::from_raw(65536);
  const auto check = [&](std::int32_t raw) {
    static_cast<void>(take_fixed_saturated());
    const Q expected = one / Q::from_raw(raw);
    const bool expected_saturated = take_fixed_saturated();
    ASSERT_EQ(Q::reciprocal_of_positive(Q::from_raw(raw)), expected) << raw;
    ASSERT_EQ(take_fixed_saturated(), expected_saturated) << raw;
  };
  for (std::int32_t raw = 1; raw <= 200000; ++raw) check(raw);
  std::mt19937_64 random(29);
  for (int i = 0; i < 200000; ++i) check(static_cast<std::int32_t>(1 + random() % std::uint64_t{INT32_MAX}));
  check(INT32_MAX);
  // 2^-16 and 2^-15 have reciprocals past max(): saturated, with the flag; 3 LSB does not.
  EXPECT_EQ(Q::reciprocal_of_positive(Q::from_raw(2)), Q::max());
  EXPECT_TRUE(take_fixed_saturated());
  EXPECT_EQ(Q::reciprocal_of_positive(Q::from_raw(3)).raw(), 1431655765);  // round(2^32 / 3)
  EXPECT_FALSE(take_fixed_saturated());
  // Zero and below count as the smallest positive value.
  EXPECT_EQ(Q::reciprocal_of_positive(Q::from_raw(-7)), Q::max());
  EXPECT_TRUE(take_fixed_saturated());
  EXPECT_DOUBLE_EQ(reciprocal_of_positive(4.0), 0.25);
}

// The passivity stage's applied share: n / d in [0, 1] in units of 2^-16 from one
// 32-bit division of the normalised top bits, within 2 of the exact quotient, over the whole
// 64-bit range of both sums, and exactly 0 and 1 at the ends.
TEST(Fixed, FractionOfTwoSumsIsWithinTwoOfTheExactQuotient) {
  const auto check = [](std::uint64_t n, std::uint64_t d) {
    const auto exact = static_cast<double>((static_cast<Uint128>(n) << 16) / d);  // floor
    const std::uint32_t q = detail::fraction_q16(n, d);
    ASSERT_LE(q, 1U << 16) << n << " / " << d;
    ASSERT_LE(std::abs(static_cast<double>(q) - exact), 2.0) << n << " / " << d;
  };
  std::mt19937_64 random(29);
  for (int i = 0; i < 1000000; ++i) {
    const std::uint64_t d = (random() >> (random() % 64)) | 1U;
    const std::uint64_t n = d == UINT64_MAX ? random() : random() % (d + 1);
    check(n, d);
    check(d, d);
    check(d - 1, d);
    check(0, d);
  }
  for (const std::uint64_t d :
       {std::uint64_t{1}, std::uint64_t{2}, std::uint64_t{3}, std::uint64_t{0xFFFF}, std::uint64_t{0x1'0000},
        std::uint64_t{0xFFFF'FFFF}, std::uint64_t{1} << 63, std::uint64_t{UINT64_MAX}}) {
    for (std::uint64_t n = 0; n <= 1000 && n <= d; ++n) check(n, d);
    check(d / 2, d);
    check(d / 3, d);
  }
  EXPECT_EQ(detail::fraction_q16(0, 12345), 0U);
  EXPECT_EQ(detail::fraction_q16(12345, 12345), 1U << 16);
  EXPECT_EQ(detail::fraction_q16(UINT64_MAX, UINT64_MAX), 1U << 16);
  EXPECT_NEAR(detail::fraction_q16(1, 2), 32768U, 2U);
}

// The 64-bit count of leading zeros built from the two words without a branch: the same as
// std::countl_zero for every bit position of either word, with the bits below it set or not,
// and for 0 (64).
TEST(Fixed, LeadingZerosFromTwoWordsAgreeWithTheStandardCount) {
  EXPECT_EQ(detail::countl_zero_words(0), 64);
  static_assert(detail::countl_zero_words(0) == 64 && detail::countl_zero_words(1) == 63);
  for (int bit = 0; bit < 64; ++bit) {
    const std::uint64_t top = std::uint64_t{1} << bit;
    for (const std::uint64_t v : {top, top | (top - 1), top | (top >> 1), top | 1U}) {
      ASSERT_EQ(detail::countl_zero_words(v), std::countl_zero(v)) << std::hex << v;
    }
  }
}

TEST(Vec3Fixed, NormIsNotBuiltFromSaturatedSquares) {
  // Each square (40000) is outside Q16.16; the norm (346.41) is not (spec §7).
  const Vec3<Q> v{Q::from_double(200.0), Q::from_double(200.0), Q::from_double(200.0)};
  EXPECT_NEAR(norm(v).to_double(), std::sqrt(3.0) * 200.0, kLsb);
  EXPECT_FALSE(take_fixed_saturated());
}

TEST(Vec3Fixed, ScaleToNormRoundsEachComponentToNearest) {
  // (3, 4, 0) LSB has norm 5 LSB exactly; scaled to 2 LSB it is (1.2, 1.6, 0): (1, 2, 0) rounded
  // to nearest, where truncation would give (1, 1, 0). The same with the signs.
  for (const std::int32_t sign : {1, -1}) {
    const Vec3<Q> v{Q::from_raw(3 * sign), Q::from_raw(4 * sign), Q{}};
    const NormOf<Q> magnitude = norm_of(v);
    ASSERT_EQ(magnitude.root, 5U);
    EXPECT_EQ(scale_to_norm(v, Q::from_raw(2), magnitude), (Vec3<Q>{Q::from_raw(sign), Q::from_raw(2 * sign), Q{}}));
  }
}

__extension__ typedef __int128 I128;  // exact products of products (g++)

TEST(Vec3Fixed, ScaleToNormIsTheRoundedQuotientExceptWithinAHairOfATie) {
  // Each component against c numerator / |v| exactly (128-bit), rounded half away from zero:
  // equal, or one LSB off where the quotient is within |c| 2^-32 LSB of a tie (the factor is a
  // 32-bit fraction). Signs kept, nothing saturates, a numerator past |v| gives v back.
  std::mt19937_64 rng(31);
  std::uniform_int_distribution<std::int32_t> any(INT32_MIN, INT32_MAX);
  for (int i = 0; i < 200000; ++i) {
    const int shift = static_cast<int>(rng() % 31);
    Vec3<Q> v{Q::from_raw(any(rng) >> shift), Q::from_raw(any(rng) >> shift), Q::from_raw(any(rng) >> shift)};
    if (i == 0) v = {Q::lowest(), Q::lowest(), Q::lowest()};
    const NormOf<Q> magnitude = norm_of(v);
    if (magnitude.root == 0) continue;
    const auto numerator = static_cast<std::int32_t>(rng() % (std::min<std::uint64_t>(magnitude.root, INT32_MAX) + 1));
    static_cast<void>(take_fixed_saturated());
    const Vec3<Q> scaled = scale_to_norm(v, Q::from_raw(numerator), magnitude);
    ASSERT_FALSE(take_fixed_saturated());
    for (const auto& [c, got] : {std::pair{v.x, scaled.x}, std::pair{v.y, scaled.y}, std::pair{v.z, scaled.z}}) {
      const I128 product = static_cast<I128>(c.raw()) * numerator;
      const I128 magnitude_product = product < 0 ? -product : product;
      const I128 root = magnitude.root;
      const I128 rounded = (2 * magnitude_product + root) / (2 * root);
      const I128 exact = product < 0 ? -rounded : rounded;
      if (got.raw() == exact) continue;
      ASSERT_EQ(std::abs(static_cast<long long>(got.raw() - exact)), 1)
          << c.raw() << " * " << numerator << " / " << magnitude.root;
      const I128 twice_remainder = 2 * (magnitude_product % root);
      const I128 from_tie = twice_remainder > root ? twice_remainder - root : root - twice_remainder;
      ASSERT_LE(from_tie * (I128{1} << 32), 2 * root * (c.raw() < 0 ? -I128{c.raw()} : c.raw()))
          << c.raw() << " * " << numerator << " / " << magnitude.root << " is not near a tie";
    }
  }
  const Vec3<Q> v{Q::from_double(3.0), Q::from_double(-4.0), Q::from_double(12.0)};
  EXPECT_EQ(scale_to_norm(v, Q::from_double(13.0), norm_of(v)), v);
  EXPECT_EQ(scale_to_norm(v, Q::from_double(100.0), norm_of(v)), v);
  EXPECT_EQ(scale_to_norm(v, Q{}, norm_of(v)), Vec3<Q>{});
  EXPECT_EQ(scale_to_norm(v, Q::from_double(-1.0), norm_of(v)), Vec3<Q>{});
}

TEST(Vec3Fixed, ScaledIfAboveIsNeverPastTheExactlyScaledVectorRoundedAndAtMostOneLsbUnder) {
  // The limits of the tick (rate limit, clamp, the slippery law's): nothing while |v| <= limit
  // (the squares compared exactly), else each component against c limit / |v| (long double),
  // rounded half away from zero: never past it in magnitude, under the exact value by at most
  // 2^-26 of it and half an LSB (the factor's error, the rounding), so at most one LSB under
  // the rounded one below 2^25 LSB (512 N), the sign kept, nothing saturating.
  std::mt19937_64 rng(32);
  std::uniform_int_distribution<std::int32_t> any(INT32_MIN, INT32_MAX);
  int scaled_count = 0;
  for (int i = 0; i < 300000; ++i) {
    const int shift = static_cast<int>(rng() % 31);
    Vec3<Q> v{Q::from_raw(any(rng) >> shift), Q::from_raw(any(rng) >> shift), Q::from_raw(any(rng) >> shift)};
    if (i == 0) v = {Q::lowest(), Q::lowest(), Q::lowest()};
    const std::uint64_t squares = detail::raw_squares(v);
    const long double norm_raw = std::sqrt(static_cast<long double>(squares));
    const auto limit = Q::from_raw(static_cast<std::int32_t>(
        rng() % (std::min<std::uint64_t>(static_cast<std::uint64_t>(norm_raw), INT32_MAX) + 2)));
    static_cast<void>(take_fixed_saturated());
    const std::optional<Vec3<Q>> scaled = scaled_if_above(v, limit);
    ASSERT_FALSE(take_fixed_saturated());
    const auto limit_squared = static_cast<std::uint64_t>(limit.raw()) * static_cast<std::uint64_t>(limit.raw());
    ASSERT_EQ(scaled.has_value(), squares > limit_squared) << i;
    if (!scaled) continue;
    ++scaled_count;
    for (const auto& [c, got] : {std::pair{v.x, scaled->x}, std::pair{v.y, scaled->y}, std::pair{v.z, scaled->z}}) {
      const long double magnitude = std::fabs(static_cast<long double>(c.raw()));
      const long double exact = magnitude * limit.raw() / norm_raw;
      const long double rounded = std::floor(exact + 0.5L);
      const long double g = std::fabs(static_cast<long double>(got.raw()));
      ASSERT_TRUE(got.raw() == 0 || (got.raw() < 0) == (c.raw() < 0)) << c.raw();
      ASSERT_LE(g, rounded) << c.raw() << " * " << limit.raw() << " / " << norm_raw;
      ASSERT_GE(g, exact * (1.0L - 0x1p-26L) - magnitude * 0x1p-32L - 0.5L)
          << c.raw() << " * " << limit.raw() << " / " << norm_raw;
      if (exact < 0x1p25L) {
        ASSERT_GE(g, rounded - 1) << c.raw() << " * " << limit.raw() << " / " << norm_raw;
      }
    }
  }
  EXPECT_GT(scaled_count, 100000);
  // At the boundary: (3, 4, 0) LSB is 5 LSB long exactly.
  const Vec3<Q> v{Q::from_raw(3), Q::from_raw(4), Q{}};
  EXPECT_FALSE(scaled_if_above(v, Q::from_raw(5)).has_value());
  EXPECT_EQ(scaled_if_above(v, Q::from_raw(4)), (Vec3<Q>{Q::from_raw(2), Q::from_raw(3), Q{}}));  // (2.4, 3.2)
  EXPECT_EQ(scaled_if_above(v, Q{}), Vec3<Q>{});
  EXPECT_EQ(scaled_if_above(v, Q::from_double(-1.0)), Vec3<Q>{});
  EXPECT_FALSE(scaled_if_above(Vec3<Q>{}, Q{}).has_value());
}

TEST(Vec3Fixed, TimesInRangeIsTheProductWhereItCannotSaturate) {
  // A vector times a share in [0, 1], and a unit vector's components times a push >= 0: the
  // value operator* gives (the same rounding), and no flag, at the ends of both ranges too.
  std::mt19937_64 rng(35);
  std::uniform_int_distribution<std::int32_t> any(INT32_MIN, INT32_MAX);
  std::uniform_int_distribution<std::int32_t> share(0, 65536);
  std::uniform_int_distribution<std::int32_t> unit(-65536, 65536);
  std::uniform_int_distribution<std::int32_t> push(0, INT32_MAX);
  std::vector<std::pair<Vec3<Q>, Q>> cases = {
      {{Q::lowest(), Q::max(), Q::from_raw(-1)}, Q::from_raw(65536)},
      {{Q::lowest(), Q::max(), Q::from_raw(1)}, Q::from_raw(32768)},
      {{Q::from_raw(-65536), Q::from_raw(65536), Q{}}, Q::max()},
      {{Q::from_raw(-65535), Q::from_raw(3), Q::from_raw(-3)}, Q::from_raw(32768)}};
  for (int i = 0; i < 200000; ++i) {
    cases.push_back({{Q::from_raw(any(rng)), Q::from_raw(any(rng)), Q::from_raw(any(rng))}, Q::from_raw(share(rng))});
    cases.push_back({{Q::from_raw(unit(rng)), Q::from_raw(unit(rng)), Q::from_raw(unit(rng))}, Q::from_raw(push(rng))});
  }
  for (const auto& [v, k] : cases) {
    static_cast<void>(take_fixed_saturated());
    ASSERT_EQ(times_in_range(v, k), v * k) << v.x.raw() << " " << v.y.raw() << " " << v.z.raw() << " times " << k.raw();
    ASSERT_FALSE(take_fixed_saturated());
  }
}

TEST(Vec3Fixed, TimesUnitIsTheProductForAnyPushButTheLowest) {
  // A unit vector's components times any push, negative ones too (an impact's recoil): the
  // value operator* gives and no flag; a push of lowest() is taken as -max(), so a component
  // of -1 gives max() (operator* saturates there) and one of +1 gives -max().
  std::mt19937_64 rng(36);
  std::uniform_int_distribution<std::int32_t> any(INT32_MIN + 1, INT32_MAX);
  std::uniform_int_distribution<std::int32_t> unit(-65536, 65536);
  std::vector<std::pair<Vec3<Q>, Q>> cases = {
      {{Q::from_raw(-65536), Q::from_raw(65536), Q{}}, Q::from_raw(INT32_MIN + 1)},
      {{Q::from_raw(-65536), Q::from_raw(65536), Q::from_raw(-1)}, Q::max()},
      {{Q::from_raw(-65535), Q::from_raw(3), Q::from_raw(-3)}, Q::from_raw(-32768)}};
  for (int i = 0; i < 200000; ++i) {
    cases.push_back({{Q::from_raw(unit(rng)), Q::from_raw(unit(rng)), Q::from_raw(unit(rng))}, Q::from_raw(any(rng))});
  }
  for (const auto& [v, k] : cases) {
    static_cast<void>(take_fixed_saturated());
    ASSERT_EQ(times_unit(v, k), v * k) << v.x.raw() << " " << v.y.raw() << " " << v.z.raw() << " times " << k.raw();
    ASSERT_FALSE(take_fixed_saturated());
  }
  const Vec3<Q> axes{Q::from_raw(-65536), Q::from_raw(65536), Q::from_raw(32768)};
  EXPECT_EQ(times_unit(axes, Q::lowest()), (Vec3<Q>{Q::max(), -Q::max(), Q::from_raw(-(INT32_MAX / 2 + 1))}));
  EXPECT_FALSE(take_fixed_saturated());
  // Floating point multiplies.
  EXPECT_EQ(times_unit(Vec3<double>{-1.0, 1.0, 0.5}, -3.0), (Vec3<double>{3.0, -3.0, -1.5}));
}

TEST(Vec3Fixed, DotWithAUnitVectorIsTheDotProductWithoutItsOverflowTests) {
  // A plane's contact and a tangential part take n.v and n.(x - p) with a unit n: the same
  // value as dot(), and for n.(x - p) the exact one even where a component of x - p saturates.
  std::mt19937_64 rng(33);
  std::uniform_int_distribution<std::int32_t> any(INT32_MIN, INT32_MAX);
  std::normal_distribution<double> gauss;
  for (int i = 0; i < 100000; ++i) {
    const Vec3<double> d{gauss(rng), gauss(rng), gauss(rng)};
    const double length = std::sqrt(dot(d, d));
    const Vec3<Q> n =
        i % 7 == 0 ? Vec3<Q>{Q{}, Q{}, Q::from_raw(i % 2 == 0 ? 65536 : -65536)} : vec_cast<Q>(d * (1.0 / length));
    const int shift = static_cast<int>(rng() % 32);
    const Vec3<Q> v{Q::from_raw(any(rng) >> shift), Q::from_raw(any(rng) >> shift), Q::from_raw(any(rng) >> shift)};
    const Vec3<Q> p{Q::from_raw(any(rng) >> shift), Q::from_raw(any(rng) >> shift), Q::from_raw(any(rng) >> shift)};
    static_cast<void>(take_fixed_saturated());
    const Q expected_v = dot(n, v);
    const bool saturated_v = take_fixed_saturated();
    ASSERT_EQ(dot_unit(n, v), expected_v);
    ASSERT_EQ(take_fixed_saturated(), saturated_v);
    // n.(v - p) exactly: the raw products of the exact differences, summed, rounded once.
    I128 exact = 0;
    for (const auto& [a, b, c] : {std::tuple{n.x, v.x, p.x}, std::tuple{n.y, v.y, p.y}, std::tuple{n.z, v.z, p.z}}) {
      exact += I128{a.raw()} * (I128{b.raw()} - c.raw());
    }
    const I128 magnitude = exact < 0 ? -exact : exact;
    const I128 rounded_magnitude = (magnitude + 0x8000) >> 16;
    const I128 rounded = exact < 0 ? -rounded_magnitude : rounded_magnitude;
    const std::int32_t want = rounded > INT32_MAX   ? INT32_MAX
                              : rounded < INT32_MIN ? INT32_MIN
                                                    : static_cast<std::int32_t>(rounded);
    ASSERT_EQ(dot_unit_difference(n, v, p).raw(), want) << i;
    ASSERT_EQ(take_fixed_saturated(), rounded > INT32_MAX || rounded < INT32_MIN) << i;
  }
}

TEST(WideFixed, SquaredNormIsTheExactDotProductOfAVectorWithItself) {
  // The thermal model's (|F| / F_c)^2 from the raw squares summed unsigned: the value and the
  // flag of Wide::dot(v, v), which saturates at 2^63 exactly when the squares pass it.
  std::mt19937_64 rng(34);
  std::uniform_int_distribution<std::int32_t> any(INT32_MIN, INT32_MAX);
  std::vector<Vec3<Q>> vectors = {Vec3<Q>{Q::lowest(), Q::lowest(), Q::lowest()},
                                  Vec3<Q>{Q::lowest(), Q::lowest(), Q{}}, Vec3<Q>{Q::max(), Q::max(), Q::max()},
                                  Vec3<Q>{Q::lowest(), Q::from_raw(1), Q{}}, Vec3<Q>{}};
  for (int i = 0; i < 100000; ++i) {
    const int shift = static_cast<int>(rng() % 32);
    vectors.push_back({Q::from_raw(any(rng) >> shift), Q::from_raw(any(rng) >> shift), Q::from_raw(any(rng) >> shift)});
  }
  for (const Vec3<Q>& v : vectors) {
    static_cast<void>(take_fixed_saturated());
    const Wide<Q> expected = Wide<Q>::dot(v, v);
    const bool saturated = take_fixed_saturated();
    ASSERT_EQ(Wide<Q>::squared_norm(v), expected) << v.x.raw() << " " << v.y.raw() << " " << v.z.raw();
    ASSERT_EQ(take_fixed_saturated(), saturated) << v.x.raw() << " " << v.y.raw() << " " << v.z.raw();
  }
  EXPECT_EQ(Wide<Q>::squared_norm(Vec3<Q>{Q::from_double(3.0), Q::from_double(4.0), Q{}}).to_double(), 25.0);
}

TEST(WideFixed, TimesAFractionIsTheExactProductRoundedOnce) {
  // The passivity controller's work times the applied share (0..1): round(d q / 2^16), half
  // up, for every Q32.32 value, the extremes included, and never a saturation.
  std::mt19937_64 rng(35);
  std::vector<std::int64_t> values = {INT64_MAX, -INT64_MAX, 0, 1, -1, 0x8000, -0x8000, std::int64_t{1} << 32};
  for (int i = 0; i < 200000; ++i) values.push_back(static_cast<std::int64_t>(rng()) >> (rng() % 64));
  std::vector<std::int32_t> fractions = {0, 1, 0x7FFF, 0x8000, 0xFFFF, 0x10000};
  for (int i = 0; i < 20; ++i) fractions.push_back(static_cast<std::int32_t>(rng() % 0x10001));
  static_cast<void>(take_fixed_saturated());
  for (const std::int64_t d : values) {
    for (const std::int32_t q : fractions) {
      const I128 exact = static_cast<I128>(d) * q;
      const I128 want = (exact + 0x8000) >> 16;  // floor(x + 1/2): half up
      ASSERT_EQ(Wide<Q>::from_raw(d).times_fraction(Q::from_raw(q)).raw(), static_cast<std::int64_t>(want))
          << d << " " << q;
    }
  }
  EXPECT_FALSE(take_fixed_saturated());
}

TEST(Vec3Fixed, DotAccumulatesInSixtyFourBitsAndRoundsOnce) {
  const Vec3<Q> a{Q::from_double(300.0), Q::from_double(300.0), Q::from_double(0.001)};
  const Vec3<Q> b{Q::from_double(300.0), Q::from_double(-300.0), Q::from_double(0.001)};
  // 90000 - 90000 + 1e-6: each product alone would saturate.
  EXPECT_NEAR(dot(a, b).to_double(), 1e-6, kLsb);
  EXPECT_FALSE(take_fixed_saturated());
  const Vec3<Q> c{Q::from_double(300.0), Q::from_double(300.0), Q{}};
  EXPECT_EQ(dot(c, c), Q::max());  // 180000 does not fit: saturates, with the flag
  EXPECT_TRUE(take_fixed_saturated());
}

TEST(Vec3, LimitMagnitudeKeepsDirection) {
  const Vec3<double> v{3.0, 4.0, 0.0};
  const auto w = limit_magnitude(v, 2.5);
  EXPECT_NEAR(norm(w), 2.5, 1e-15);
  EXPECT_NEAR(w.x / w.y, 0.75, 1e-15);
  EXPECT_EQ(limit_magnitude(v, 6.0), v);
}

/// Max |sin_turns - sin| over a dense grid of two turns (negative phases included).
template <Scalar S>
double sine_error(SineMethod method) {
  double worst = 0.0;
  for (int i = -20000; i <= 20000; ++i) {
    const double turns = i / 10000.0 + 0.5e-5;
    const S value = sin_turns(scalar_cast<S>(turns), method);
    // Compare with the sine of the phase as the scalar holds it (input rounding is not the
    // method's error).
    const double exact = std::sin(2.0 * M_PI * to_double(scalar_cast<S>(turns)));
    worst = std::max(worst, std::abs(to_double(value) - exact));
  }
  return worst;
}

// The bounds stated in math/sine.hpp, checked.
TEST(Sine, DoubleMethodsMeetTheirStatedErrors) {
  EXPECT_LT(sine_error<double>(SineMethod::kLibrary), 1e-15);
  EXPECT_LT(sine_error<double>(SineMethod::kPolynomial), 6e-7);
  EXPECT_LT(sine_error<double>(SineMethod::kTable), 5e-6);
}

TEST(Sine, FloatMethodsMeetTheirStatedErrors) {
  EXPECT_LT(sine_error<float>(SineMethod::kLibrary), 2e-6);  // 2 pi p rounds in float
  EXPECT_LT(sine_error<float>(SineMethod::kPolynomial), 1e-6);
  EXPECT_LT(sine_error<float>(SineMethod::kTable), 5e-6);
}

// The Q16.16 polynomial in 32-bit words gives the 64-bit evaluation's result for every
// quarter-wave argument there is (sine.hpp: fixed_polynomial_q16), so no force changed with it.
TEST(Sine, Q16PolynomialInWordsIsTheWideOneOnEveryArgument) {
  int differ = 0;
  for (std::int32_t raw = 0; raw <= Q::kOneRaw / 4; ++raw) {
    const Q wide = detail::fixed_polynomial(Q::from_raw(raw));
    const std::int32_t words = detail::fixed_polynomial_q16(raw);
    if (words != wide.raw()) {
      ADD_FAILURE() << "q = " << raw << " / 65536: " << words << " against " << wide.raw();
      if (++differ == 5) break;
    }
  }
  EXPECT_FALSE(take_fixed_saturated());
}

TEST(Sine, Q16MethodsStayNearTheFormatResolution) {
  EXPECT_LT(sine_error<Q>(SineMethod::kPolynomial), 1 * kLsb);
  EXPECT_LT(sine_error<Q>(SineMethod::kTable), 3 * kLsb);
  EXPECT_FALSE(take_fixed_saturated());
}

}  // namespace
}  // namespace toonforce
