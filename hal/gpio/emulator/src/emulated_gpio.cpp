// SPDX-License-Identifier: Apache-2.0
// The emulated kernel side of the GPIO uAPI v1 (linux/gpio.h), as libgpiod 1.6 drives it:
//   chip fd:        GPIO_GET_CHIPINFO_IOCTL, GPIO_GET_LINEINFO_IOCTL, GPIO_GET_LINEHANDLE_IOCTL
//   line-handle fd: GPIOHANDLE_GET_LINE_VALUES_IOCTL, GPIOHANDLE_SET_LINE_VALUES_IOCTL
// A line request must hand back a new fd whose ioctls also reach us. The handler runs in this
// process, so it opens another emulated node (/dev/gpio-line-handle, with its own handler) and
// returns that fd; each open is a new umockdev client, which `client-connected` ties to the
// lines of the request waiting for it (docs/GPIO.md, "The emulation").
#include "toonforce/hal/gpio/emulated_gpio.hpp"

#include <fcntl.h>
#include <linux/gpio.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <deque>
#include <mutex>
#include <stdexcept>

#include <fmt/format.h>
#include <umockdev.h>

namespace toonforce::gpio::emulation {

namespace {

constexpr const char* kHandleNode = "/dev/gpio-line-handle";

struct Line {
  LineState state;
  std::string name;
  bool claimed = false;  // held by "another program"
  bool driven = false;   // something outside drives the (input) pin
  int request_error = 0;
  int value_error = 0;
};

struct Chip {
  ChipSpec spec;
  std::vector<Line> lines;
  int open_error = 0;
};

/// The lines one handle fd holds.
struct Handle {
  unsigned chip = 0;
  std::vector<unsigned> offsets;
};

GObject* as_object(void* p) { return reinterpret_cast<GObject*>(p); }

}  // namespace

struct EmulatedGpio::Impl {
  struct ChipContext {
    Impl* impl;
    unsigned chip;
  };

  UMockdevTestbed* testbed = nullptr;
  std::vector<UMockdevIoctlBase*> handlers;
  std::vector<std::unique_ptr<ChipContext>> contexts;

  mutable std::mutex mu;
  std::vector<Chip> chips;
  std::deque<Handle> pending;  // requests whose handle fd has not connected yet
  struct Held {
    UMockdevIoctlClient* client;  // a reference we own
    Handle handle;
  };
  std::vector<Held> held;  // connected handle fds and their lines
  std::uint64_t ioctls = 0;

  Line& at(unsigned chip, unsigned offset) {
    if (chip >= chips.size() || offset >= chips[chip].lines.size()) {
      throw std::out_of_range(fmt::format("emulated gpiochip{} has no line {}", chip, offset));
    }
    return chips[chip].lines[offset];
  }

  // Where an undriven input settles: the pull resistor, else where it was.
  static void settle(Line& l) {
    if (l.driven || l.state.output) return;
    if (l.state.bias == Bias::kPullUp) l.state.physical = 1;
    if (l.state.bias == Bias::kPullDown) l.state.physical = 0;
  }

  static UMockdevIoctlData* argument(UMockdevIoctlClient* client, gulong request) {
    GError* error = nullptr;
    UMockdevIoctlData* data =
        umockdev_ioctl_data_resolve(umockdev_ioctl_client_get_arg(client), 0, _IOC_SIZE(request), &error);
    if (error != nullptr) g_error_free(error);
    return data;
  }

  static void complete(UMockdevIoctlClient* client, int error) {
    umockdev_ioctl_client_complete(client, error == 0 ? 0 : -1, error);
  }

  static gboolean on_chip_ioctl(UMockdevIoctlBase*, UMockdevIoctlClient* client, gpointer user) {
    auto* ctx = static_cast<ChipContext*>(user);
    Impl& self = *ctx->impl;
    const gulong request = umockdev_ioctl_client_get_request(client);
    UMockdevIoctlData* data = argument(client, request);
    std::unique_lock lock(self.mu);
    ++self.ioctls;
    self.reap_closed_handles();
    Chip& chip = self.chips[ctx->chip];
    if (data == nullptr) {
      complete(client, EFAULT);
      return TRUE;
    }

    if (request == GPIO_GET_CHIPINFO_IOCTL) {
      if (chip.open_error != 0) {
        complete(client, chip.open_error);
        return TRUE;
      }
      auto* info = reinterpret_cast<gpiochip_info*>(data->data);
      std::snprintf(info->name, sizeof info->name, "gpiochip%u", ctx->chip);
      std::snprintf(info->label, sizeof info->label, "%s", chip.spec.label.c_str());
      info->lines = static_cast<__u32>(chip.lines.size());
      complete(client, 0);
      return TRUE;
    }

    if (request == GPIO_GET_LINEINFO_IOCTL) {
      auto* info = reinterpret_cast<gpioline_info*>(data->data);
      if (info->line_offset >= chip.lines.size()) {
        complete(client, EINVAL);
        return TRUE;
      }
      const Line& l = chip.lines[info->line_offset];
      __u32 flags = 0;
      if (l.state.requested) flags |= GPIOLINE_FLAG_KERNEL;
      if (l.state.output) flags |= GPIOLINE_FLAG_IS_OUT;
      if (l.state.active_low) flags |= GPIOLINE_FLAG_ACTIVE_LOW;
      if (l.state.bias == Bias::kPullUp) flags |= GPIOLINE_FLAG_BIAS_PULL_UP;
      if (l.state.bias == Bias::kPullDown) flags |= GPIOLINE_FLAG_BIAS_PULL_DOWN;
      info->flags = flags;
      std::snprintf(info->name, sizeof info->name, "%s", l.name.c_str());
      std::snprintf(info->consumer, sizeof info->consumer, "%s", l.state.consumer.c_str());
      complete(client, 0);
      return TRUE;
    }

    if (request == GPIO_GET_LINEHANDLE_IOCTL) {
      auto* req = reinterpret_cast<gpiohandle_request*>(data->data);
      if (req->lines == 0 || req->lines > GPIOHANDLES_MAX) {
        complete(client, EINVAL);
        return TRUE;
      }
      Handle handle{ctx->chip, {}};
      for (__u32 i = 0; i < req->lines; ++i) {
        const unsigned offset = req->lineoffsets[i];
        if (offset >= chip.lines.size()) {
          complete(client, EINVAL);
          return TRUE;
        }
        const Line& l = chip.lines[offset];
        if (l.state.requested) {  // the kernel: one requester per line
          complete(client, EBUSY);
          return TRUE;
        }
        if (l.request_error != 0) {
          complete(client, l.request_error);
          return TRUE;
        }
        handle.offsets.push_back(offset);
      }
      const bool output = (req->flags & GPIOHANDLE_REQUEST_OUTPUT) != 0;
      const bool active_low = (req->flags & GPIOHANDLE_REQUEST_ACTIVE_LOW) != 0;
      const Bias bias = (req->flags & GPIOHANDLE_REQUEST_BIAS_PULL_UP) != 0     ? Bias::kPullUp
                        : (req->flags & GPIOHANDLE_REQUEST_BIAS_PULL_DOWN) != 0 ? Bias::kPullDown
                                                                                : Bias::kAsIs;
      for (__u32 i = 0; i < req->lines; ++i) {
        Line& l = chip.lines[req->lineoffsets[i]];
        l.state.requested = true;
        l.state.output = output;
        l.state.active_low = active_low;
        l.state.bias = bias;
        l.state.consumer = std::string(req->consumer_label, strnlen(req->consumer_label, sizeof req->consumer_label));
        if (output) l.state.physical = (req->default_values[i] != 0 ? 1 : 0) ^ (active_low ? 1 : 0);
        settle(l);
      }
      self.pending.push_back(std::move(handle));
      // Unlock: opening an emulated node from the handler must not hold our lock while
      // umockdev sets up the new client.
      lock.unlock();
      req->fd = open(kHandleNode, O_RDWR | O_CLOEXEC);
      complete(client, req->fd < 0 ? errno : 0);
      return TRUE;
    }

    complete(client, ENOTTY);
    return TRUE;
  }

  static void on_handle_connected(UMockdevIoctlBase*, UMockdevIoctlClient* client, gpointer user) {
    Impl& self = *static_cast<Impl*>(user);
    std::lock_guard lock(self.mu);
    if (self.pending.empty()) return;  // someone opened the node directly: no lines
    auto* handle = new Handle(std::move(self.pending.front()));
    self.pending.pop_front();
    self.held.push_back({reinterpret_cast<UMockdevIoctlClient*>(g_object_ref(client)), *handle});
    g_object_set_data_full(as_object(client), "toonforce-handle", handle,
                           [](gpointer p) { delete static_cast<Handle*>(p); });
  }

  // A closed handle fd (libgpiod released its lines) frees the lines. umockdev 0.17 declares
  // `client-vanished` but never emits it, and its `notify::connected` did not reach us either;
  // what is reliable is the client's `connected` state once umockdev's worker has seen the
  // EOF, so held handles are checked whenever someone looks at the lines. Lock held.
  void reap_closed_handles() {
    for (auto it = held.begin(); it != held.end();) {
      if (umockdev_ioctl_client_get_connected(it->client) != FALSE) {
        ++it;
        continue;
      }
      for (const unsigned offset : it->handle.offsets) {
        Line& l = chips[it->handle.chip].lines[offset];
        l.state.requested = false;
        l.state.consumer.clear();
      }
      g_object_unref(it->client);
      it = held.erase(it);
    }
  }

  static gboolean on_handle_ioctl(UMockdevIoctlBase*, UMockdevIoctlClient* client, gpointer user) {
    Impl& self = *static_cast<Impl*>(user);
    const gulong request = umockdev_ioctl_client_get_request(client);
    const auto* handle = static_cast<const Handle*>(g_object_get_data(as_object(client), "toonforce-handle"));
    std::lock_guard lock(self.mu);
    ++self.ioctls;
    if (handle == nullptr ||
        (request != GPIOHANDLE_GET_LINE_VALUES_IOCTL && request != GPIOHANDLE_SET_LINE_VALUES_IOCTL)) {
      complete(client, ENOTTY);
      return TRUE;
    }
    UMockdevIoctlData* data = argument(client, request);
    if (data == nullptr) {
      complete(client, EFAULT);
      return TRUE;
    }
    auto* values = reinterpret_cast<gpiohandle_data*>(data->data);
    Chip& chip = self.chips[handle->chip];
    for (const unsigned offset : handle->offsets) {
      if (chip.lines[offset].value_error != 0) {
        complete(client, chip.lines[offset].value_error);
        return TRUE;
      }
    }
    for (std::size_t i = 0; i < handle->offsets.size(); ++i) {
      Line& l = chip.lines[handle->offsets[i]];
      const int invert = l.state.active_low ? 1 : 0;
      if (request == GPIOHANDLE_GET_LINE_VALUES_IOCTL) {
        values->values[i] = static_cast<__u8>(l.state.physical ^ invert);
        ++l.state.reads;
      } else {
        if (!l.state.output) {  // the kernel refuses to set an input
          complete(client, EPERM);
          return TRUE;
        }
        const int physical = (values->values[i] != 0 ? 1 : 0) ^ invert;
        if (physical != l.state.physical) ++l.state.changes;
        l.state.physical = physical;
        ++l.state.writes;
      }
    }
    complete(client, 0);
    return TRUE;
  }
};

bool EmulatedGpio::available() noexcept {
  // umockdev_in_mock_environment() stats /sys, which the preload redirects only while a
  // testbed exists, and caches its first answer: ask it once, with a testbed.
  static const bool in_mock = [] {
    UMockdevTestbed* testbed = umockdev_testbed_new();
    const bool answer = umockdev_in_mock_environment() != FALSE;
    g_object_unref(testbed);
    return answer;
  }();
  return in_mock;
}

EmulatedGpio::EmulatedGpio(const std::vector<ChipSpec>& chips) : impl_(std::make_unique<Impl>()) {
  if (!available()) throw std::runtime_error("EmulatedGpio needs umockdev-wrapper");
  Impl& self = *impl_;
  self.testbed = umockdev_testbed_new();

  std::string description;
  for (unsigned i = 0; i < chips.size(); ++i) {
    Chip chip{chips[i], std::vector<Line>(chips[i].num_lines), 0};
    for (unsigned offset = 0; offset < chip.lines.size() && offset < chips[i].line_names.size(); ++offset) {
      chip.lines[offset].name = chips[i].line_names[offset];
    }
    self.chips.push_back(std::move(chip));
    // libgpiod checks that /dev/gpiochipN is a char device whose major:minor matches
    // /sys/bus/gpio/devices/gpiochipN/dev; umockdev fakes stat() and the bus link from this.
    description += fmt::format("P: /devices/platform/toonforce-gpio.0/gpiochip{0}\nN: gpiochip{0}\n"
                               "E: DEVNAME=/dev/gpiochip{0}\nE: MAJOR=254\nE: MINOR={0}\nE: SUBSYSTEM=gpio\n"
                               "A: dev=254:{0}\\n\n\n",
                               i);
  }
  description += "P: /devices/platform/toonforce-gpio.0/gpio-line-handle\nN: gpio-line-handle\n"
                 "E: SUBSYSTEM=gpiohandle\n";
  GError* error = nullptr;
  if (umockdev_testbed_add_from_string(self.testbed, description.c_str(), &error) == FALSE) {
    const std::string message = error != nullptr ? error->message : "unknown error";
    if (error != nullptr) g_error_free(error);
    g_object_unref(self.testbed);
    throw std::runtime_error("umockdev: " + message);
  }

  auto attach = [&](const std::string& node, UMockdevIoctlBase* handler) {
    self.handlers.push_back(handler);
    GError* attach_error = nullptr;
    if (umockdev_testbed_attach_ioctl(self.testbed, node.c_str(), handler, &attach_error) == FALSE) {
      const std::string message = attach_error != nullptr ? attach_error->message : "unknown error";
      if (attach_error != nullptr) g_error_free(attach_error);
      throw std::runtime_error("umockdev: cannot attach " + node + ": " + message);
    }
  };
  for (unsigned i = 0; i < chips.size(); ++i) {
    self.contexts.push_back(std::make_unique<Impl::ChipContext>(Impl::ChipContext{&self, i}));
    UMockdevIoctlBase* handler = umockdev_ioctl_base_new();
    g_signal_connect(handler, "handle-ioctl", reinterpret_cast<GCallback>(&Impl::on_chip_ioctl),
                     self.contexts.back().get());
    attach(fmt::format("/dev/gpiochip{}", i), handler);
  }
  UMockdevIoctlBase* handle_handler = umockdev_ioctl_base_new();
  g_signal_connect(handle_handler, "handle-ioctl", reinterpret_cast<GCallback>(&Impl::on_handle_ioctl), &self);
  g_signal_connect(handle_handler, "client-connected", reinterpret_cast<GCallback>(&Impl::on_handle_connected), &self);
  attach(kHandleNode, handle_handler);
}

EmulatedGpio::~EmulatedGpio() {
  Impl& self = *impl_;
  // The testbed first: it stops umockdev's worker thread, the only caller of our handlers.
  if (self.testbed != nullptr) g_object_unref(self.testbed);
  for (auto* handler : self.handlers) g_object_unref(handler);
  for (auto& h : self.held) g_object_unref(h.client);
}

void EmulatedGpio::drive(unsigned chip, unsigned offset, int level) {
  std::lock_guard lock(impl_->mu);
  Line& l = impl_->at(chip, offset);
  l.driven = true;
  l.state.physical = level != 0 ? 1 : 0;
}

void EmulatedGpio::disconnect(unsigned chip, unsigned offset) {
  std::lock_guard lock(impl_->mu);
  Line& l = impl_->at(chip, offset);
  l.driven = false;
  Impl::settle(l);
}

LineState EmulatedGpio::line(unsigned chip, unsigned offset) const {
  std::lock_guard lock(impl_->mu);
  impl_->reap_closed_handles();
  return impl_->at(chip, offset).state;
}

std::uint64_t EmulatedGpio::ioctl_count() const {
  std::lock_guard lock(impl_->mu);
  return impl_->ioctls;
}

void EmulatedGpio::claim(unsigned chip, unsigned offset, std::string consumer) {
  std::lock_guard lock(impl_->mu);
  Line& l = impl_->at(chip, offset);
  l.claimed = true;
  l.state.requested = true;
  l.state.consumer = std::move(consumer);
}

void EmulatedGpio::deny_open(unsigned chip, int error) {
  std::lock_guard lock(impl_->mu);
  if (chip >= impl_->chips.size()) throw std::out_of_range("no such emulated chip");
  impl_->chips[chip].open_error = error;
}

void EmulatedGpio::fail_request(unsigned chip, unsigned offset, int error) {
  std::lock_guard lock(impl_->mu);
  impl_->at(chip, offset).request_error = error;
}

void EmulatedGpio::fail_values(unsigned chip, unsigned offset, int error) {
  std::lock_guard lock(impl_->mu);
  impl_->at(chip, offset).value_error = error;
}

}  // namespace toonforce::gpio::emulation
