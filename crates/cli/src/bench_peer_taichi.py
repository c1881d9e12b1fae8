"""The cube drop of `mpm bench` written in Taichi (CPU backend, f64): the peer that
`mpm bench --peer taichi` runs beside its own run on the same machine and thread count.

A straightforward MLS-MPM program, as Taichi's own examples write it: one particle-parallel
P2G with atomic adds on a dense grid, a node-parallel grid update, one particle-parallel
G2P. The scene is the one `mpm bench` builds (crates/cli/src/bench.rs, `cube-drop`):
a unit box of n³ cells; an elastic cube of ⌊0.8 n⌋³ particles (2 per cell along each
axis) from 0.3 m, falling at 1 m/s under gravity; fixed-corotated (E = 1e5 Pa, ν = 0.3,
1000 kg/m³); APIC with the MLS-MPM force; quadratic B-splines; dt = 1e-4 s; slip walls
3 cells thick on every face (a wall node keeps no velocity into the wall).

Prints one JSON document: particles, steps, wall seconds of the step loop (kernels
compiled before the clock starts), particle-steps per second, and the centre of mass at
each of `--frames` + 1 evenly spaced steps (0 and the last included), which
`mpm bench --peer` compares with its own run's.
"""

import argparse
import json
import time

import taichi as ti


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cells", type=int, default=64)
    ap.add_argument("--steps", type=int, default=50)
    ap.add_argument("--frames", type=int, default=1)
    ap.add_argument("--threads", type=int, default=0, help="0: Taichi's default")
    args = ap.parse_args()

    init = dict(arch=ti.cpu, default_fp=ti.f64, default_ip=ti.i32, log_level=ti.WARN)
    if args.threads > 0:
        init["cpu_max_num_threads"] = args.threads
    ti.init(**init)

    n = args.cells
    dx = 1.0 / n
    inv_dx = float(n)
    per_axis = int(0.8 * n)
    spacing = dx / 2.0
    count = per_axis**3
    dt = 1e-4
    rho, youngs, poisson = 1000.0, 1e5, 0.3
    mu = youngs / (2.0 * (1.0 + poisson))
    lam = youngs * poisson / ((1.0 + poisson) * (1.0 - 2.0 * poisson))
    volume = spacing**3
    mass = rho * volume
    gravity = ti.Vector([0.0, -9.81, 0.0])
    wall = 2  # nodes 0..=2 and n-2..=n are wall nodes: 3 cells thick
    nodes = n + 1

    x = ti.Vector.field(3, ti.f64, count)
    v = ti.Vector.field(3, ti.f64, count)
    C = ti.Matrix.field(3, 3, ti.f64, count)
    F = ti.Matrix.field(3, 3, ti.f64, count)
    grid_v = ti.Vector.field(3, ti.f64, (nodes, nodes, nodes))
    grid_m = ti.field(ti.f64, (nodes, nodes, nodes))
    com = ti.Vector.field(3, ti.f64, ())

    @ti.kernel
    def reset():
        for p in x:
            i = p // (per_axis * per_axis)
            j = (p // per_axis) % per_axis
            k = p % per_axis
            x[p] = ti.Vector([0.3 + (i + 0.5) * spacing, 0.3 + (j + 0.5) * spacing,
                              0.3 + (k + 0.5) * spacing])
            v[p] = ti.Vector([0.0, -1.0, 0.0])
            C[p] = ti.Matrix.zero(ti.f64, 3, 3)
            F[p] = ti.Matrix.identity(ti.f64, 3)

    @ti.kernel
    def clear():
        for I in ti.grouped(grid_m):
            grid_m[I] = 0.0
            grid_v[I] = ti.Vector.zero(ti.f64, 3)

    @ti.kernel
    def p2g():
        for p in x:
            base = (x[p] * inv_dx - 0.5).cast(int)
            fx = x[p] * inv_dx - base.cast(float)
            w = [0.5 * (1.5 - fx) ** 2, 0.75 - (fx - 1.0) ** 2, 0.5 * (fx - 0.5) ** 2]
            J = F[p].determinant()
            R, _ = ti.polar_decompose(F[p])
            # Kirchhoff stress τ = 2μ (F − R) Fᵀ + λ (J − 1) J I, times the initial volume.
            tau = 2.0 * mu * (F[p] - R) @ F[p].transpose() + ti.Matrix.identity(
                ti.f64, 3) * lam * (J - 1.0) * J
            affine = -dt * volume * 4.0 * inv_dx * inv_dx * tau + mass * C[p]
            mv = mass * (v[p] + dt * gravity)
            for i, j, k in ti.static(ti.ndrange(3, 3, 3)):
                offset = ti.Vector([i, j, k])
                dpos = (offset.cast(float) - fx) * dx
                weight = w[i][0] * w[j][1] * w[k][2]
                grid_m[base + offset] += weight * mass
                grid_v[base + offset] += weight * (mv + affine @ dpos)

    @ti.kernel
    def grid_update():
        for I in ti.grouped(grid_m):
            m = grid_m[I]
            if m > 0.0:
                vel = grid_v[I] / m
                for a in ti.static(range(3)):
                    if I[a] <= wall and vel[a] < 0.0:
                        vel[a] = 0.0
                    if I[a] >= n - wall and vel[a] > 0.0:
                        vel[a] = 0.0
                grid_v[I] = vel

    @ti.kernel
    def g2p():
        for p in x:
            base = (x[p] * inv_dx - 0.5).cast(int)
            fx = x[p] * inv_dx - base.cast(float)
            w = [0.5 * (1.5 - fx) ** 2, 0.75 - (fx - 1.0) ** 2, 0.5 * (fx - 0.5) ** 2]
            new_v = ti.Vector.zero(ti.f64, 3)
            new_c = ti.Matrix.zero(ti.f64, 3, 3)
            for i, j, k in ti.static(ti.ndrange(3, 3, 3)):
                offset = ti.Vector([i, j, k])
                dpos = (offset.cast(float) - fx) * dx
                weight = w[i][0] * w[j][1] * w[k][2]
                gv = grid_v[base + offset]
                new_v += weight * gv
                new_c += 4.0 * inv_dx * inv_dx * weight * gv.outer_product(dpos)
            v[p] = new_v
            C[p] = new_c
            x[p] += dt * new_v
            F[p] = (ti.Matrix.identity(ti.f64, 3) + dt * new_c) @ F[p]

    @ti.kernel
    def centre():
        com[None] = ti.Vector.zero(ti.f64, 3)
        for p in x:
            com[None] += x[p] / count

    def step():
        clear()
        p2g()
        grid_update()
        g2p()

    # Compile every kernel before the clock starts, then start from the initial state.
    reset()
    step()
    centre()
    reset()
    ti.sync()

    frames = max(1, min(args.frames, args.steps))
    record = {round(f * args.steps / frames) for f in range(frames + 1)}
    trajectory = []
    elapsed = 0.0
    for s in range(args.steps + 1):
        if s in record:
            centre()
            trajectory.append({"step": s, "time": s * dt, "com": list(com[None].to_numpy())})
        if s == args.steps:
            break
        t0 = time.perf_counter()
        step()
        ti.sync()
        elapsed += time.perf_counter() - t0

    print(json.dumps({
        "peer": "taichi",
        "taichi": ".".join(str(p) for p in ti.__version__),
        "threads": args.threads,
        "cells": n,
        "particles": count,
        "steps": args.steps,
        "wall_seconds": elapsed,
        "particle_steps_per_second": count * args.steps / elapsed,
        "trajectory": trajectory,
    }))


if __name__ == "__main__":
    main()
