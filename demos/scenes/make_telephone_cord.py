#!/usr/bin/env python3
"""Writes the telephone-cord scene (Strings Fig. 6c): a cord twisted eight turns whose ends
are then brought together coils into a spiral; an untwisted cord beside it, moved the same,
only bends. Usage: make_telephone_cord.py > telephone-cord.json.

Both cords start with the same small out-of-line wiggle (2 mm): a perfectly straight
string has no curvature for the twist to act on (Strings Eq. 6-7: the twist force is
along the curvature binormal), so it would stay in its line however far it is twisted;
a real cord is never quite straight."""
import json, math, re

n = 100                  # segments, 1 m
wiggle = 0.002           # m, out of line (z), zero at the clamped ends
turns = 8
twist_seconds = 3.0
material = {"torsion": {"modulus": 1e9, "yield": 5, "plastic_modulus": 1e8, "rupture": 10}, "variation": 1e-4}


def cord(name, z0):
    points = [[round(-0.5 + i / n, 6), 1.0,
               round(z0 + wiggle * math.sin(math.pi * i / n) * math.sin(6 * math.pi * i / n), 6)]
              for i in range(n + 1)]
    return {"name": name, "points": points, "radius": 0.002, "density": 1150, "damping": 3.0,
            "material": material,
            # Held as by two hands: the two end particles at each end pinned, so the end segments
            # keep their direction and the cord its link (twist + writhe); held at one particle,
            # an end swivels and lets the twist out.
            "attachments": [{"particle": p, "world": points[p]} for p in (0, 1, -2, -1)]}


scene = {
    "format": "tearables-scene/1",
    "description": "Strings Fig. 6c: a cord twisted eight turns, its ends then brought together, coils up like "
                   "a telephone cord; the untwisted cord behind it only bends (no gravity)",
    "dt": 0.01,
    "steps": 750,
    "gravity": [0, 0, 0],
    "strings": [cord("cord", 0.0), cord("plain", -0.6)],  # 0.6 m behind: the coil swings 0.2 m out, the bow 0.15 m,
    "drivers": [
        {"type": "twist", "target": "cord", "end": -1, "rate": round(2 * math.pi * turns / twist_seconds, 4),
         "from": 0, "until": twist_seconds},
        # Then both right ends move 0.8 m toward the left ends in 4 s and hold for 0.5 s (the
        # tightening coil touches itself more and more: string collisions cost 10 ms a step).
        *[{"type": "move", "target": name, "particle": p, "velocity": [-0.2, 0, 0], "from": 3, "until": 7}
          for name in ("cord", "plain") for p in (-2, -1)],
    ],
    "camera": {"eye": [-0.3, 1.16, 0.45], "target": [-0.3, 1.0, -0.3], "fov": 45},
    "output": {"every": 10},
}
text = json.dumps(scene, indent=1)
# One line per point.
text = re.sub(r"\[\s+(-?[0-9.e+-]+),\s+(-?[0-9.e+-]+),\s+(-?[0-9.e+-]+)\s+\]", r"[\1, \2, \3]", text)
print(text)
