# SPDX-License-Identifier: GPL-3.0-or-later
"""Independent jobs (the frames of an animation, the bakes of several yarns) as tasks on Dask distributed:
an in-process LocalCluster by default, or a running scheduler's address to scale out to other machines.

Each job is a command that writes one file. It writes to a temporary name beside the file, which is moved
into place (an atomic rename) only after the command succeeded, so:
  - a worker killed mid-job loses nothing: Dask gives the task to another worker, and the dead worker's
    command dies with it (it gets SIGKILL when its worker goes, on Linux);
  - a re-run skips every job whose file exists;
  - a half-written file never has the final name.
No bpy here: batch.py (renders) and scripts/bake_farm.py (bakes) build the commands.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
import uuid
from dataclasses import dataclass, field

#: The placeholder in a job's command for the temporary output path.
OUT = "{out}"


class FarmError(RuntimeError):
    pass


@dataclass
class Job:
    name: str
    argv: list[str]  # the command; OUT marks where the output path goes
    out: str  # the final file
    env: dict = field(default_factory=dict)  # added to the environment


def _die_with_parent() -> None:
    """In the job's process, before exec: SIGKILL when the worker that started it dies (Linux prctl)."""
    try:
        import ctypes
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


def run_job(job: Job) -> str:
    """Runs one job on this machine: its command writes a temporary file, which then replaces job.out.
    Returns job.out; raises FarmError with the command's last lines when it fails."""
    folder, base = os.path.split(os.path.abspath(job.out))
    stem, ext = os.path.splitext(base)
    tmp = os.path.join(folder, f".{stem}.{uuid.uuid4().hex[:12]}.tmp{ext}")
    argv = [a.replace(OUT, tmp) for a in job.argv]
    try:
        r = subprocess.run(argv, capture_output=True, text=True, env={**os.environ, **job.env},
                           preexec_fn=_die_with_parent if sys.platform.startswith("linux") else None)
        if r.returncode != 0 or not os.path.isfile(tmp):
            tail = " ".join((r.stderr or r.stdout or "").strip().splitlines()[-3:])
            raise FarmError(f"the command exited with {r.returncode}" + (f": {tail}" if tail else "")
                            + ("" if r.returncode else " and wrote no file"))
        os.replace(tmp, job.out)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
    return job.out


def run_jobs(jobs: list[Job], *, scheduler: str | None = None, workers: int = 2, progress=print,
             on_submitted=None) -> dict:
    """Runs the jobs whose file does not exist yet as Dask tasks: on the scheduler at `scheduler`
    ("tcp://host:8786"), else on a LocalCluster of `workers` single-threaded worker processes. `progress`
    receives one line per finished job; `on_submitted(client)` is called once the tasks are submitted (the
    tests kill a worker there). Returns {"done": [...], "skipped": [...], "failed": {name: reason},
    "seconds": s}; never raises for a failed job (the caller decides), but FarmError if Dask is missing."""
    try:
        import cloudpickle
        from distributed import Client, LocalCluster, as_completed
    except ImportError as e:
        raise FarmError(f"the farm needs Dask distributed ({e}); install it with "
                        "`python -m pip install 'dask[distributed]'` (scripts/setup.sh does, into .venv)") from None
    # The workers cannot import this file as part of the add-on package: send it by value.
    cloudpickle.register_pickle_by_value(sys.modules[__name__])
    t0 = time.monotonic()
    todo = [j for j in jobs if not os.path.isfile(j.out)]
    # Temporary files of runs that were killed outright (the driver too): one listing per folder.
    pending: dict[str, list[tuple[str, str]]] = {}
    for j in todo:
        folder, base = os.path.split(os.path.abspath(j.out))
        pending.setdefault(folder, []).append(os.path.splitext(base))
    for folder, names in pending.items():
        for name in os.listdir(folder) if os.path.isdir(folder) else []:
            if any(name.startswith(f".{stem}.") and name.endswith(f".tmp{ext}") for stem, ext in names):
                os.remove(os.path.join(folder, name))
    skipped = [j.name for j in jobs if os.path.isfile(j.out)]
    out = {"done": [], "skipped": skipped, "failed": {}, "seconds": 0.0}
    if skipped:
        progress(f"farm: {len(skipped)} of {len(jobs)} already done, skipped")
    if not todo:
        return out
    cluster = None
    if scheduler:
        client = Client(scheduler)
    else:
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None)
        client = Client(cluster)
    try:
        futures = {client.submit(run_job, j, key=f"{j.name}-{uuid.uuid4().hex[:8]}", pure=False, retries=1): j
                   for j in todo}
        if on_submitted is not None:
            on_submitted(client)
        for k, f in enumerate(as_completed(futures), 1):
            j = futures[f]
            try:
                f.result()
                out["done"].append(j.name)
                progress(f"farm: [{k}/{len(todo)}] {j.name}: {j.out}")
            except Exception as e:  # the job's own failure, or Dask giving up on it
                out["failed"][j.name] = str(e)
                progress(f"farm: [{k}/{len(todo)}] {j.name}: FAILED, {e}")
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    out["seconds"] = time.monotonic() - t0
    return out


def main(argv: list[str] | None = None) -> int:
    """`python farm.py JOBS.json [--scheduler ADDRESS] [--workers N]`: runs the jobs of a JSON list
    ([{"name", "argv", "out", "env"}]) and prints a line per job; exit code 1 if any failed. The driver runs in
    a Python of its own (with Dask), not inside Blender: Dask's local workers re-import the driver's main
    module, which must not be a script that imports bpy."""
    import argparse
    import json
    ap = argparse.ArgumentParser(prog="farm.py", description=main.__doc__.split("\n")[0])
    ap.add_argument("jobs")
    ap.add_argument("--scheduler")
    ap.add_argument("--workers", type=int, default=2)
    a = ap.parse_args(argv)
    try:
        with open(a.jobs) as f:
            jobs = [Job(j["name"], list(j["argv"]), j["out"], dict(j.get("env", {}))) for j in json.load(f)]
        res = run_jobs(jobs, scheduler=a.scheduler, workers=a.workers, progress=lambda s: print(s, flush=True))
    except (OSError, ValueError, KeyError, TypeError, FarmError) as e:
        print(f"farm: error: {e}", file=sys.stderr)
        return 1
    print(f"farm: {len(res['done'])} done, {len(res['skipped'])} skipped, {len(res['failed'])} failed "
          f"({res['seconds']:.1f} s)", flush=True)
    for name, why in res["failed"].items():
        print(f"farm: error: {name}: {why}", file=sys.stderr)
    return 1 if res["failed"] else 0


if __name__ == "__main__":
    sys.exit(main())
