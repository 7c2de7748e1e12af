#!/bin/sh
# Runs a test binary under umockdev-wrapper (LD_PRELOAD of libumockdev-preload), so the
# libusb, hidapi and sysfs calls inside see the devices the test emulates. Under ASan the
# sanitizer runtime is then not first in the preload list, which is harmless here: allow it
# (shared/reference/test-environment.md §2d), keeping whatever else ASAN_OPTIONS says.
export ASAN_OPTIONS="${ASAN_OPTIONS:+$ASAN_OPTIONS:}verify_asan_link_order=0"
exec umockdev-wrapper "$@"
