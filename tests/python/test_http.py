"""zarr-python opens a job's results directly over HTTP from the real `mpm serve`."""

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


def test_results_open_over_http(tmp_path):
    server = subprocess.Popen(
        [MPM, "serve", "--listen", "127.0.0.1:0", "--data", str(tmp_path / "data")],
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        line = server.stdout.readline()
        assert line.startswith("listening on "), line
        url = line.split()[-1]
        scene = json.loads((ROOT / "examples" / "vibrating-bar.json").read_text())
        request = urllib.request.Request(
            f"{url}/v1/jobs",
            data=json.dumps(scene).encode(),
            headers={"Content-Type": "application/json"},
            method="POST",
        )
        with urllib.request.urlopen(request) as r:
            assert r.status == 202
            job = json.load(r)
        deadline = time.time() + 60
        while job["status"] not in ("succeeded", "failed", "cancelled"):
            assert time.time() < deadline
            time.sleep(0.1)
            with urllib.request.urlopen(f"{url}/v1/jobs/{job['id']}") as r:
                job = json.load(r)
        assert job["status"] == "succeeded"

        g = zarr.open_group(f"{url}/v1/jobs/{job['id']}/results", mode="r")
        assert g.attrs["metrics"]["error"] == job["metrics"]["error"]
        x = g["particles/x"][:]
        assert x.shape == (41, 320, 2)
        assert np.all(np.isfinite(x))
        assert g["time"][-1] == 0.4
    finally:
        server.kill()
        server.wait()
