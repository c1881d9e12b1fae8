"""A job's store in an S3 bucket (moto's server) opens in zarr-python: through the API over
HTTP as before, and from the bucket's objects, whose keys under the job's prefix are the
store's own keys."""

import json
import os
import pathlib
import socket
import subprocess
import sys
import time
import urllib.request

import numpy as np
import pytest
import zarr

from mpm_helpers import example, open_bar_results, run_job, start_server

MOTO = os.environ.get("MPM_MOTO_SERVER", str(pathlib.Path(sys.executable).parent / "moto_server"))


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def moto():
    if not os.path.isfile(MOTO):
        pytest.skip(f"no moto_server at {MOTO} (pip install -r tests/python/requirements.txt)")
    port = free_port()
    server = subprocess.Popen(
        [MOTO, "-H", "127.0.0.1", "-p", str(port)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    endpoint = f"http://127.0.0.1:{port}"
    try:
        deadline = time.time() + 60
        while True:
            try:
                urllib.request.urlopen(endpoint).close()
                break
            except OSError:
                assert time.time() < deadline, "moto_server did not start"
                time.sleep(0.1)
        yield endpoint
    finally:
        server.kill()
        server.wait()


def test_s3_results_open_over_http(tmp_path, moto):
    # CreateBucket: moto takes unsigned requests.
    urllib.request.urlopen(urllib.request.Request(f"{moto}/results", method="PUT")).close()
    env = dict(
        os.environ,
        AWS_ENDPOINT_URL=moto,
        AWS_ACCESS_KEY_ID="testing",
        AWS_SECRET_ACCESS_KEY="testing",
        AWS_REGION="us-east-1",
    )
    server, url = start_server(
        ["--data", str(tmp_path / "data"), "--store", "s3://results/mpm"], env=env
    )
    try:
        job = run_job(url, example("vibrating-bar.json"))
        assert job["status"] == "succeeded"

        # Through the API, exactly as with a local store.
        g, x = open_bar_results(url, job)

        # Straight from the bucket: the objects under `mpm/<id>/results.zarr/` are the
        # store's keys, so copying them as files gives a store zarr-python opens (boto3
        # comes with moto; s3fs is not needed for this).
        boto3 = pytest.importorskip("boto3")
        s3 = boto3.client(
            "s3",
            endpoint_url=moto,
            aws_access_key_id="testing",
            aws_secret_access_key="testing",
            region_name="us-east-1",
        )
        prefix = f"mpm/{job['id']}/results.zarr/"
        keys = [
            o["Key"]
            for page in s3.get_paginator("list_objects_v2").paginate(Bucket="results", Prefix=prefix)
            for o in page.get("Contents", [])
        ]
        with urllib.request.urlopen(f"{url}/v1/jobs/{job['id']}/files") as r:
            assert sorted(k[len(prefix):] for k in keys) == json.load(r)["files"]
        direct_dir = tmp_path / "direct.zarr"
        for key in keys:
            path = direct_dir / key[len(prefix):]
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(s3.get_object(Bucket="results", Key=key)["Body"].read())
        direct = zarr.open_group(str(direct_dir), mode="r")
        assert direct.attrs["metrics"] == g.attrs["metrics"]
        np.testing.assert_array_equal(direct["particles/x"][:], x)
        # Nothing of the job stays in the service's scratch folder once it is uploaded.
        assert not (tmp_path / "data" / "scratch" / job["id"]).exists()
    finally:
        server.kill()
        server.wait()
