// SPDX-License-Identifier: Apache-2.0
// toonforce-dds's check of a control message from DDS before it is forwarded as WebSocket
// text (tools/dds/state_bridge.hpp, utf8): it must refuse exactly what the run's control server
// would close the connection on, which is Boost.Beast's own UTF-8 check. A message it passed
// that Beast refuses would end the relay for every later message; one it refused that Beast
// takes would be a message lost. Any input where the two differ aborts.
#include <boost/beast/websocket/detail/utf8_checker.hpp>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "toonforce/dds/state_bridge.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const bool ours = toonforce::dds::utf8(text);
  const bool beasts = boost::beast::websocket::detail::check_utf8(text.data(), text.size());
  if (ours != beasts) std::abort();
  return 0;
}
