"""Helpers of the Python tests: start the real `mpm serve`, submit a scene and wait for it."""

import json
import os
import pathlib
import subprocess
import time
import urllib.request

import numpy as np
import zarr

ROOT = pathlib.Path(__file__).resolve().parents[2]
MPM = os.environ.get("MPM_BIN", str(ROOT / "target" / "release" / "mpm"))


def start_server(args, env=None):
    """Starts `mpm serve --listen 127.0.0.1:0 ARGS`; returns the process and its base URL."""
    server = subprocess.Popen(
        [MPM, "serve", "--listen", "127.0.0.1:0", *args],
        stdout=subprocess.PIPE,
        text=True,
        env=env,
    )
    line = server.stdout.readline()
    if not line.startswith("listening on "):
        server.kill()
        server.wait()
        raise AssertionError(line)
    return server, line.split()[-1]


def run_job(url, scene, seconds=60):
    """Submits `scene` (202) and returns the job once it has ended."""
    request = urllib.request.Request(
        f"{url}/v1/jobs",
        data=json.dumps(scene).encode(),
        headers={"Content-Type": "application/json"},
        method="POST",
    )
    with urllib.request.urlopen(request) as r:
        assert r.status == 202
        job = json.load(r)
    deadline = time.time() + seconds
    while job["status"] not in ("succeeded", "failed", "cancelled"):
        assert time.time() < deadline
        time.sleep(0.1)
        with urllib.request.urlopen(f"{url}/v1/jobs/{job['id']}") as r:
            job = json.load(r)
    return job


def example(name):
    """An example scene as JSON."""
    return json.loads((ROOT / "examples" / name).read_text())


def open_bar_results(url, job):
    """Opens the vibrating bar job's store with zarr-python over HTTP through the API and
    checks it: the metrics, 41 frames of 320 finite positions, the end time. Returns the
    group and the positions."""
    g = zarr.open_group(f"{url}/v1/jobs/{job['id']}/results", mode="r")
    assert g.attrs["metrics"]["error"] == job["metrics"]["error"]
    x = g["particles/x"][:]
    assert x.shape == (41, 320, 2)
    assert np.all(np.isfinite(x))
    assert g["time"][-1] == 0.4
    return g, x
