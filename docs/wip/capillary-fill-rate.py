"""The fill rate of a capillary_filling run with liquid particles, window by window, against
Washburn's: R = d(x^2)/dt / (h sigma cos(theta) / (3 mu)), which is 1 under Washburn's law
and cos(theta_d)/cos(theta) if the moving meniscus meets the plates at theta_d.

Usage: .venv/bin/python docs/wip/capillary-fill-rate.py STORE.zarr [FRAMES_PER_WINDOW]

The front is the reference's: the volume of the particles past the entrance over the gap
(2D scenes; the particles' volume is taken as (cell/2)^2, two per cell per axis).
"""

import sys

import numpy as np
import zarr

store = zarr.open_group(sys.argv[1], mode="r")
window = int(sys.argv[2]) if len(sys.argv) > 2 else 2
scene = store.attrs["scene"]
ref = scene["reference"]
h, sigma, mu = ref["gap"], ref["surface_tension"], ref["viscosity"]
theta = np.radians(ref["contact_angle"])
axis, entrance = ref["axis"], ref["entrance"]
volume = (scene["domain"]["cell_size"] / 2) ** 2
washburn = h * sigma * np.cos(theta) / (3 * mu)

times = store["time"][:]
positions = store["particles/x"]
fronts = []
for i in range(len(times)):
    x = np.asarray(positions[i])
    x = x[np.isfinite(x[:, axis])]
    fronts.append(min((x[:, axis] > entrance).sum() * volume / h, ref["length"]))

print("from s  to s   front mm  x/h    Washburn's front mm  R = rate/Washburn's  Ca = mu*U/sigma")
for a in range(0, len(times) - window, window):
    b = a + window
    (t0, x0), (t1, x1) = (times[a], fronts[a]), (times[b], fronts[b])
    rate = (x1**2 - x0**2) / (t1 - t0)
    speed = (x1 - x0) / (t1 - t0)
    print(
        f"{t0:6.2f} {t1:6.2f} {x1 * 1e3:8.2f} {x1 / h:6.2f} {np.sqrt(washburn * t1) * 1e3:10.2f}"
        f" {rate / washburn:18.3f} {mu * speed / sigma:16.4f}"
    )
