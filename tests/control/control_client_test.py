#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""The control protocol of live scenes (docs/spec/control-protocol.md) from a client in another
language than C++: Python with Debian's python3-websockets, against `toonforce run --device sim
--view 0 --control`. Each check states what the spec says; the script exits non-zero on the
first that fails."""

import asyncio
import json
import os
import re
import signal
import subprocess
import sys
import tempfile

import websockets

BINARY = sys.argv[1]
TOKEN = "test-token-0123"
SCENE = """name = "control test"
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

failures = []


def check(ok, what):
    print(("ok    " if ok else "FAIL  ") + what, flush=True)
    if not ok:
        failures.append(what)


async def talk(ws, message):
    await ws.send(message if isinstance(message, str) else json.dumps(message))
    return json.loads(await ws.recv())


async def closed(ws, code=1008):
    try:
        await asyncio.wait_for(ws.recv(), 5)
    except websockets.ConnectionClosed as e:
        return e.rcvd is not None and e.rcvd.code == code
    except asyncio.TimeoutError:
        return False
    return False


async def conversation(url):
    # Nothing is taken before a hello with the token.
    async with websockets.connect(url) as ws:
        reply = await talk(ws, {"type": "set", "effect": "surface1", "keys": {"stiffness": 900}})
        check(reply["type"] == "error" and "hello" in reply["message"], "a change before the hello is refused")
        check(await closed(ws), "... and the connection closed (1008)")
    async with websockets.connect(url) as ws:
        reply = await talk(ws, {"type": "hello", "version": 1, "token": "guess"})
        check(reply["type"] == "error" and reply["message"] == "wrong token", "a wrong token is refused")
        check(await closed(ws), "... and the connection closed")
    async with websockets.connect(url) as ws:
        reply = await talk(ws, {"type": "hello", "version": 2, "token": TOKEN})
        check(reply["type"] == "error" and "version" in reply["message"], "another protocol version is refused")
    async with websockets.connect(url) as ws:
        reply = await talk(ws, "{not json")
        check(reply["type"] == "error" and await closed(ws), "a first message that is not JSON: error, closed (1008)")
    async with websockets.connect(url) as ws:
        reply = await talk(ws, '{"type": "hello", "version": 1, "token": "guess", "token": "%s"}' % TOKEN)
        check(reply["type"] == "error" and "twice" in reply["message"] and await closed(ws),
              "a key given twice (a wrong token, then the right one) is refused, closed")

    # Another site's page may not drive the scene.
    try:
        async with websockets.connect(url, origin="http://evil.example") as ws:
            check(False, "a page of another origin is refused (403)")
    except websockets.InvalidStatusCode as e:
        check(e.status_code == 403, "a page of another origin is refused (403)")

    async with websockets.connect(url) as ws:
        welcome = await talk(ws, {"type": "hello", "version": 1, "token": TOKEN, "id": "h"})
        check(welcome["type"] == "welcome" and welcome["version"] == 1 and welcome["id"] == "h",
              "hello with the token: welcome, the id echoed")
        effects = welcome["scene"]["effects"]
        check(len(effects) == 1 and effects[0]["key"] == "surface" and effects[0]["params"]["stiffness"] == 500,
              "the welcome carries the scene")

        sent = 0
        reply = await talk(ws, {"type": "set", "id": 1, "effect": "surface1", "keys": {"stiffness": 800, "point": [0, 0, 0.014]}})
        check(reply == {"type": "ok", "id": 1, "sequence": 1}, "set: ok with the update's sequence")
        sent += 1
        reply = await talk(ws, {"type": "scene"})
        params = reply["scene"]["effects"][0]["params"]
        check(params["stiffness"] == 800 and params["point"] == [0, 0, 0.014] and params["impact"]["recoil_gain"] == 300,
              "the scene after the change: the keys given changed, the others kept")

        reply = await talk(ws, {"type": "set", "id": 2, "effect": "surface1", "keys": {"stifness": 900}})
        check(reply["type"] == "error" and reply["id"] == 2 and "unknown key 'stifness'" in reply["message"]
              and "stiffness" in reply["message"], "a typo: the scene files' message, naming the key")
        reply = await talk(ws, {"type": "set", "effect": "surface1", "keys": {"stiffness": -1}})
        check(reply["type"] == "error" and "must be > 0" in reply["message"], "a value out of range is refused")
        reply = await talk(ws, {"type": "add", "kind": "surface",
                                "keys": {"point": [0, 0, 0], "normal": [0, 0, 1], "stiffness": 100}})
        check(reply["type"] == "error" and "list of effects" in reply["message"],
              "run: a change of the list of effects is refused (the trace's columns)")
        reply = await talk(ws, {"type": "fire", "effect": "surface1", "event": "impact", "value": 0.3})
        check(reply["type"] == "ok" and reply["sequence"] == 2, "fire an impact: ok")
        sent += 1
        reply = await talk(ws, {"type": "fire", "effect": "surface1", "event": "look_down"})
        check(reply["type"] == "error", "a surface has no look_down")
        reply = await talk(ws, "{not json")
        check(reply["type"] == "error" and reply["message"] == "not JSON", "not JSON: an error reply")
        reply = await talk(ws, {"type": "teleport"})
        check(reply["type"] == "error" and "unknown type" in reply["message"], "an unknown type: an error reply")
        reply = await talk(ws, {"type": "remove", "effect": "surface1", "force": True})
        check(reply["type"] == "error" and "no field 'force'" in reply["message"],
              "an unknown field is refused, not ignored")
        reply = await talk(ws, {"type": "load", "toml": "[device]\nmax_force = 50\n" + SCENE})
        check(reply["type"] == "error" and "[device]" in reply["message"], "a scene with other limits is refused")
        reply = await talk(ws, {"type": "load", "name": "softer.toml", "toml": SCENE.replace("500", "300")})
        check(reply["type"] == "ok", "load a scene with the same effects: ok")
        sent += 1

        # The loop applies them (one a tick).
        applied = 0
        for _ in range(200):
            applied = (await talk(ws, {"type": "status"}))["applied"]
            if applied == sent:
                break
            await asyncio.sleep(0.01)
        check(applied == sent, f"status: the loop applied all {sent} updates")

        # Rate limit: a flood is answered, not obeyed. 1000 at once: none would be refused only
        # if the server took over 4.75 s to read them (50 + 200/s), far slower than any machine.
        flood = 1000
        for _ in range(flood):
            await ws.send(json.dumps({"type": "status"}))
        replies = [json.loads(await ws.recv()) for _ in range(flood)]
        limited = sum(1 for r in replies if r["type"] == "error" and "rate limit" in r["message"])
        check(limited > 0 and all(r["type"] in ("status", "error") for r in replies),
              f"rate limit: {limited} of {flood} messages sent at once refused, every one answered")

    async with websockets.connect(url) as ws:
        welcome = await talk(ws, {"type": "hello", "version": 1, "token": TOKEN, "id": None})
        check(welcome["type"] == "welcome" and "id" in welcome and welcome["id"] is None, '"id": null is echoed')
        reply = await talk(ws, {"type": "status", "id": "x" * 129})
        check(reply["type"] == "error" and "id" not in reply, "an id longer than 128 bytes is refused, not echoed")
        reply = await talk(ws, {"type": "set", "effect": "surface1", "keys": {"a": json.loads("[" * 40 + "]" * 40)}})
        check(reply["type"] == "error" and "at most 32 levels" in reply["message"], "nesting deeper than 32 is refused")
        await ws.send(json.dumps({"type": "status"}).encode())
        reply = json.loads(await ws.recv())
        check(reply["type"] == "error" and "binary" in reply["message"] and await closed(ws, 1003),
              "a binary message: error, closed (1003)")
    return sent


async def wrong_hello(url):
    async with websockets.connect(url) as ws:
        reply = await talk(ws, {"type": "hello", "version": 1, "token": "not-it"})
        return reply["type"] == "error"


def control_wait(work, scene):
    """--control-wait: the loop does not start (no trace, no device) until a hello passes; a wrong
    token is not one; Ctrl-C while waiting ends the run unstarted, exit status 2."""
    trace = os.path.join(work, "wait-trace.csv")
    run = subprocess.Popen([BINARY, "run", "--device", "sim", "--scene", scene, "--allow-non-rt", "--no-mlock",
                            "--duration", "0.2", "--view", "0", "--control", "--control-token", TOKEN,
                            "--control-wait", "--trace", trace],
                           stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    url = None
    for line in run.stderr:
        print("run: " + line.rstrip(), flush=True)
        m = re.search(r"control: (ws://\S+/control), token", line)
        if m:
            url = m.group(1)
        if "waiting for a control client" in line:
            break
    check(url is not None, "--control-wait: the run says it waits for a control client")
    if url is not None:
        check(asyncio.run(wrong_hello(url)), "--control-wait: a wrong token is refused")
    # Four times the run's duration: had the loop started, its trace would be written by now.
    try:
        run.wait(timeout=0.8)
    except subprocess.TimeoutExpired:
        pass
    check(run.poll() is None and not os.path.exists(trace), "--control-wait: the loop has not started (no trace)")
    run.send_signal(signal.SIGINT)
    out, err = run.communicate(timeout=30)
    print(out + err)
    check(run.returncode == 2 and "the loop did not start" in err,
          "--control-wait: Ctrl-C while waiting ends the run unstarted, exit status 2")


REWRITTEN = """name = "rewritten"
[[surface]]
point = [0, 0, 0.015]
normal = [0, 0, 1]
stiffness = 200
[[surface]]
point = [0, 0, -0.015]
normal = [0, 0, 1]
stiffness = 200
"""


async def hello_and_one_change(url):
    async with websockets.connect(url) as ws:
        welcome = await talk(ws, {"type": "hello", "version": 1, "token": TOKEN})
        effects = welcome["scene"]["effects"] if welcome["type"] == "welcome" else []
        check(len(effects) == 1 and effects[0]["params"]["stiffness"] == 500,
              "scene read once: the editor has the scene as the run read it, not as rewritten since")
        reply = await talk(ws, {"type": "set", "id": 1, "effect": "surface1", "keys": {"stiffness": 800}})
        check(reply == {"type": "ok", "id": 1, "sequence": 1}, "scene read once: the live change is taken")
        applied = 0
        for _ in range(300):
            applied = (await talk(ws, {"type": "status"}))["applied"]
            if applied == 1:
                break
            await asyncio.sleep(0.01)
        check(applied == 1, "scene read once: the loop applied the change")


def scene_read_once(work):
    """The scene file is read once, when the run starts: rewritten on disk (another list of
    effects) while the run waits for its control client, the loop still renders the scene it
    read, before and after a live change, and the editor edits that same scene."""
    scene = os.path.join(work, "once.toml")
    trace = os.path.join(work, "once-trace.csv")
    with open(scene, "w") as f:
        f.write(SCENE)
    run = subprocess.Popen([BINARY, "run", "--device", "sim", "--scene", scene, "--allow-non-rt", "--no-mlock",
                            "--duration", "0.3", "--view", "0", "--control", "--control-token", TOKEN,
                            "--control-wait", "--trace", trace],
                           stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    url = None
    for line in run.stderr:
        print("run: " + line.rstrip(), flush=True)
        m = re.search(r"control: (ws://\S+/control), token", line)
        if m:
            url = m.group(1)
        if "waiting for a control client" in line:
            break
    check(url is not None, "scene read once: the run waits for a control client")
    if url is None:
        run.kill()
        run.communicate()
        return
    with open(scene, "w") as f:
        f.write(REWRITTEN)
    asyncio.run(hello_and_one_change(url))
    # The loop took the change: stop it (after its --duration the page would keep serving).
    run.send_signal(signal.SIGTERM)
    try:
        out, err = run.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        run.kill()
        out, err = run.communicate()
    print(out + err)
    check(run.returncode == 0, "scene read once: the run ends with status 0")
    check(f"scene    control test ({scene}): 1 surface(s), 0 cliff(s)" in out,
          "scene read once: the loop rendered the scene as read at the start (its name, one surface)")
    with open(trace) as f:
        header = f.readline()
    check("surface1" in header and "surface2" not in header,
          "scene read once: the trace's effect columns are the starting scene's")


def main():
    work = tempfile.mkdtemp(prefix="toonforce_control_")
    scene = os.path.join(work, "scene.toml")
    stats = os.path.join(work, "stats.json")
    with open(scene, "w") as f:
        f.write(SCENE)
    control_wait(work, scene)
    scene_read_once(work)
    run = subprocess.Popen([BINARY, "run", "--device", "sim", "--scene", scene, "--allow-non-rt", "--no-mlock",
                            "--view", "0", "--control", "--control-token", TOKEN, "--stats-json", stats,
                            "--trace", os.path.join(work, "trace.csv")],
                           stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    url = None
    for line in run.stderr:
        print("run: " + line.rstrip(), flush=True)
        m = re.search(r"control: (ws://\S+/control), token (\S+)", line)
        if m:
            url = m.group(1)
            check(m.group(2) == TOKEN, "the token printed is the one given")
            break
    if url is None:
        run.kill()
        print("FAIL  the run printed no control URL")
        return 1
    sent = asyncio.run(conversation(url))
    # One SIGTERM ends the run and the command, --view or not (a run stopped from outside does
    # not keep serving its page: docs/VIEWER.md).
    run.send_signal(signal.SIGTERM)
    try:
        out, err = run.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        run.kill()
        out, err = run.communicate()
        check(False, "one SIGTERM ends `run --view` (it was still serving 60 s later)")
    print(out + err)
    check("the page closes with it" in err, "it says why the page closes")
    check(f"live     {sent} scene update(s) applied" in out, "the summary counts the updates applied")
    with open(stats) as f:
        check(json.load(f)["updates_applied"] == sent, "so does --stats-json")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
