// SPDX-License-Identifier: Apache-2.0
// Cost of the tick-path GPIO calls (Google Benchmark). By default through the umockdev
// emulation of /dev/gpiochip0: an emulated ioctl is a round trip over a unix socket to
// umockdev's worker thread (~0.2 ms, docs/GPIO.md), so those numbers are the
// EMULATION's cost and say nothing about hardware. On a bring-up host, point it at real, free
// lines instead (the output line is toggled, the input only read):
//   umockdev-wrapper build/release/tools/gpio/toonforce_gpio_bench              # emulated
//   TOONFORCE_GPIO_BENCH_OUTPUT=gpiochip0:17 TOONFORCE_GPIO_BENCH_INPUT=gpiochip0:27
//     build/release/tools/gpio/toonforce_gpio_bench                             # real lines
// (both variables on the command line of the second form).
// It also counts operator new per call, which is meaningful anywhere: the C-API path
// allocates nothing, gpiod.hpp's line::set_value allocates on every call.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <cstdlib>
#include <memory>
#include <new>
#include <vector>

#include <gpiod.hpp>

#include "toonforce/hal/gpio/emulated_gpio.hpp"
#include "toonforce/hal/gpio/gpio_session.hpp"

namespace toonforce::bench {
std::size_t new_calls() noexcept;  // count_new.cpp
}  // namespace toonforce::bench

namespace toonforce::gpio {
namespace {

const char* env_or(const char* name, const char* fallback) {
  const char* value = std::getenv(name);
  return value != nullptr && *value != '\0' ? value : fallback;
}
const char* output_line() { return env_or("TOONFORCE_GPIO_BENCH_OUTPUT", "gpiochip0:0"); }
const char* input_line() { return env_or("TOONFORCE_GPIO_BENCH_INPUT", "gpiochip0:1"); }

Result<GpioSession> open_bench_pins() {
  GpioOptions o;
  o.tick_pin = output_line();
  o.estop_pin = input_line();
  return open_gpio(o);
}

void report_allocations(benchmark::State& state, std::size_t allocations) {
  state.counters["allocs/call"] =
      benchmark::Counter(static_cast<double>(allocations), benchmark::Counter::kAvgIterations);
}

void BM_TickToggle(benchmark::State& state) {
  auto session = open_bench_pins();
  if (!session) return state.SkipWithError(session.error().c_str());
  GpioPins pins = session->pins();
  const std::size_t before = bench::new_calls();
  for (auto _ : state) pins.tick.toggle();
  report_allocations(state, bench::new_calls() - before);
  if (pins.tick.write_errors() != 0) state.SkipWithError("write errors");
}
BENCHMARK(BM_TickToggle)->Unit(benchmark::kMicrosecond);

void BM_InputRead(benchmark::State& state) {
  auto session = open_bench_pins();
  if (!session) return state.SkipWithError(session.error().c_str());
  GpioPins pins = session->pins();
  const std::size_t before = bench::new_calls();
  for (auto _ : state) benchmark::DoNotOptimize(pins.estop.read());
  report_allocations(state, bench::new_calls() - before);
}
BENCHMARK(BM_InputRead)->Unit(benchmark::kMicrosecond);

// For comparison only: the libgpiod C++ wrapper's set_value on the output line.
void BM_CxxWrapperSetValue(benchmark::State& state) {
  try {
    auto spec = parse_line_spec(output_line());
    if (!spec || spec->by_name()) return state.SkipWithError("give the output as CHIP:OFFSET");
    gpiod::chip chip(chip_path(spec->chip));
    gpiod::line line = chip.get_line(spec->offset);
    line.request({"toonforce-bench", gpiod::line_request::DIRECTION_OUTPUT, 0}, 0);
    int value = 0;
    const std::size_t before = bench::new_calls();
    for (auto _ : state) line.set_value(value ^= 1);
    report_allocations(state, bench::new_calls() - before);
    line.release();
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
  }
}
BENCHMARK(BM_CxxWrapperSetValue)->Unit(benchmark::kMicrosecond);

// What a run without that pin pays: one predictable branch.
void BM_AbsentTickPin(benchmark::State& state) {
  GpioTickPin pin;
  for (auto _ : state) {
    pin.toggle();
    benchmark::ClobberMemory();
  }
}
BENCHMARK(BM_AbsentTickPin);

void BM_NullTickPin(benchmark::State& state) {
  NullTickPin pin;
  for (auto _ : state) {
    pin.toggle();
    benchmark::ClobberMemory();
  }
}
BENCHMARK(BM_NullTickPin);

}  // namespace
}  // namespace toonforce::gpio

int main(int argc, char** argv) {
  using toonforce::gpio::emulation::EmulatedGpio;
  std::unique_ptr<EmulatedGpio> emulation;
  if (std::getenv("TOONFORCE_GPIO_BENCH_OUTPUT") != nullptr) {
    std::printf("real GPIO lines: output %s, input %s\n", toonforce::gpio::output_line(),
                toonforce::gpio::input_line());
  } else if (EmulatedGpio::available()) {
    emulation = std::make_unique<EmulatedGpio>(std::vector<toonforce::gpio::emulation::ChipSpec>{{"bench", 8, {}}});
    std::printf("EMULATED /dev/gpiochip0 (umockdev): these times are the emulation's, not "
                "hardware's\n");
  } else {
    std::fprintf(stderr, "toonforce_gpio_bench: run it under umockdev-wrapper (emulated "
                         "/dev/gpiochip0), or set TOONFORCE_GPIO_BENCH_OUTPUT=CHIP:OFFSET "
                         "(and _INPUT) to real lines\n");
    return 77;
  }
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
