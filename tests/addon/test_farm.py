# SPDX-License-Identifier: Apache-2.0
"""Frame farms on Dask distributed (addon/farm.py, batch.py --frames; issue 20): a local cluster of 2
workers, one of which is killed while it runs a job; every file arrives whole, nothing half-written is left,
and a re-run skips what is done."""
import os
import signal
import subprocess
import sys
import time

import pytest

ADDON = os.path.abspath(os.path.join(os.path.dirname(__file__), os.pardir, os.pardir, "addon"))


def _farm():
    bpy = sys.modules.get("bpy")
    if bpy is not None and bpy.app.binary_path:
        pytest.skip("inside a Blender executable: the farm's driver and workers run in a Python of their own "
                    "(batch.py --farm-python); the bpy-wheel run covers it")
    pytest.importorskip("distributed")
    sys.path.insert(0, ADDON)
    try:
        import farm
    finally:
        sys.path.remove(ADDON)
    return farm


def _slow_writer(seconds: float) -> list[str]:
    """A job command: sleeps, then writes its output (as a render writes its image at the end)."""
    code = "import sys, time; time.sleep(float(sys.argv[1])); open(sys.argv[2], 'w').write('frame')"
    return [sys.executable, "-c", code, str(seconds), "{out}"]


def test_a_killed_worker_loses_no_job_and_a_rerun_skips_the_done(tmp_path):
    farm = _farm()
    jobs = [farm.Job(f"job {k}", _slow_writer(1.5), str(tmp_path / f"out_{k}.txt")) for k in range(6)]
    killed = {}

    def kill_one_busy_worker(client):
        # Wait until both workers run a job, then SIGKILL one of them mid-job.
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            busy = {w: len(t) for w, t in client.processing().items() if t}
            if len(busy) >= 2:
                break
            time.sleep(0.05)
        pids = client.run(os.getpid)
        worker = sorted(busy)[0]
        killed["pid"] = pids[worker]
        os.kill(pids[worker], signal.SIGKILL)

    res = farm.run_jobs(jobs, workers=2, progress=lambda s: None, on_submitted=kill_one_busy_worker)
    assert "pid" in killed
    assert res["failed"] == {} and sorted(res["done"]) == sorted(j.name for j in jobs)
    for j in jobs:
        assert open(j.out).read() == "frame"
    assert sorted(os.listdir(tmp_path)) == sorted(os.path.basename(j.out) for j in jobs)  # no temporary files
    again = farm.run_jobs(jobs, workers=2, progress=lambda s: None)
    assert again["done"] == [] and len(again["skipped"]) == len(jobs)


def test_a_failing_job_is_reported_and_leaves_no_file(tmp_path):
    farm = _farm()
    bad = farm.Job("bad", [sys.executable, "-c", "import sys; sys.exit('no luck')", "{out}"], str(tmp_path / "b.txt"))
    good = farm.Job("good", _slow_writer(0.0), str(tmp_path / "g.txt"))
    res = farm.run_jobs([bad, good], workers=1, progress=lambda s: None)
    assert res["done"] == ["good"] and "no luck" in res["failed"]["bad"]
    assert sorted(os.listdir(tmp_path)) == ["g.txt"]
