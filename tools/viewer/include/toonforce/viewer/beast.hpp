// SPDX-License-Identifier: Apache-2.0
#pragma once
/// Boost.Beast and Boost.Asio, included in one place so that every file that uses them (the
/// server and its tests) sees the same configuration and the same warning exceptions.
///
/// Two false positives of g++ 12 inside Boost 1.74 once inlined at -O2/-O3: Beast's HTTP parser
/// trips -Wmaybe-uninitialized (boost::optional<std::size_t> content_length), and Asio's
/// scheduler trips -Wnull-dereference (this_thread in compensating_work_started(), non-null
/// whenever it is called from a running io_context). g++ only: clang has no
/// -Wmaybe-uninitialized and would warn about the unknown option.

#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wnull-dereference"
#endif
#include <boost/asio.hpp>
#include <boost/beast/core.hpp>
#include <boost/beast/http.hpp>
#include <boost/beast/websocket.hpp>
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif
