"""Result stores open with the real zarr-python 3 and xarray, as they are.

The test runs the `mpm` binary (MPM_BIN, default target/release/mpm) on the vibrating bar,
opens the store with zarr and xarray, checks the documented layout, and recomputes the
run's error against the analytic solution in numpy from the stored arrays alone.
"""

import json
import math
import os
import pathlib
import subprocess

import numpy as np
import xarray as xr
import zarr

ROOT = pathlib.Path(__file__).resolve().parents[2]
MPM = os.environ.get("MPM_BIN", str(ROOT / "target" / "release" / "mpm"))


def run_bar(tmp_path):
    subprocess.run(
        [MPM, "run", str(ROOT / "examples" / "vibrating-bar.json"), "--out", str(tmp_path), "-q"],
        check=True,
    )
    return tmp_path / "vibrating-bar.zarr"


def test_layout_and_attributes_with_zarr(tmp_path):
    store = run_bar(tmp_path)
    g = zarr.open_group(str(store), mode="r")
    assert g.metadata.zarr_format == 3
    frames = g["time"].shape[0]
    assert frames == 41
    assert g["particles/x"].shape == (frames, 320, 2)
    assert g["particles/v"].shape == (frames, 320, 2)
    assert g["particles/stress"].shape == (frames, 320, 2, 2)
    assert g["particles/x"].dtype == np.float64
    assert g["diagnostics/total_energy"].shape == (frames,)
    attrs = g.attrs
    assert attrs["scene"]["name"] == "vibrating-bar"
    assert attrs["mpm_version"]
    metrics = attrs["metrics"]
    for key in ["wall_seconds", "steps", "particle_steps_per_second", "bytes_per_particle", "energy_drift", "error"]:
        assert key in metrics, key
    assert metrics["outcome"] == "finished"


def test_error_recomputed_from_stored_arrays_matches_the_run(tmp_path):
    store = run_bar(tmp_path)
    g = zarr.open_group(str(store), mode="r")
    ref = g.attrs["scene"]["reference"]
    t = g["time"][:]
    x = g["particles/x"][:]
    x0 = x[0]
    length, amplitude = ref["length"], ref["amplitude"]
    omega = math.pi * math.sqrt(ref["youngs_modulus"] / ref["density"]) / (2 * length)
    shape = np.sin(math.pi * (x0[:, 0] - ref["fixed_end"]) / (2 * length))
    u_ref = (amplitude / omega) * np.sin(omega * t)[:, None] * shape[None, :]
    u = x[:, :, 0] - x0[None, :, 0]
    # Every particle has the same mass here, so the mass weights cancel.
    error = math.sqrt(((u - u_ref) ** 2).sum() / (u_ref**2).sum())
    assert abs(error - g.attrs["metrics"]["error"]) < 1e-9 * error
    assert error < 0.01


def test_xarray_opens_groups_and_tree(tmp_path):
    store = run_bar(tmp_path)
    particles = xr.open_zarr(str(store), group="particles", consolidated=False)
    assert particles["x"].dims == ("frame", "particle", "component")
    assert particles["stress"].dims == ("frame", "particle", "component", "column")
    assert particles.sizes["frame"] == 41
    tree = xr.open_datatree(str(store), engine="zarr", consolidated=False)
    assert "particles" in tree.children and "diagnostics" in tree.children
    energy = tree["diagnostics"]["kinetic_energy"].values + tree["diagnostics"]["strain_energy"].values
    # Kinetic plus strain energy oscillates with the staggered time integration (velocities
    # are first-order at whole steps; measured amplitude 1.04%) and does not drift: the two
    # periods of the run have the same mean.
    relative = energy / energy[0] - 1
    assert np.all(np.abs(relative) < 0.02)
    assert abs(relative[1:21].mean() - relative[21:41].mean()) < 0.002
    assert json.loads(json.dumps(tree.attrs["metrics"]))["steps"] > 0


def test_a_store_with_a_checkpoint_opens_in_zarr_and_xarray(tmp_path):
    subprocess.run(
        [MPM, "run", str(ROOT / "examples" / "vibrating-bar.json"), "--out", str(tmp_path), "-q",
         "--set", 'output.checkpoint={"steps":100}'],
        check=True,
    )
    store = tmp_path / "vibrating-bar.zarr"
    g = zarr.open_group(str(store), mode="r")
    pointer = g.attrs["checkpoint"]
    assert pointer["step"] == 400 and pointer["frames"] == 37
    checkpoint = g[pointer["path"]]
    assert checkpoint["particles.position"].shape == (320 * 2,)
    assert checkpoint.attrs["state"]["step"] == 400
    tree = xr.open_datatree(str(store), engine="zarr", consolidated=False)
    assert tree["checkpoints"]["400"]["particles.mass"].shape == (320,)


def test_a_staged_store_opens_stage_by_stage(tmp_path):
    scene = json.loads((ROOT / "examples" / "vibrating-bar.json").read_text())
    scene["name"] = "bar-staged"
    scene["output"]["frames"] = 4
    scene["stages"] = [
        {"name": "first", "changes": {"solver": {"end_time": 0.2}}},
        {"name": "second", "changes": {"solver": {"end_time": 0.4}}},
    ]
    path = tmp_path / "staged.json"
    path.write_text(json.dumps(scene))
    subprocess.run([MPM, "run", str(path), "--out", str(tmp_path), "-q"], check=True)
    store = tmp_path / "bar-staged.zarr"
    g = zarr.open_group(str(store), mode="r")
    assert [s["name"] for s in g.attrs["metrics"]["stages"]] == ["first", "second"]
    second = g["stages/1-second"]
    assert second["time"][0] == 0.2 and second["time"][-1] == 0.4
    assert second.attrs["metrics"]["outcome"] == "finished"
    # The first frame of a stage is the last of the stage before.
    assert np.array_equal(second["particles/x"][0], g["stages/0-first/particles/x"][-1])
    tree = xr.open_datatree(str(store), engine="zarr", consolidated=False)
    assert tree["stages"]["0-first"]["particles"]["x"].shape == (5, 320, 2)


def test_the_fill_to_cure_chain_opens_with_its_tables_and_fewer_particles(tmp_path):
    # The process chain's fill and a short cure: the fill stage keeps two tables of
    # different lengths (each table has its own dimension names), and the cure stage has
    # fewer particles than the fill (the trapped air's particles were removed).
    scene = json.loads((ROOT / "examples" / "underfill-process-2d.json").read_text())
    scene["stages"] = scene["stages"][:2]
    scene["stages"][1]["changes"]["solver"]["end_time"] = 61.6
    scene["stages"][1]["changes"]["output"]["frames"] = 1
    path = tmp_path / "chain.json"
    path.write_text(json.dumps(scene))
    subprocess.run([MPM, "run", str(path), "--out", str(tmp_path), "-q"], check=True)
    store = tmp_path / "underfill-process-2d.zarr"
    tree = xr.open_datatree(str(store), engine="zarr", consolidated=False)
    fill = tree["stages"]["0-fill"]
    voids = fill["tables"]["underfill_voids"]
    history = fill["tables"]["underfill_fill"]
    assert voids.dims == ("underfill_voids_row", "underfill_voids_column")
    assert voids.shape[0] >= 1 and history.shape[0] > voids.shape[0]
    removed = zarr.open_group(str(store), mode="r").attrs["metrics"]["stages"][1][
        "removed_particles"
    ]
    assert removed > 0
    before = fill["particles"]["x"].shape[1]
    after = tree["stages"]["1-cure"]["particles"]["x"].shape[1]
    assert after == before - removed
