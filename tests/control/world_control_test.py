#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""The control protocol of a running world (docs/spec/control-protocol.md, "Worlds") from
Python with Debian's python3-websockets, against `toonforce run --device sim --scene
scenes/two_players.toml --view 0 --control`: the welcome names every device and the effects that
act on it; a change of an effect is applied once, on every device; what a running world keeps
(couplings, ball, which devices an effect acts on, its list of effects) is refused with the
reason; the summary and --stats-json count the updates. Exits non-zero if a check fails."""

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
SOURCE = sys.argv[2]
TOKEN = "world-token-0123"
failures = []


def check(ok, what):
    print(("ok    " if ok else "FAIL  ") + what, flush=True)
    if not ok:
        failures.append(what)


async def talk(ws, message):
    await ws.send(json.dumps(message))
    return json.loads(await ws.recv())


async def applied(ws, sequence):
    for _ in range(500):
        if (await talk(ws, {"type": "status"}))["applied"] >= sequence:
            return True
        await asyncio.sleep(0.01)
    return False


async def conversation(url):
    async with websockets.connect(url) as ws:
        welcome = await talk(ws, {"type": "hello", "version": 1, "token": TOKEN})
        check(welcome["type"] == "welcome", "the hello passes")
        devices = welcome.get("scene", {}).get("devices", [])
        check([d["name"] for d in devices] == ["left", "right"], "the welcome names the world's devices")
        check(all(d["effects"] == [{"key": "surface", "number": 1}] for d in devices),
              "... and the effects that act on each (the floor on both)")
        reply = await talk(ws, {"type": "set", "id": "a", "effect": "surface1", "keys": {"stiffness": 2500}})
        check(reply == {"type": "ok", "id": "a", "sequence": 1}, "a change of the floor is taken")
        check(await applied(ws, 1), "... and applied by the world")
        scene = await talk(ws, {"type": "scene"})
        check(scene["scene"]["effects"][0]["params"]["stiffness"] == 2500, "the scene after it has the new stiffness")
        reply = await talk(ws, {"type": "fire", "effect": "surface1", "event": "impact", "value": 0.2})
        check(reply.get("sequence") == 2, "an impact on demand is taken (on every device the floor acts on)")
        check(await applied(ws, 2), "... and applied")
        for message, says, what in [
            ({"type": "set", "effect": "coupling1", "keys": {"stiffness": 400}}, "fixed while it runs",
             "the coupling is fixed while the world runs"),
            ({"type": "set", "effect": "surface1", "keys": {"devices": ["left"]}}, "'devices' is fixed",
             "which devices an effect acts on is fixed"),
            ({"type": "set", "effect": "surface1", "keys": {"stiffnes": 1}}, "stiffnes",
             "a misspelt key is refused, named"),
            ({"type": "add", "kind": "surface", "keys": {"stiffness": 1}}, "list of effects is fixed",
             "add is refused in a world"),
            ({"type": "remove", "effect": "surface1"}, "list of effects is fixed", "remove is refused in a world"),
            ({"type": "load", "toml": "name = \"x\"\n"}, "keeps its devices", "load is refused in a world"),
        ]:
            reply = await talk(ws, message)
            check(reply["type"] == "error" and says in reply["message"], what)
        status = await talk(ws, {"type": "status"})
        check(status["applied"] == 2, "nothing refused reached the world")
        return 2


def main():
    work = tempfile.mkdtemp(prefix="toonforce_world_control_")
    stats = os.path.join(work, "stats.json")
    trace = os.path.join(work, "trace.csv")
    hands = os.path.join(SOURCE, "scenes", "hands")
    world = os.path.join(SOURCE, "scenes", "two_players.toml")
    run = subprocess.Popen([BINARY, "run", "--device", "sim", "--scene", world,
                            "--script", "left=" + os.path.join(hands, "left_push.toml"),
                            "--script", "right=" + os.path.join(hands, "right_push.toml"),
                            "--duration", "3", "--allow-non-rt", "--no-mlock", "--view", "0", "--control",
                            "--control-token", TOKEN, "--control-wait", "--stats-json", stats, "--trace", trace],
                           stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    url = None
    for line in run.stderr:
        print("run: " + line.rstrip(), flush=True)
        m = re.search(r"control: (ws://\S+/control), token (\S+)", line)
        if m:
            url = m.group(1)
        if "waiting for a control client" in line:
            break
    if url is None:
        run.kill()
        print(run.communicate())
        print("FAIL  the world's run printed no control URL")
        return 1
    sent = asyncio.run(conversation(url))
    run.send_signal(signal.SIGTERM)
    try:
        out, err = run.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        run.kill()
        out, err = run.communicate()
        check(False, "one SIGTERM ends the world's run")
    print(out + err)
    check(f"live     {sent} scene update(s) applied (each on every device at once), 0 refused" in out,
          "the summary counts the updates applied")
    with open(stats) as f:
        data = json.load(f)
    check(data.get("updates_applied") == sent and data.get("updates_refused") == 0, "so does --stats-json")
    with open(trace) as f:
        header = f.readline()
    check("left.fz" in header and "right.fz" in header, "the trace is the world's, a column set per device")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
