# SPDX-License-Identifier: Apache-2.0
"""A client of the control protocol of live scenes (docs/spec/control-protocol.md), for a
`toonforce run ... --view PORT --control` in another process: change the running scene from a
script or a Jupyter notebook.

    from toonforce.control import Client
    with Client("ws://127.0.0.1:8765/control", token="T") as run:
        sequence = run.set("surface1", stiffness=800.0)       # N/m, the scene file's keys
        run.fire("surface1", "impact", 0.3)                   # an impact at 0.3 m/s
        run.wait_applied(sequence)                            # the loop has applied it

`Client` is synchronous and works where an event loop already runs (Jupyter): it talks on an
event loop of its own, in a thread. `AsyncClient` is the same for asyncio code. Both keep the
spec's rules on the client side, so a refusal is the run's verdict on the change, not a slip
of the client: every message gets an `id` and its reply is matched to it; a message over
64 KiB or with a number JSON cannot carry (NaN, infinity) is refused before it is sent; and
messages are paced to the server's rate limit (a bucket of 50, refilled at 200 a second), so
a burst waits instead of being refused. A change refused because the loop has not yet taken
the changes before it (its mailbox holds a few; it takes one a tick: "try again") is sent again
until it passes, for at most `change_timeout_s` (then `TimeoutError`). Each other refusal raises
`ControlError` with the server's message; `RateLimited` if the server refused one for its rate
anyway.

Only Debian's python3-websockets (10.4: asyncio API) is used.
"""

from __future__ import annotations

import asyncio
import itertools
import json
import os
import re
import threading
import time
from typing import Any, Dict, Optional, Tuple

import websockets

__all__ = ["AsyncClient", "Client", "ControlError", "RateLimited", "ProtocolError", "parse_announcement",
           "PROTOCOL_VERSION", "MAX_MESSAGE_BYTES", "RATE_BUCKET", "RATE_PER_S"]

PROTOCOL_VERSION = 1
MAX_MESSAGE_BYTES = 64 * 1024  # larger: the server closes the connection (1009)
RATE_BUCKET = 50  # messages per connection at once ...
RATE_PER_S = 200.0  # ... refilled at this rate

_ANNOUNCEMENT = re.compile(r"control: (ws://\S+/control), token (\S+)")
# The live-scene editor's refusal while the loop's mailbox is full (docs/spec/live-scenes.md
# section 2): nothing changed, and the same change passes once the loop has taken one.
MAILBOX_FULL = re.compile(r"not applied: .*\btry again\s*$")


class ControlError(Exception):
    """The run refused a message: `message` is its reason (for a scene key, the scene files'
    message naming the key), `reply` the whole reply."""

    def __init__(self, message: str, reply: Optional[Dict[str, Any]] = None):
        super().__init__(message)
        self.message = message
        self.reply = reply or {}


class RateLimited(ControlError):
    """The server refused a message for its rate (nothing changed); send it again later."""


class ProtocolError(Exception):
    """The server broke the protocol (a reply out of order, not JSON) or closed the connection."""


def parse_announcement(text: str) -> Tuple[str, str]:
    """The control URL and token from what `toonforce run --control` prints on standard error
    ("control: ws://127.0.0.1:8765/control, token 3f0c..."): (url, token)."""
    match = _ANNOUNCEMENT.search(text)
    if match is None:
        raise ValueError("no 'control: ws://.../control, token ...' line in the text")
    return match.group(1), match.group(2)


class _Pacer:
    """The server's token bucket, mirrored: how long to wait before the next message."""

    def __init__(self, bucket: int = RATE_BUCKET, per_s: float = RATE_PER_S):
        # One message of margin: the server's bucket started when it accepted the connection.
        self._capacity = float(bucket - 1)
        self._per_s = per_s
        self._tokens = self._capacity
        self._last = time.monotonic()

    def delay(self) -> float:
        now = time.monotonic()
        self._tokens = min(self._capacity, self._tokens + (now - self._last) * self._per_s)
        self._last = now
        if self._tokens >= 1.0:
            self._tokens -= 1.0
            return 0.0
        wait = (1.0 - self._tokens) / self._per_s
        self._tokens = 0.0
        self._last = now + wait
        return wait


def _encode(message: Dict[str, Any]) -> str:
    try:
        text = json.dumps(message, allow_nan=False, separators=(",", ":"))
    except ValueError as e:  # NaN or infinity: JSON has no such numbers
        raise ValueError(f"cannot send {message.get('type')!r}: {e} (JSON numbers are finite)") from None
    if len(text.encode("utf-8")) > MAX_MESSAGE_BYTES:
        raise ValueError(f"cannot send {message.get('type')!r}: {len(text.encode('utf-8'))} bytes, "
                         f"over the protocol's {MAX_MESSAGE_BYTES}")
    return text


def _keys(keys: Optional[Dict[str, Any]], named: Dict[str, Any]) -> Dict[str, Any]:
    merged = dict(keys or {})
    overlap = set(merged) & set(named)
    if overlap:
        raise ValueError(f"key(s) given twice: {', '.join(sorted(overlap))}")
    merged.update(named)
    if not merged:
        raise ValueError("no keys to set")
    return merged


class AsyncClient:
    """The control protocol for asyncio code. `async with AsyncClient(url, token) as run:`;
    the token defaults to the environment's TOONFORCE_CONTROL_TOKEN, as the run's does."""

    def __init__(self, url: str, token: Optional[str] = None, *, open_timeout_s: float = 10.0,
                 reply_timeout_s: float = 10.0, change_timeout_s: float = 5.0):
        self.url = url
        self.change_timeout_s = change_timeout_s
        self.token = token if token is not None else os.environ.get("TOONFORCE_CONTROL_TOKEN", "")
        self.open_timeout_s = open_timeout_s
        self.reply_timeout_s = reply_timeout_s
        self.scene: Dict[str, Any] = {}
        """The scene the welcome carried (effects with key, number, params, values)."""
        self._ws = None
        self._ids = itertools.count(1)
        self._pacer = _Pacer()

    async def __aenter__(self) -> "AsyncClient":
        await self.connect()
        return self

    async def __aexit__(self, *exc) -> None:
        await self.close()

    async def connect(self) -> Dict[str, Any]:
        """Opens the connection and says hello; the welcome (its scene is also `self.scene`)."""
        # No Origin header (a program's, not a page's); no compression, as the server offers none.
        self._ws = await websockets.connect(self.url, open_timeout=self.open_timeout_s, compression=None,
                                            max_size=None)
        welcome = await self.request({"type": "hello", "version": PROTOCOL_VERSION, "token": self.token})
        if welcome.get("type") != "welcome":
            raise ProtocolError(f"expected a welcome, got {welcome!r}")
        self.scene = welcome.get("scene", {})
        return welcome

    async def close(self) -> None:
        if self._ws is not None:
            await self._ws.close()
            self._ws = None

    async def request(self, message: Dict[str, Any]) -> Dict[str, Any]:
        """Sends one message with a fresh id and returns its reply; a refusal raises
        ControlError (RateLimited for the rate). A change refused for a full mailbox ("try
        again") is sent again until it passes, for at most `change_timeout_s` (TimeoutError)."""
        deadline = None
        pause_s = 0.001  # a tick at 1 kHz: the loop takes one change a tick
        while True:
            try:
                return await self._request_once(message)
            except ControlError as e:
                if isinstance(e, RateLimited) or not MAILBOX_FULL.search(e.message):
                    raise
                now = time.monotonic()
                if deadline is None:
                    deadline = now + self.change_timeout_s
                elif now >= deadline:
                    raise TimeoutError(f"{e.message.rstrip()}: still refused after {self.change_timeout_s:g} s "
                                       "(is the run's loop running?)") from None
                await asyncio.sleep(pause_s)
                pause_s = min(2.0 * pause_s, 0.02)

    async def _request_once(self, message: Dict[str, Any]) -> Dict[str, Any]:
        if self._ws is None:
            raise ProtocolError("not connected")
        ident = next(self._ids)
        text = _encode({**message, "id": ident})
        wait = self._pacer.delay()
        if wait > 0:
            await asyncio.sleep(wait)
        try:
            await self._ws.send(text)
            raw = await asyncio.wait_for(self._ws.recv(), self.reply_timeout_s)
        except websockets.ConnectionClosed as e:
            code = e.rcvd.code if e.rcvd is not None else None
            reason = e.rcvd.reason if e.rcvd is not None else ""
            raise ProtocolError(f"the run closed the connection (code {code}{': ' + reason if reason else ''})") from None
        except asyncio.TimeoutError:
            raise ProtocolError(f"no reply to {message.get('type')!r} within {self.reply_timeout_s:g} s") from None
        try:
            reply = json.loads(raw)
        except (TypeError, ValueError):
            raise ProtocolError(f"a reply that is not JSON: {raw[:64]!r}") from None
        if reply.get("type") == "error":
            reason = reply.get("message", "")
            error = RateLimited if "rate limit" in reason else ControlError
            raise error(reason, reply)
        if reply.get("id") != ident:
            raise ProtocolError(f"reply {reply.get('id')!r} to message {ident}: out of order")
        return reply

    async def set(self, effect: str, keys: Optional[Dict[str, Any]] = None, **named: Any) -> int:
        """Replaces the effect's keys given (a dict for a sub-table merges key by key), checked
        as a scene file's; the change's sequence number."""
        reply = await self.request({"type": "set", "effect": effect, "keys": _keys(keys, named)})
        return int(reply["sequence"])

    async def fire(self, effect: str, event: str, value: float = 0.0) -> int:
        """A one-shot event ("impact" with its speed in m/s, "look_down"); its sequence."""
        reply = await self.request({"type": "fire", "effect": effect, "event": event, "value": float(value)})
        return int(reply["sequence"])

    async def load(self, toml: str, name: Optional[str] = None) -> int:
        """Another scene (a whole scene file's text); its sequence."""
        message: Dict[str, Any] = {"type": "load", "toml": toml}
        if name is not None:
            message["name"] = name
        reply = await self.request(message)
        return int(reply["sequence"])

    async def add(self, kind: str, keys: Optional[Dict[str, Any]] = None, **named: Any) -> int:
        """A new effect ("surface", "cliff"; `toonforce run` refuses it: its trace's columns)."""
        reply = await self.request({"type": "add", "kind": kind, "keys": _keys(keys, named)})
        return int(reply["sequence"])

    async def remove(self, effect: str) -> int:
        """Removes an effect (`toonforce run` refuses it too)."""
        reply = await self.request({"type": "remove", "effect": effect})
        return int(reply["sequence"])

    async def applied(self) -> int:
        """How many changes the loop has applied."""
        return int((await self.request({"type": "status"}))["applied"])

    async def current_scene(self) -> Dict[str, Any]:
        """The scene after the changes sent."""
        return (await self.request({"type": "scene"}))["scene"]

    async def wait_applied(self, sequence: int, timeout_s: float = 5.0, poll_s: float = 0.005) -> int:
        """Waits until the loop has applied change `sequence` (it applies one a tick)."""
        deadline = time.monotonic() + timeout_s
        while True:
            applied = await self.applied()
            if applied >= sequence:
                return applied
            if time.monotonic() >= deadline:
                raise TimeoutError(f"change {sequence} not applied within {timeout_s:g} s (applied: {applied})")
            await asyncio.sleep(poll_s)


class Client:
    """The control protocol, synchronous: usable from a plain script and from Jupyter, where an
    event loop already runs. `with Client(url, token) as run:`. Each method is AsyncClient's,
    run on an event loop in a thread of its own."""

    def __init__(self, url: str, token: Optional[str] = None, **options: Any):
        self._client = AsyncClient(url, token, **options)
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, name="toonforce.control", daemon=True)
        self._thread.start()
        try:
            self._call(self._client.connect())
        except BaseException:
            self._stop_loop()
            raise

    @property
    def scene(self) -> Dict[str, Any]:
        """The scene the welcome carried."""
        return self._client.scene

    def _call(self, coroutine):
        return asyncio.run_coroutine_threadsafe(coroutine, self._loop).result()

    def _stop_loop(self) -> None:
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join()
        self._loop.close()

    def close(self) -> None:
        if self._loop.is_closed():
            return
        try:
            self._call(self._client.close())
        finally:
            self._stop_loop()

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def request(self, message: Dict[str, Any]) -> Dict[str, Any]:
        return self._call(self._client.request(message))

    def set(self, effect: str, keys: Optional[Dict[str, Any]] = None, **named: Any) -> int:
        return self._call(self._client.set(effect, keys, **named))

    def fire(self, effect: str, event: str, value: float = 0.0) -> int:
        return self._call(self._client.fire(effect, event, value))

    def load(self, toml: str, name: Optional[str] = None) -> int:
        return self._call(self._client.load(toml, name))

    def add(self, kind: str, keys: Optional[Dict[str, Any]] = None, **named: Any) -> int:
        return self._call(self._client.add(kind, keys, **named))

    def remove(self, effect: str) -> int:
        return self._call(self._client.remove(effect))

    def applied(self) -> int:
        return self._call(self._client.applied())

    def current_scene(self) -> Dict[str, Any]:
        return self._call(self._client.current_scene())

    def wait_applied(self, sequence: int, timeout_s: float = 5.0) -> int:
        return self._call(self._client.wait_applied(sequence, timeout_s))

    for _name in ("request", "set", "fire", "load", "add", "remove", "applied", "current_scene", "wait_applied"):
        locals()[_name].__doc__ = getattr(AsyncClient, _name).__doc__
    del _name
