# SPDX-License-Identifier: Apache-2.0
"""toonforce.control against a real `toonforce run --device sim --view 0 --control` (what the
spec says a run does with each message) and against a stand-in server (what the client must
do when a server misbehaves: a reply out of order, a refusal for the rate).

The binary is TOONFORCE_BINARY (CTest sets it)."""

import asyncio
import json
import math
import os
import subprocess
import threading
import time

import pytest
import websockets

from toonforce.control import (MAX_MESSAGE_BYTES, AsyncClient, Client, ControlError, ProtocolError, RateLimited,
                               parse_announcement)

BINARY = os.environ.get("TOONFORCE_BINARY", "toonforce")
TOKEN = "python-control-test"
SCENE = """name = "python control test"
[[surface]]
point = [0, 0, 0.015]
normal = [0, 0, 1]
stiffness = 500
[surface.impact]
recoil_gain = 300
oscillation_gain = 900
duration = 0.1
frequency = 30
"""


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A run on the simulated device with the control protocol; (url, token). Ended with SIGTERM
    (after Ctrl-C a run with --view goes on serving its recording; a stop from outside ends it)."""
    scene = tmp_path_factory.mktemp("control") / "scene.toml"
    scene.write_text(SCENE)
    process = subprocess.Popen(
        [BINARY, "run", "--device", "sim", "--scene", str(scene), "--duration", "600", "--view", "0", "--control",
         "--control-token", TOKEN, "--allow-non-rt", "--no-mlock"],
        stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    seen = []
    url = None
    deadline = time.monotonic() + 60
    while url is None and time.monotonic() < deadline:
        line = process.stderr.readline()
        if not line:
            break
        seen.append(line)
        try:
            url, token = parse_announcement(line)
        except ValueError:
            continue
    if url is None:
        process.kill()
        process.wait()
    assert url is not None, "the run never announced its control socket:\n" + "".join(seen)
    assert token == TOKEN
    # Keep reading its standard error so that it never blocks on a full pipe.
    drain = threading.Thread(target=lambda: [seen.append(l) for l in process.stderr], daemon=True)
    drain.start()
    try:
        yield url, token
        process.terminate()
        assert process.wait(timeout=30) == 0, "".join(seen)
    finally:
        if process.poll() is None:  # never leave a run behind, whatever failed
            process.kill()
            process.wait()
        drain.join(timeout=5)


def test_the_announcement_line_gives_url_and_token():
    assert parse_announcement("viewer: http://127.0.0.1:9/\ncontrol: ws://127.0.0.1:8765/control, token 3f0c\n") == (
        "ws://127.0.0.1:8765/control", "3f0c")
    with pytest.raises(ValueError):
        parse_announcement("viewer: http://127.0.0.1:9/")


def test_a_change_is_applied_by_the_loop_and_the_scene_shows_it(run):
    url, token = run
    with Client(url, token) as control:
        assert control.scene["effects"][0]["params"]["stiffness"] == 500
        sequence = control.set("surface1", stiffness=800.0, point=[0, 0, 0.014])
        assert control.wait_applied(sequence) >= sequence
        params = control.current_scene()["effects"][0]["params"]
        assert params["stiffness"] == 800 and params["point"] == [0, 0, 0.014]
        assert params["impact"]["recoil_gain"] == 300, "keys not given are kept"
        impact = control.fire("surface1", "impact", 0.3)
        assert impact == sequence + 1
        control.wait_applied(impact)


def test_a_refused_change_raises_with_the_scene_files_message_and_changes_nothing(run):
    url, token = run
    with Client(url, token) as control:
        before = control.current_scene()
        with pytest.raises(ControlError) as refused:
            control.set("surface1", stifness=900)
        assert "unknown key 'stifness'" in refused.value.message and "stiffness" in refused.value.message
        with pytest.raises(ControlError) as refused:
            control.fire("surface1", "impact", 1e200)  # its peak force is past what a double can square
        assert "impact" in refused.value.message  # the speed's range, named
        with pytest.raises(ControlError):
            control.fire("surface1", "look_down")
        assert control.current_scene() == before
        # The connection is still good after refusals: each got its reply, in order.
        assert control.applied() >= 0


def test_what_json_cannot_carry_or_the_server_would_not_read_is_refused_before_it_is_sent(run):
    url, token = run
    with Client(url, token) as control:
        with pytest.raises(ValueError, match="finite"):
            control.set("surface1", stiffness=math.nan)
        with pytest.raises(ValueError, match=str(MAX_MESSAGE_BYTES)):
            control.load("#" * MAX_MESSAGE_BYTES)
        with pytest.raises(ValueError, match="twice"):
            control.set("surface1", {"stiffness": 1.0}, stiffness=2.0)
        before = control.applied()
        assert control.current_scene()["effects"][0]["key"] == "surface", "the connection was not closed"
        assert control.applied() == before


def test_a_burst_is_paced_to_the_servers_rate_limit_not_refused(run):
    url, token = run
    with Client(url, token) as control:
        started = time.monotonic()
        for _ in range(150):  # three times the server's bucket of 50
            control.applied()
        elapsed = time.monotonic() - started
    # 150 messages through a bucket of 50 refilled at 200/s take at least (150 - 49) / 200 s.
    assert elapsed >= (150 - 49) / 200.0 * 0.9


def test_the_sync_client_works_inside_a_running_event_loop_as_in_jupyter(run):
    url, token = run

    async def notebook_cell():
        with Client(url, token) as control:
            return control.applied()

    assert asyncio.run(notebook_cell()) >= 0


def test_the_async_client(run):
    url, token = run

    async def script():
        async with AsyncClient(url, token) as control:
            sequence = await control.set("surface1", stiffness=650.0)
            await control.wait_applied(sequence)
            return (await control.current_scene())["effects"][0]["params"]["stiffness"]

    assert asyncio.run(script()) == 650


def test_a_wrong_token_is_refused_at_the_hello(run):
    url, _ = run
    with pytest.raises(ControlError, match="wrong token"):
        Client(url, "not the token")


# ---- a stand-in server: what the client does when a server misbehaves ----------------------


class StandIn:
    """A WebSocket server on a thread: welcome, then `answer(message) -> reply dict`."""

    def __init__(self, answer):
        self.answer = answer
        self.loop = asyncio.new_event_loop()
        ready = threading.Event()

        async def handler(ws, path=None):
            async for text in ws:
                message = json.loads(text)
                if message["type"] == "hello":
                    reply = {"type": "welcome", "version": 1, "applied": 0, "scene": {"effects": []},
                             "id": message["id"]}
                else:
                    reply = self.answer(message)
                await ws.send(json.dumps(reply))

        async def start():
            self.server = await websockets.serve(handler, "127.0.0.1", 0)
            self.port = self.server.sockets[0].getsockname()[1]
            ready.set()

        self.thread = threading.Thread(target=self.loop.run_forever, daemon=True)
        self.thread.start()
        asyncio.run_coroutine_threadsafe(start(), self.loop)
        ready.wait(10)

    def close(self):
        async def stop():
            self.server.close()
            await self.server.wait_closed()

        asyncio.run_coroutine_threadsafe(stop(), self.loop).result(10)
        self.loop.call_soon_threadsafe(self.loop.stop)
        self.thread.join(10)


def test_a_reply_to_another_message_is_a_protocol_error():
    server = StandIn(lambda m: {"type": "status", "applied": 0, "id": m["id"] + 1})
    try:
        with Client(f"ws://127.0.0.1:{server.port}/control", "t") as control:
            with pytest.raises(ProtocolError, match="out of order"):
                control.applied()
    finally:
        server.close()


def test_a_refusal_for_the_rate_is_rate_limited():
    server = StandIn(lambda m: {"type": "error", "message": "rate limit: at most 200 messages a second",
                                "id": m["id"]})
    try:
        with Client(f"ws://127.0.0.1:{server.port}/control", "t") as control:
            with pytest.raises(RateLimited):
                control.set("surface1", stiffness=1.0)
    finally:
        server.close()
