#!/usr/bin/env python3
"""Writes the bridge scene (Strings Fig. 10): boards tied by rope pieces into a hanging
bridge, crates spawned onto it until the ropes tear. Usage: make_bridge.py [crates]."""
import json, sys
boards = 8
bw, bt, bd = 0.12, 0.04, 0.35   # board half extents (x, y, z)
gap = 0.16                      # rope length between boards
span = boards * 2 * bw + (boards + 1) * gap
y0 = 2.0
x0 = -span / 2
bodies = [{"name": "ground", "shape": {"plane": [0, 1, 0, 0]}, "mass": 0}]
strings = []
mat = {"tensile": {"young": 1e9, "yield": 1.4e7, "plastic_modulus": 1e8, "rupture": 1.7e7}, "variation": 0.05}
xs = []
x = x0 + gap
for i in range(boards):
    cx = x + bw
    bodies.append({"name": f"board{i}", "shape": {"box": [bw, bt, bd]}, "mass": 4.0,
                   "position": [round(cx, 4), y0, 0], "friction": 0.8})
    xs.append(cx)
    x += 2 * bw + gap
seg_total = 0
for side, z in (("l", -0.3), ("r", 0.3)):
    for g in range(boards + 1):
        a = x0 if g == 0 else xs[g - 1] + bw
        b = x0 + span if g == boards else xs[g] - bw
        n = 45 if g == 0 else 41
        seg_total += n
        att = []
        if g == 0: att.append({"particle": 0, "world": [round(a, 4), y0, z]})
        else: att.append({"particle": 0, "body": f"board{g-1}", "local": [bw, 0, z]})
        if g == boards: att.append({"particle": -1, "world": [round(b, 4), y0, z]})
        else: att.append({"particle": -1, "body": f"board{g}", "local": [-bw, 0, z]})
        strings.append({"name": f"{side}{g}", "from": [round(a, 4), y0, z], "to": [round(b, 4), y0, z],
                        "segments": n, "radius": 0.004, "density": 1150, "material": mat, "attachments": att})
drivers = []
for k in range(int(sys.argv[1]) if len(sys.argv) > 1 else 6):
    drivers.append({"type": "spawn", "at": round(1.0 + 0.8 * k, 2),
                    "body": {"name": f"crate{k}", "shape": {"box": [0.1, 0.1, 0.1]}, "mass": 10,
                             "position": [round(xs[[3, 4, 2, 5, 1, 6, 0, 7][k % 8]], 3), y0 + 0.5, 0], "friction": 0.8}})
scene = {"format": "tearables-scene/1",
         "description": f"Strings Fig. 10: {boards} wooden boards tied by {2*(boards+1)} ropes ({seg_total} segments) into a hanging bridge; crates fall on it until the ropes tear",
         "dt": 0.01, "steps": 600, "gravity": [0, -9.81, 0], "seed": 1,
         "camera": {"eye": [0.3, 2.9, 3.4], "target": [0, 1.5, 0], "fov": 45},
         "bodies": bodies, "strings": strings, "drivers": drivers, "output": {"every": 5}}
print(json.dumps(scene, indent=1))
