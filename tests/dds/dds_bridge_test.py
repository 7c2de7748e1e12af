#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""toonforce-dds across two hosts made here (docs/DDS.md): two network namespaces joined by a
veth pair, made and removed by this test, on addresses inside them only. In the first, `toonforce
run --device sim` of the two-player world with `--view`, and toonforce-dds reading its viewer; in
the second, a DDS reader (tests/dds/dds_echo.cpp) as a ROS 2 node on another machine would be.
Checks: the publications it discovers have ROS 2's topic names (rt/toonforce/NAME/...) and type
names (geometry_msgs::msg::dds_::PoseStamped_, ...) with best-effort reliability; every pose and
wrench it receives is a row of the run's trace (the same device, the same tick's values); a
world's poses are in the world frame; control messages sent over DDS reach the run's control
protocol and their replies come back (a refused one, one that is not JSON, one the bridge
refuses as not UTF-8, and the one after it); a bridge killed without a word is seen gone on the
other host through its writers' liveliness. Needs root (namespaces); exits 77 (skipped) without."""

import csv
import json
import os
import re
import signal
import subprocess
import sys
import tempfile

TOONFORCE, BRIDGE, ECHO, SOURCE = sys.argv[1:5]
TOKEN = "dds-test-token"
failures = []


def check(ok, what):
    print(("ok    " if ok else "FAIL  ") + what, flush=True)
    if not ok:
        failures.append(what)


def ip(*args):
    subprocess.run(["ip", *args], check=True)


def make_hosts(a, b):
    ip("netns", "add", a)
    ip("netns", "add", b)
    end_a, end_b = f"tfd{os.getpid() % 100000}", f"tfe{os.getpid() % 100000}"  # interface names: 15 bytes at most
    ip("link", "add", end_a, "type", "veth", "peer", "name", end_b)
    ip("link", "set", end_a, "netns", a)
    ip("link", "set", end_b, "netns", b)
    for ns, name, addr in [(a, end_a, "10.213.7.1/24"), (b, end_b, "10.213.7.2/24")]:
        ip("-n", ns, "addr", "add", addr, "dev", name)
        ip("-n", ns, "link", "set", name, "up")
        ip("-n", ns, "link", "set", "lo", "up")


def main():
    if os.geteuid() != 0 or subprocess.run(["ip", "netns", "list"], capture_output=True).returncode != 0:
        print("skipped: needs root and `ip netns` (network namespaces) to make its two hosts")
        return 77
    work = tempfile.mkdtemp(prefix="toonforce_dds_")
    trace = os.path.join(work, "world.csv")
    a, b = f"tfdds-a-{os.getpid()}", f"tfdds-b-{os.getpid()}"
    hands = os.path.join(SOURCE, "scenes", "hands")
    procs = []
    try:
        make_hosts(a, b)
        run = subprocess.Popen(
            ["ip", "netns", "exec", a, TOONFORCE, "run", "--device", "sim",
             "--scene", os.path.join(SOURCE, "scenes", "two_players.toml"),
             "--script", "left=" + os.path.join(hands, "left_push.toml"),
             "--script", "right=" + os.path.join(hands, "right_push.toml"),
             "--duration", "6", "--allow-non-rt", "--no-mlock", "--view", "0", "--control", "--control-token", TOKEN,
             "--trace", trace],
            stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        procs.append(run)
        url = None
        for line in run.stderr:
            print("run: " + line.rstrip(), flush=True)
            m = re.search(r"viewer: (http://\S+)", line)
            if m:
                url = m.group(1)
                break
        check(url is not None, "the run serves its viewer")
        if url is None:
            return 1
        bridge = subprocess.Popen(["ip", "netns", "exec", a, BRIDGE, "--view", url, "--domain", "17", "--rate", "200",
                                   "--duration", "12", "--control-token", TOKEN],
                                  stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        procs.append(bridge)
        sends = [b'{"type": "set", "id": "dds-1", "effect": "surface1", "keys": {"stiffness": 2000}}',
                 b'{"type": "set", "id": "dds-2", "effect": "coupling1", "keys": {"stiffness": 1}}',
                 b'not json', b'{"type": "status", "id": "\xff"}', b'{"type": "status", "id": "dds-5"}']
        command = [b"ip", b"netns", b"exec", b.encode(), ECHO.encode(), b"--domain", b"17", b"--device", b"left",
                   b"--samples", b"100", b"--timeout", b"20"]
        for text in sends:
            command += [b"--send", text]
        echo = subprocess.run(command, capture_output=False, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              timeout=60)
        echo.stdout = echo.stdout.decode("utf-8", "replace")
        print(echo.stderr.decode("utf-8", "replace"))
        check(echo.returncode == 0, "the other host received 100 poses of device 'left'")
        lines = [line.split(",") for line in echo.stdout.splitlines()]
        publications = {p[1]: (p[2], p[3]) for p in lines if p[0] == "publication"}
        for name in ["left", "right"]:
            for what, type_name in [("pose", "geometry_msgs::msg::dds_::PoseStamped_"),
                                    ("wrench", "geometry_msgs::msg::dds_::WrenchStamped_"),
                                    ("faults", "std_msgs::msg::dds_::UInt32_")]:
                topic = f"rt/toonforce/{name}/{what}"
                check(publications.get(topic) == (type_name, "best_effort"),
                      f"discovered {topic} as {type_name}, best effort (got {publications.get(topic)})")
        replies = [json.loads(line[len("reply,"):]) for line in echo.stdout.splitlines() if line.startswith("reply,")]
        print(replies)
        check(len(replies) == 5, "every control message sent over DDS got one reply")
        if len(replies) == 5:
            check(replies[0] == {"type": "ok", "id": "dds-1", "sequence": 1},
                  "a scene change over DDS passes the control protocol's checks and is taken")
            check(replies[1]["type"] == "error" and "fixed while it runs" in replies[1]["message"],
                  "... one it refuses comes back with its reason")
            check(replies[2]["type"] == "error", "a message that is not JSON gets an error reply")
            check(replies[3]["type"] == "error" and "UTF-8" in replies[3]["message"],
                  "one that is not UTF-8 is refused by the bridge (the control connection stays)")
            check(replies[4].get("type") == "status" and replies[4].get("id") == "dds-5",
                  "... and the next message still gets its reply")
        check("rt/toonforce/left/twist" not in publications,
              "no twist for a world's device (its rows carry no velocity): nothing made up")
        bridge.send_signal(signal.SIGINT)
        _, bridge_err = bridge.communicate(timeout=60)
        print(bridge_err)
        check(bridge.returncode == 0 and "published" in bridge_err, "the bridge ends on Ctrl-C with its count")
        # A bridge that dies without a word (SIGKILL): the other host learns it from the writers'
        # liveliness (automatic, a 1 s lease), not from a goodbye.
        second = subprocess.Popen(["ip", "netns", "exec", a, BRIDGE, "--view", url, "--domain", "17", "--rate", "200"],
                                  stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        procs.append(second)
        watch = subprocess.Popen(["ip", "netns", "exec", b, ECHO, "--domain", "17", "--device", "left",
                                  "--samples", "1", "--until-gone", "yes", "--timeout", "60"],
                                 stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        procs.append(watch)
        for line in watch.stdout:
            if line.startswith("pose,"):
                break
        second.kill()
        second.communicate()
        watched, _ = watch.communicate(timeout=90)
        gone = [line for line in watched.splitlines() if line.startswith("gone,")]
        print(gone)
        check(watch.returncode == 0 and len(gone) == 1,
              "a bridge killed without a word is seen gone on the other host (its liveliness lapsed)")
        run.send_signal(signal.SIGTERM)  # stopped from outside, the page closes with the run
        run_out, _ = run.communicate(timeout=60)
        print(run_out)
        check("live     1 scene update(s) applied (each on every device at once), 0 refused" in run_out,
              "the world applied the one change that came over DDS")
        with open(trace) as f:
            rows = list(csv.DictReader(f))
        hips = [(float(r["left.x"]), float(r["left.y"]), float(r["left.z"])) for r in rows if r["left.x"] != "nan"]
        forces = [(float(r["left.fx"]), float(r["left.fy"]), float(r["left.fz"])) for r in rows]

        def in_trace(v, values):
            return any(all(abs(p - q) <= 1e-9 * max(1.0, abs(q)) for p, q in zip(v, row)) for row in values)
        poses = [tuple(float(x) for x in p[1:4]) for p in lines if p[0] == "pose"]
        wrenches = [tuple(float(x) for x in p[1:4]) for p in lines if p[0] == "wrench"]
        check(len(poses) >= 100 and all(in_trace(p, hips) for p in poses),
              f"each of the {len(poses)} poses received is the HIP of a row of the run's trace (world frame)")
        check(len(set(poses)) > 10, "... and they move (the hand script pushes)")
        check(len(wrenches) > 0 and all(in_trace(w, forces) for w in wrenches),
              f"each of the {len(wrenches)} wrenches received is the commanded force of a row of the trace")
        check(all(p[4] == "1" and p[5] == "toonforce_world" for p in lines if p[0] == "pose"),
              "poses carry frame_id toonforce_world and the identity orientation")
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
                p.communicate()
        for ns in (a, b):
            subprocess.run(["ip", "netns", "del", ns], capture_output=True)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
