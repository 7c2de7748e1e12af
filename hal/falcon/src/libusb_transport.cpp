// SPDX-License-Identifier: Apache-2.0
// FalconTransport over libusb-1.0 (FALCON.md §1: interface 0, bulk OUT 0x02, bulk IN 0x81,
// vendor requests with bmRequestType 0x40, wIndex 0, 1000 ms).
#include "libusb_transport.hpp"

#include <grp.h>
#include <linux/usbdevice_fs.h>
#include <poll.h>
#include <pwd.h>
#include <sys/ioctl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>

#include "udev_check.hpp"

namespace toonforce::falcon {
namespace {

constexpr unsigned kControlTimeoutMs = 1000;
constexpr int kInterface = 0;
constexpr std::uint8_t kVendorOut = 0x40;  // vendor | device | host-to-device (FALCON.md §1)

void LIBUSB_CALL mark_completed(libusb_transfer* transfer) { *static_cast<int*>(transfer->user_data) = 1; }

}  // namespace

TransportStatus from_libusb(int error) noexcept {
  switch (error) {
    case LIBUSB_SUCCESS: return TransportStatus::kOk;
    case LIBUSB_ERROR_TIMEOUT: return TransportStatus::kTimeout;
    case LIBUSB_ERROR_NO_DEVICE: return TransportStatus::kNoDevice;
    case LIBUSB_ERROR_ACCESS: return TransportStatus::kAccessDenied;
    case LIBUSB_ERROR_BUSY: return TransportStatus::kBusy;
    case LIBUSB_ERROR_PIPE: return TransportStatus::kStall;
    default: return TransportStatus::kIoError;
  }
}

std::shared_ptr<UsbContext> UsbContext::create(std::string& error) {
  libusb_context* ctx = nullptr;
  const int r = libusb_init(&ctx);
  if (r != LIBUSB_SUCCESS) {
    error = std::string("cannot initialise libusb-1.0: ") + libusb_error_name(r);
    return nullptr;
  }
  return std::shared_ptr<UsbContext>(new UsbContext(ctx));
}

UsbContext::~UsbContext() { libusb_exit(ctx_); }

std::vector<UsbFalcon> find_falcons(libusb_context* ctx, libusb_device**& list) {
  std::vector<UsbFalcon> out;
  list = nullptr;
  const ssize_t n = libusb_get_device_list(ctx, &list);
  for (ssize_t i = 0; i < n; ++i) {
    libusb_device_descriptor d{};
    if (libusb_get_device_descriptor(list[i], &d) != LIBUSB_SUCCESS) continue;
    if (d.idVendor != kFalconVendorId || d.idProduct != kFalconProductId) continue;
    UsbFalcon f;
    f.device = list[i];
    f.bus = libusb_get_bus_number(list[i]);
    f.address = libusb_get_device_address(list[i]);
    char node[64];
    std::snprintf(node, sizeof node, "/dev/bus/usb/%03u/%03u", f.bus, f.address);
    f.node = node;
    char location[96];
    std::snprintf(location, sizeof location, "usb %03u/%03u (%s)", f.bus, f.address, node);
    f.location = location;
    out.push_back(f);
  }
  // libusb lists devices in no documented order: number them by bus and address instead.
  std::sort(out.begin(), out.end(), [](const UsbFalcon& a, const UsbFalcon& b) {
    return a.bus != b.bus ? a.bus < b.bus : a.address < b.address;
  });
  return out;
}

std::string describe_node(const std::string& node) {
  struct stat st {};
  if (::stat(node.c_str(), &st) != 0) return {};
  char mode[11] = "----------";
  mode[0] = S_ISCHR(st.st_mode) ? 'c' : '-';
  const char* rwx = "rwxrwxrwx";
  for (int i = 0; i < 9; ++i) {
    if (st.st_mode & (1u << (8 - i))) mode[i + 1] = rwx[i];
  }
  const passwd* pw = ::getpwuid(st.st_uid);
  const group* gr = ::getgrgid(st.st_gid);
  return std::string(mode) + " " + (pw ? pw->pw_name : std::to_string(st.st_uid)) + ":" +
         (gr ? gr->gr_name : std::to_string(st.st_gid));
}

std::string permission_fix(const std::string& node) {
  (void)node;
  const UdevRuleCheck rule = check_udev_rule();
  const GroupCheck plugdev = check_group("plugdev");
  std::string fix;
  if (!rule.installed) {
    fix += "install the udev rule: `toonforce falcon udev-rule | sudo tee /etc/udev/rules.d/60-novint-falcon.rules`, "
           "then `sudo udevadm control --reload-rules && sudo udevadm trigger` and replug the Falcon; ";
  } else {
    fix += "the udev rule " + rule.path + " is installed; replug the Falcon so it applies; ";
  }
  if (!plugdev.exists) {
    fix +=
        "create the group: `sudo groupadd plugdev` and add yourself: `sudo usermod -aG plugdev $USER`, then log out and in";
  } else if (plugdev.in_session) {
    fix += "you are in group plugdev already";
  } else if (plugdev.listed) {
    fix += "you were added to group plugdev but this session predates it: log out and in (or run `newgrp plugdev`)";
  } else {
    fix += "add yourself to group plugdev: `sudo usermod -aG plugdev $USER`, then log out and in";
  }
  return fix + " (docs/FALCON.md, \"Permissions\")";
}

std::variant<std::unique_ptr<LibusbTransport>, OpenFailure> LibusbTransport::open(std::shared_ptr<UsbContext> context,
                                                                                  const UsbFalcon& falcon) {
  libusb_device_handle* handle = nullptr;
  int r = libusb_open(falcon.device, &handle);
  if (r != LIBUSB_SUCCESS) {
    OpenFailure f;
    f.status = from_libusb(r);
    if (r == LIBUSB_ERROR_ACCESS) {
      const std::string node = describe_node(falcon.node);
      f.problem = "permission denied opening the Novint Falcon at " + falcon.location +
                  (node.empty() ? std::string() : " (the node is " + node + ")");
      f.fix = permission_fix(falcon.node);
    } else if (r == LIBUSB_ERROR_NO_DEVICE) {
      f.problem = "the Novint Falcon at " + falcon.location + " disappeared while opening it";
      f.fix = "check the USB cable and the power supply, then try again";
    } else {
      f.problem = "cannot open the Novint Falcon at " + falcon.location + ": " + libusb_error_name(r);
      f.fix = "unplug and replug it; if it repeats, try another USB port (not a hub)";
    }
    return f;
  }
  // Our own precaution (libnifalcon never detaches, FALCON.md §1): release a kernel driver if one
  // bound itself (ftdi_sio does not know this product id, but a local quirk might).
  (void)libusb_set_auto_detach_kernel_driver(handle, 1);
  r = libusb_claim_interface(handle, kInterface);
  if (r != LIBUSB_SUCCESS) {
    libusb_close(handle);
    OpenFailure f;
    f.status = from_libusb(r);
    if (r == LIBUSB_ERROR_BUSY) {
      f.problem = "the Novint Falcon at " + falcon.location + " is in use by another program";
      f.fix = "close the other program (another toonforce, or anything built on libnifalcon) and try again";
    } else {
      f.problem = "cannot claim interface 0 of the Novint Falcon at " + falcon.location + ": " + libusb_error_name(r);
      f.fix = "unplug and replug it, then try again";
    }
    return f;
  }
  std::unique_ptr<LibusbTransport> t(new LibusbTransport(std::move(context), handle, falcon.location));
  t->node_ = falcon.node;
  libusb_device_descriptor d{};
  if (libusb_get_device_descriptor(falcon.device, &d) == LIBUSB_SUCCESS && d.iSerialNumber != 0) {
    unsigned char serial[128] = {};
    const int n = libusb_get_string_descriptor_ascii(handle, d.iSerialNumber, serial, sizeof serial);
    if (n > 0) t->serial_.assign(reinterpret_cast<const char*>(serial), static_cast<std::size_t>(n));
  }
  t->out_ = libusb_alloc_transfer(0);
  t->in_ = libusb_alloc_transfer(0);
  if (t->out_ == nullptr || t->in_ == nullptr) {
    OpenFailure f;
    f.problem = "out of memory allocating USB transfers for the Falcon at " + falcon.location;
    return f;
  }
  // libusb keeps each open device's usbfs descriptor in its poll set (events POLLOUT): that is
  // the descriptor emergency_write() uses. This context has no other device open.
  if (const libusb_pollfd** fds = libusb_get_pollfds(t->context_->get()); fds != nullptr) {
    for (const libusb_pollfd** p = fds; *p != nullptr; ++p) {
      if ((*p)->events & POLLOUT) t->usbfs_fd_ = (*p)->fd;
    }
    libusb_free_pollfds(fds);
  }
  return t;
}

LibusbTransport::LibusbTransport(std::shared_ptr<UsbContext> context, libusb_device_handle* handle,
                                 std::string location)
    : context_(std::move(context)), handle_(handle), location_(std::move(location)) {}

LibusbTransport::~LibusbTransport() {
  if (!broken_) {
    if (out_ != nullptr) libusb_free_transfer(out_);
    if (in_ != nullptr) libusb_free_transfer(in_);
  }
  (void)libusb_release_interface(handle_, kInterface);
  libusb_close(handle_);
}

TransportStatus LibusbTransport::run(libusb_transfer* transfer) noexcept {
  if (broken_) return TransportStatus::kIoError;
  int completed = 0;
  transfer->user_data = &completed;
  transfer->callback = &mark_completed;
  const int r = libusb_submit_transfer(transfer);
  if (r != LIBUSB_SUCCESS) return from_libusb(r);
  // The transfer's own timeout bounds this wait. The deadlines guard against a transfer that
  // libusb never completes (a device or emulator that ignores the cancellation): cancel it,
  // and if even that does not complete it, abandon it and its buffer rather than spin.
  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  const auto cancel_at = start + std::chrono::milliseconds(transfer->timeout + 500);
  const auto abandon_at = cancel_at + std::chrono::milliseconds(1000);
  bool cancelled = false;
  while (completed == 0) {
    timeval tv{0, 100000};
    const int e = libusb_handle_events_timeout_completed(context_->get(), &tv, &completed);
    if (completed != 0) break;
    const auto now = Clock::now();
    if (!cancelled && (now >= cancel_at || (e < 0 && e != LIBUSB_ERROR_INTERRUPTED))) {
      (void)libusb_cancel_transfer(transfer);
      cancelled = true;
    } else if (cancelled && now >= abandon_at) {
      broken_ = true;
      return TransportStatus::kIoError;
    }
  }
  switch (transfer->status) {
    case LIBUSB_TRANSFER_COMPLETED: return TransportStatus::kOk;
    case LIBUSB_TRANSFER_TIMED_OUT: return TransportStatus::kTimeout;
    case LIBUSB_TRANSFER_NO_DEVICE: return TransportStatus::kNoDevice;
    case LIBUSB_TRANSFER_STALL: return TransportStatus::kStall;
    default: return TransportStatus::kIoError;
  }
}

TransportStatus LibusbTransport::control(std::uint8_t request, std::uint16_t value) noexcept {
  const int r = libusb_control_transfer(handle_, kVendorOut, request, value, 0, nullptr, 0, kControlTimeoutMs);
  return r >= 0 ? TransportStatus::kOk : from_libusb(r);
}

TransportStatus LibusbTransport::write(std::span<const std::uint8_t> data, std::size_t& written,
                                       std::uint32_t timeout_ms) noexcept {
  written = 0;
  const std::size_t n = std::min(data.size(), out_buffer_.size());
  std::memcpy(out_buffer_.data(), data.data(), n);
  libusb_fill_bulk_transfer(out_, handle_, kEndpointOut, out_buffer_.data(), static_cast<int>(n), nullptr, nullptr,
                            timeout_ms);
  const TransportStatus s = run(out_);
  written = static_cast<std::size_t>(std::max(0, out_->actual_length));
  if (s == TransportStatus::kOk && n < data.size()) return TransportStatus::kIoError;  // larger than one call sends
  return s;
}

TransportStatus LibusbTransport::read(std::span<std::uint8_t> data, std::size_t& received,
                                      std::uint32_t timeout_ms) noexcept {
  received = 0;
  const std::size_t n = std::min(data.size(), in_buffer_.size());
  libusb_fill_bulk_transfer(in_, handle_, kEndpointIn, in_buffer_.data(), static_cast<int>(n), nullptr, nullptr,
                            timeout_ms);
  TransportStatus s = run(in_);
  const auto got = static_cast<std::size_t>(std::max(0, in_->actual_length));
  if (s == TransportStatus::kTimeout && got > 0) s = TransportStatus::kOk;  // keep data that did arrive
  if (s == TransportStatus::kOk) {
    std::memcpy(data.data(), in_buffer_.data(), std::min(got, n));
    received = std::min(got, n);
  }
  return s;
}

bool LibusbTransport::emergency_write(std::span<const std::uint8_t> data) noexcept {
  if (usbfs_fd_ < 0 || data.size() > kFrameBytes) return false;
  std::array<std::uint8_t, kFrameBytes> buffer{};
  std::memcpy(buffer.data(), data.data(), data.size());
  usbdevfs_bulktransfer bulk{};
  bulk.ep = kEndpointOut;
  bulk.len = static_cast<unsigned>(data.size());
  bulk.timeout = 20;  // ms: bounded, never indefinite
  bulk.data = buffer.data();
  return ::ioctl(usbfs_fd_, USBDEVFS_BULK, &bulk) == static_cast<int>(data.size());
}

}  // namespace toonforce::falcon
