#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""Writes the bundled motions in scenes/motions/ (open-loop HIP paths for `toonforce replay`).

Run with Debian's python (no third-party modules): /usr/bin/python3 scenes/motions/make_motions.py
Each motion is sampled at 1 kHz. Positions only: replay estimates velocity as a device would.
"""
import math
import os

HERE = os.path.dirname(os.path.abspath(__file__))
RATE_HZ = 1000.0


def write(name, comment, samples):
    with open(os.path.join(HERE, name), "w") as f:
        for line in comment.strip().splitlines():
            f.write("# " + line + "\n")
        f.write("t,x,y,z\n")
        for t, (x, y, z) in samples:
            f.write(f"{t:.3f},{x:.9f},{y:.9f},{z:.9f}\n")


def strike():
    """Down onto the floor at 0.2 m/s, pressed 3 mm in, held, then lifted off at 0.1 m/s."""
    out = []
    z_contact_t = 0.1  # reaches z = 0 at t = 0.1 s from z = 0.02 m
    for k in range(700):
        t = k / RATE_HZ
        if t < z_contact_t:
            z = 0.02 - 0.2 * t
        elif t < 0.4:
            # exponential settling to 3 mm inside, continuous in position and velocity
            tau = 0.015
            z = -0.2 * tau * (1.0 - math.exp(-(t - z_contact_t) / tau))
        else:
            z_hold = -0.2 * 0.015 * (1.0 - math.exp(-(0.4 - z_contact_t) / 0.015))
            z = min(z_hold + 0.1 * (t - 0.4), 0.02)
        out.append((t, (0.0, 0.0, z)))
    return out


def stroke():
    """Pressed 2 mm into the floor and stroked along +x, speeding up smoothly to 0.1 m/s."""
    out = []
    ramp_s = 0.2
    for k in range(800):
        t = k / RATE_HZ
        # speed 0.1 (1 - cos(pi t / ramp)) / 2 during the ramp, then 0.1 m/s; x is its integral
        if t < ramp_s:
            x = -0.04 + 0.1 * (t / 2.0 - ramp_s / (2.0 * math.pi) * math.sin(math.pi * t / ramp_s))
        else:
            x = -0.04 + 0.1 * (ramp_s / 2.0 + (t - ramp_s))
        out.append((t, (x, 0.0, -0.002)))
    return out


def crossing(speed_m_per_s, name, what):
    """Along +x at constant speed on the ground (1 mm pressed in) across the cliff's gap."""
    out = []
    duration = 0.08 / speed_m_per_s
    for k in range(int(duration * RATE_HZ) + 1):
        t = k / RATE_HZ
        out.append((t, (-0.04 + speed_m_per_s * t, 0.0, -0.001)))
    write(name, what, out)


write("strike.csv", strike.__doc__ + "\nFor scenes/cartoon_wall.toml and scenes/wall.toml.", strike())
write("stroke.csv", stroke.__doc__ + "\nFor scenes/realistic_friction.toml and scenes/slippery.toml.", stroke())
crossing(0.2, "crossing_fast.csv", "Across the cliff's gap at 0.2 m/s, 1 mm into the ground.\nFor scenes/cliff.toml.")
crossing(0.04, "crossing_slow.csv", "Across the cliff's gap at 0.04 m/s, 1 mm into the ground.\nFor scenes/cliff.toml.")
