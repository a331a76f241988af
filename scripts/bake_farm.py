# SPDX-License-Identifier: Apache-2.0
"""Bakes of several yarns as tasks on Dask distributed (addon/farm.py: a local cluster, or a scheduler's
address to spread them over machines), one model file each, written atomically; a re-run bakes only the
missing ones.

    .venv/bin/python scripts/bake_farm.py --out DIR (--presets fleece silk ... | --params a.json b.json ...)
        [--workers 2] [--threads-per-bake 1] [--scheduler tcp://host:8786] [-- extra `neuralyarn bake` options]

DIR/<name>.json per yarn (the preset's name, or the parameter file's stem). Every bake's results do not
depend on its thread count, so a farm's models equal the ones `neuralyarn bake` makes on one machine.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), os.pardir))
CLI = os.path.join(ROOT, "build", "cpp_core", "neuralyarn")
FARM = os.path.join(ROOT, "addon", "farm.py")


def main() -> int:
    argv = sys.argv[1:]
    extra = argv[argv.index("--") + 1:] if "--" in argv else []
    argv = argv[: argv.index("--")] if "--" in argv else argv
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", required=True, help="directory of the model files")
    ap.add_argument("--presets", nargs="+", default=[])
    ap.add_argument("--params", nargs="+", default=[], help="fiber parameter files (JSON)")
    ap.add_argument("--workers", type=int, default=2, help="local cluster workers (default 2)")
    ap.add_argument("--threads-per-bake", type=int, default=1)
    ap.add_argument("--scheduler", help="a Dask scheduler's address (default: a local cluster)")
    a = ap.parse_args(argv)
    if not (a.presets or a.params):
        ap.error("give --presets or --params")
    if not os.access(CLI, os.X_OK):
        ap.error(f"{CLI} is not built (scripts/setup.sh)")
    os.makedirs(a.out, exist_ok=True)
    yarns = [(p, ["--preset", p]) for p in a.presets] + \
            [(os.path.splitext(os.path.basename(f))[0], ["--params", os.path.abspath(f)]) for f in a.params]
    jobs = [{"name": f"bake {name}", "out": os.path.abspath(os.path.join(a.out, f"{name}.json")),
             "argv": [CLI, "bake", *source, "--threads", str(a.threads_per_bake), *extra, "--out", "{out}"]}
            for name, source in yarns]
    with tempfile.NamedTemporaryFile("w", suffix=".json", delete=False) as f:
        json.dump(jobs, f)
    try:
        cmd = [sys.executable, FARM, f.name, "--workers", str(a.workers)]
        return subprocess.run(cmd + (["--scheduler", a.scheduler] if a.scheduler else [])).returncode
    finally:
        os.remove(f.name)


if __name__ == "__main__":
    sys.exit(main())
