"""`mpm bench --peer taichi`: the Taichi program of the cube drop computes the same motion.

Runs the real `mpm` binary (MPM_BIN) with this venv's Python, which has the `taichi` package
(requirements.txt), on the cube drop at 16³ cells for 2,000 steps: the cube falls, hits the
slip floor (about step 1,300) and bounces, so the walls, the stress and the transfers all
act. The two centres of mass must agree to the tolerance `mpm bench` states (1e-6 cells);
both speeds must be measured.
"""

import json
import os
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[2]
MPM = os.environ.get("MPM_BIN", str(ROOT / "target" / "release" / "mpm"))


def test_taichi_peer_follows_the_same_trajectory():
    done = subprocess.run(
        [MPM, "bench", "--peer", "taichi", "--size", "16", "--steps", "2000", "--json",
         "--python", sys.executable],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    doc = json.loads(done.stdout)
    (case,) = doc["cases"]
    assert case["cells"] == 16
    assert case["mpm"]["particles"] == case["peer"]["particles"] == 12**3
    assert case["mpm"]["steps"] == case["peer"]["steps"] == 2000
    assert case["com_samples"] == 11
    assert case["com_difference"] <= case["com_tolerance"] == 1e-6 / 16
    # The cube fell onto the floor and came back up: the comparison saw the impact.
    heights = [s["com"][1] for s in case["peer"]["trajectory"]]
    lowest = min(range(len(heights)), key=heights.__getitem__)
    assert heights[0] - heights[lowest] > 0.1
    assert 0 < lowest < len(heights) - 1
    assert case["mpm"]["particle_steps_per_second"] > 0
    assert case["peer"]["particle_steps_per_second"] > 0
    assert case["ratio"] > 0
