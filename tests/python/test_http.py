"""zarr-python opens a job's results directly over HTTP from the real `mpm serve`."""

from mpm_helpers import example, open_bar_results, run_job, start_server


def test_results_open_over_http(tmp_path):
    server, url = start_server(["--data", str(tmp_path / "data")])
    try:
        job = run_job(url, example("vibrating-bar.json"))
        assert job["status"] == "succeeded"
        open_bar_results(url, job)
    finally:
        server.kill()
        server.wait()
