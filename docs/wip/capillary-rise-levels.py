"""Reads a 2D capillary-rise run (examples/capillary-rise.json and its variants): per frame,
the column's height between the plates and the pool's level by liquid volume over
footprint, the pool's counted two ways, and the rise of each against Jurin's height.

- `sharp`: every particle whose centre lies in a pool stretch counts whole (what the
  `capillary_rise` reference did before stop 84);
- `ramp`: a stretch's end inside the domain counts a particle by the share of its width
  (one particle spacing) inside the stretch; an end at the domain's bound stays sharp
  (what the reference does since stop 84).

The sharp count jumps by a whole column of particles when the pool's particle lattice
shears: in a 2 mm stretch one column is an eighth of the count. Stop 83 found the pool's
level read 7.0 mm by it in runs whose level read 7.2 mm by the ramp and by stretches 3 to
6 mm wide, so the reference's rise read about 0.2 mm high.

Usage: .venv/bin/python docs/wip/capillary-rise-levels.py STORE/capillary-rise.zarr
"""

import sys

import numpy as np
import zarr

store = zarr.open_group(sys.argv[1], mode="r")
scene = store.attrs["scene"]
reference = scene["reference"]
plates, pool = reference["plates"], reference["pool"]
across = reference.get("across", 0)
low, high = scene["domain"]["min"][across], scene["domain"]["max"][across]
spacing = max(
    scene["domain"]["cell_size"] / b.get("particles_per_cell", 2) for b in scene["bodies"]
)
volume = spacing**2
g = -scene["solver"]["gravity"][reference.get("up", 1)]
jurin = (
    2 * reference["surface_tension"] * np.cos(np.radians(reference["contact_angle"]))
    / (reference["density"] * g * (plates[1] - plates[0]))
)


def share(x, start, end):
    """Each particle's share inside [start, end]: ramps at ends inside the domain."""
    if start > low:
        lower = np.clip((x - start) / spacing + 0.5, 0, 1)
    else:
        lower = (x > start).astype(float)
    if end < high:
        upper = np.clip((end - x) / spacing + 0.5, 0, 1)
    else:
        upper = (x < end).astype(float)
    return lower * upper


times = store["time"][:]
width = sum(b - a for a, b in pool)
print(f"Jurin {jurin * 1e3:.3f} mm")
print("t s    column mm  pool sharp  pool ramp  rise sharp  rise ramp  (error ramp)")
for f in range(len(times)):
    x = np.asarray(store["particles/x"][f])[:, across]
    column = ((x > plates[0]) & (x < plates[1])).sum() * volume / (plates[1] - plates[0])
    sharp = sum(((x > a) & (x < b)).sum() for a, b in pool) * volume / width
    ramp = sum(share(x, a, b).sum() for a, b in pool) * volume / width
    print(
        f"{times[f]:5.2f}  {column * 1e3:9.3f}  {sharp * 1e3:10.3f}  {ramp * 1e3:9.3f}"
        f"  {(column - sharp) * 1e3:10.3f}  {(column - ramp) * 1e3:9.3f}"
        f"  ({(column - ramp) / jurin - 1:+.3f})"
    )
