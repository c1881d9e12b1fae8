"""Writes examples/underfill-process-2d.json with N thermal cycles, one stage each, to stdout.

Usage: python3 docs/process-cycles.py N > cycles.json && mpm run cycles.json --json
(the README's 30-cycle damage figures: N = 30). Each cycle is the example's: 15 min ramp to
398 K, 15 min dwell, 15 min ramp to 233 K, 15 min dwell; one frame per cycle.
"""

import json
import pathlib
import sys

n = int(sys.argv[1])
scene = json.loads(
    (pathlib.Path(__file__).parent.parent / "examples/underfill-process-2d.json").read_text()
)
stages = [s for s in scene["stages"] if not s["name"].startswith("cycle-")]
first = next(s for s in scene["stages"] if s["name"] == "cycle-1")
start = 3000.0
ambient = [[start, 298.0]]
t = start
for _ in range(n):
    for step, temperature in [(900, 398.0), (900, 398.0), (900, 233.0), (900, 233.0)]:
        t += step
        ambient.append([t, temperature])
first["changes"]["physics"]["thermal"]["boundaries"][0]["convection"]["ambient"] = ambient
first["changes"]["solver"]["end_time"] = start + 3600.0
first["changes"]["output"]["frames"] = 1
stages.append(first)
for k in range(2, n + 1):
    stages.append(
        {
            "name": f"cycle-{k}",
            "changes": {"solver": {"end_time": start + 3600.0 * k}, "output": {"frames": 1}},
        }
    )
scene["stages"] = stages
json.dump(scene, sys.stdout, indent=1)
