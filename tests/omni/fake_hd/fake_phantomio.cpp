// SPDX-License-Identifier: Apache-2.0
// Stands in for the Touch Device Driver's libPhantomIOLib42.so, which the real libHD.so needs
// (OMNI.md §2.1). A fake libHD linked against it, with this library left where the dynamic
// loader does not look, reproduces "libHD is there but a dependency is missing".
extern "C" __attribute__((visibility("default"))) int tf_fake_phantomio_present() { return 1; }
