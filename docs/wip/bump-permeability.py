"""Permeability ratio K/K0 of the bump cell (issue 19, work in progress).

Usage: python docs/wip/bump-permeability.py BUMPS.zarr PLATES.zarr PITCH DIAMETER
(stores of docs/wip/bump-cell-150.json and docs/wip/bump-cell-plates.json). Prints, per
frame, the mean x velocity of the particles over the middle two pitches of the slug, and
K/K0 = (1 - pi D^2 / (4 P^2)) * mean_bumps / mean_plates: the superficial velocity is the
mean over the liquid times the open fraction, and the same body force drives both.
"""
import sys

import numpy as np
import zarr


def window_means(path, pitch):
    g = zarr.open_group(path, mode="r")
    v = np.asarray(g["particles"]["v"][:])
    x = np.asarray(g["particles"]["x"][:])
    inside = (x[..., 0] > 2 * pitch) & (x[..., 0] < 4 * pitch)
    return np.asarray(g["time"][:]), [v[k, inside[k], 0].mean() if inside[k].any() else 0.0 for k in range(len(v))]


bumps, plates, pitch, diameter = sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4])
open_fraction = 1 - np.pi * diameter**2 / (4 * pitch**2)
times, with_bumps = window_means(bumps, pitch)
_, without = window_means(plates, pitch)
for t, b, p in zip(times[1:], with_bumps[1:], without[1:]):
    print(f"t = {t:.3e} s  mean u: bumps {b:.4e}, plates {p:.4e} m/s  K/K0 = {open_fraction * b / p:.4f}")
