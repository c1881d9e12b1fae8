"""Reads a bump-row-3d run (examples/bump-row-3d.json, one bump): per frame, the share of
the bump's rear half that is wetted (10-degree sectors from -90 to 90 degrees about +x
with an entered liquid particle within 0.3 mm of the bump's surface), the liquid
particles inside the bump (more than 50 um in from its surface), and the fastest
particle.

Usage: .venv/bin/python docs/wip/bump-row-rear.py STORE/bump-row-3d.zarr
"""

import sys

import numpy as np
import zarr

store = zarr.open_group(sys.argv[1], mode="r")
bump = store.attrs["scene"]["obstacles"][0]["shape"]["cylinder"]
centre, radius = np.array(bump["center"][:2]), bump["radius"]
times = store["time"][:]
positions, injected, velocity = (
    store["particles/x"],
    store["particles/injected"],
    store["particles/v"],
)
print("t ms   rear half wetted  liquid inside the bump  fastest m/s")
for f in range(len(times)):
    entered = np.asarray(injected[f]) > 0
    x = np.asarray(positions[f])[entered]
    d = x[:, :2] - centre
    r = np.hypot(d[:, 0], d[:, 1])
    angle = np.degrees(np.arctan2(d[:, 1], d[:, 0]))
    sectors = np.floor((angle[r < radius + 3e-4] + 90) / 10).astype(int)
    wetted = len({s for s in sectors if 0 <= s < 18}) / 18
    inside = int((r < radius - 5e-5).sum())
    fastest = np.linalg.norm(np.asarray(velocity[f])[entered], axis=1).max()
    print(f"{times[f] * 1e3:5.1f}  {wetted:16.2f}  {inside:22d}  {fastest:11.2f}")
