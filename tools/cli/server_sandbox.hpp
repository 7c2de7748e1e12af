// SPDX-License-Identifier: Apache-2.0
#pragma once
// The seccomp filter of `run --view`'s server process (server_process.hpp; docs/DEPLOY.md
// section 6). That process parses whatever the network sends; if a parser bug hands it to an
// attacker, the filter leaves it what serving sockets it already holds needs and nothing else:
// no open, no new socket, no connect or bind, no exec, no ptrace, no signal to another process.
// A call outside the list kills the whole process (SIGSYS): the loop goes on without its viewer.
// In a library of its own so that a test can install it in a child of its own and show it acts.
#include <string>

namespace toonforce::cli {

/// Installs the filter on every thread of the calling process (SCMP_FLTATR_CTL_TSYNC) and on
/// the threads it starts later; sets no_new_privs. Call once the server listens, before it
/// serves. Empty on success, else why not (the filter is then not installed).
std::string install_server_filter();

}  // namespace toonforce::cli
