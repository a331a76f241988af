#!/usr/bin/env python3
"""Finds loops GCC may have miscompiled with AVX masked loads (decisions D55).

GCC before 14 (Debian 12 has 12.2) can vectorise conditional loads from an interleaved group — `t[c] > 0 ?
x[c] / t[c] : 0` over an array of three channels — with AVX masked loads and give every vector of the group the
first vector's mask (the closest upstream report is GCC PR 114375, wrong code from masked loads in SLP groups,
fixed in 2024). It made the image fit count a black channel as 1 on an AVX-512 CPU (commit 4abf79d); nothing
warns. Turning the vectoriser's if-conversion off avoids it but costs the trainer 3x (its networks' loops are
if-converted), so the build keeps GCC's final GIMPLE of every translation unit instead (CMakeLists.txt) and this
audit reads it: a vector .MASK_LOAD whose mask another vector .MASK_LOAD of the same function shares is the
fault's signature (two arrays read under one condition share a mask correctly too: such a site is rewritten or
read by hand). Exit status 1 if one is found.

    .venv/bin/python scripts/audit_mask_loads.py --dumps build                   # what the build kept (CTest)
    .venv/bin/python scripts/audit_mask_loads.py --build build/cycles --only kernel/device/cpu/kernel.cpp
                                                        # recompiles (Cycles' kernel with the closure headers)
    .venv/bin/python scripts/audit_mask_loads.py --control c++ tests/data/masked_load_fault.cpp
                                                        # the audit catches the fault where the compiler has it
"""
from __future__ import annotations

import argparse
import glob
import json
import os
import re
import shlex
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor

# ";; Function NAME (MANGLED, funcdef_no=..."; the mangled name tells overloads apart.
FUNCTION = re.compile(r"^;; Function (.*) \((\S+), funcdef_no=")
# .MASK_LOAD (address, alignment, mask) with a vector result; .MASK_STORE (address, alignment, mask, value).
MASK_LOAD = re.compile(r"\bvect_\S+ = \.MASK_LOAD \([^,]+, [^,]+, ([^,)]+)\)")
MASK_STORE = re.compile(r"\.MASK_STORE \(")
# The options under which GCC 12 takes the faulty path on every AVX target tried (x86-64-v3, -v4, Haswell,
# Skylake-AVX512, Ice Lake, Zen 3/4): the control compiles the fault's loop with them.
CONTROL_OPTIONS = ["-O3", "-march=native", "-ffp-contract=off", "-fno-trapping-math", "-mprefer-vector-width=256"]


def masked_sites(dump: str) -> dict[str, tuple[int, int]]:
    """Function -> (vector masked loads and stores, loads among them that share their mask with another load)."""
    counts: dict[str, list] = {}
    function = "?"
    with open(dump, errors="replace") as f:
        for line in f:
            m = FUNCTION.match(line)
            if m:
                function = f"{m.group(1)} [{m.group(2)}]"
                continue
            load = MASK_LOAD.search(line)
            if load or MASK_STORE.search(line):
                c = counts.setdefault(function, [0, {}])
                c[0] += 1
                if load:
                    c[1][load.group(1)] = c[1].get(load.group(1), 0) + 1
    return {fn: (n, sum(k for k in masks.values() if k > 1)) for fn, (n, masks) in counts.items()}


def report(found: dict[str, dict[str, tuple[int, int]]], units: int) -> int:
    for path, sites in sorted(found.items()):
        for function, (n, shared) in sorted(sites.items()):
            flag = "  <- loads sharing a mask" if shared else ""
            print(f"{path}: {function}: {n} vector masked load(s)/store(s){flag}")
    total = sum(n for s in found.values() for n, _ in s.values())
    shared = sum(k for s in found.values() for _, k in s.values())
    print(f"{units} translation units, {total} vector masked loads/stores in "
          f"{sum(map(len, found.values()))} functions, {shared} loads sharing a mask")
    return 1 if shared else 0


def progress(done: int, total: int, name: str) -> None:
    if sys.stderr.isatty():
        print(f"\r[{done}/{total}] {name[:60]:60}", end="" if done < total else "\n", file=sys.stderr, flush=True)


def object_of(dump: str) -> str:
    """GCC names a dump after its object: X.cpp.o's is X.cpp.cpp.252t.optimized."""
    return re.sub(r"\.[^./]+\.\d+t\.optimized$", ".o", dump)


def scan_dumps(root: str) -> int:
    dumps = sorted(glob.glob(os.path.join(root, "**", "*.optimized"), recursive=True))
    # Only the translation units the build compiles now: a deleted or renamed source leaves its dump behind.
    db = os.path.join(root, "compile_commands.json")
    if os.path.exists(db):
        outputs = set()
        for e in compile_commands(root):
            args = e["arguments"] if "arguments" in e else shlex.split(e["command"])
            if "-o" in args:
                outputs.add(os.path.abspath(os.path.join(e["directory"], args[args.index("-o") + 1])))
        dumps = [d for d in dumps if os.path.abspath(object_of(d)) in outputs]
    if not dumps:
        print(f"audit_mask_loads: no GCC tree dumps (*.optimized) under {root}: the build keeps them only with "
              "GCC before 14 and NY_NATIVE (CMakeLists.txt)", file=sys.stderr)
        return 2
    found = {}
    for k, dump in enumerate(dumps, 1):
        progress(k, len(dumps), os.path.basename(dump))
        sites = masked_sites(dump)
        if sites:
            found[os.path.relpath(dump, root)] = sites
    return report(found, len(dumps))


def compile_commands(build: str) -> list[dict]:
    path = os.path.join(build, "compile_commands.json")
    if os.path.exists(path):
        with open(path) as f:
            return json.load(f)
    # A ninja build without CMake's export (Cycles' own): ask ninja.
    out = subprocess.run(["ninja", "-C", build, "-t", "compdb"], check=True, capture_output=True, text=True).stdout
    return json.loads(out)


def dump_command(entry: dict, dump: str) -> list[str]:
    args = entry["arguments"] if "arguments" in entry else shlex.split(entry["command"])
    # A compiler launcher first (Cycles' build starts every compile with ccache): run the compiler itself.
    while args and os.path.basename(args[0]) in ("ccache", "sccache"):
        args = args[1:]
    kept, skip = [], False
    for a in args:
        if skip:
            skip = False
        elif a in ("-o", "-MF", "-MT", "-MQ"):
            skip = True
        elif a not in ("-MD", "-MMD"):
            kept.append(a)
    return kept + ["-o", os.devnull, f"-fdump-tree-optimized={dump}"]


def recompile(build: str, only: list[str], jobs: int) -> int:
    entries = [e for e in compile_commands(build) if any(s in e["file"] for s in only)]
    if not entries:
        print(f"audit_mask_loads: no translation unit in {build} matches {only}", file=sys.stderr)
        return 2
    found, failed = {}, []
    with tempfile.TemporaryDirectory() as tmp:
        def one(k_entry):
            k, e = k_entry
            dump = os.path.join(tmp, f"{k}.optimized")
            r = subprocess.run(dump_command(e, dump), cwd=e["directory"], stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL)
            return e["file"], masked_sites(dump) if r.returncode == 0 and os.path.exists(dump) else None

        with ThreadPoolExecutor(jobs) as pool:
            for done, (path, sites) in enumerate(pool.map(one, enumerate(entries)), 1):
                progress(done, len(entries), os.path.basename(path))
                if sites is None:
                    failed.append(path)
                elif sites:
                    found[path] = sites
    for path in failed:
        print(f"audit_mask_loads: could not recompile {path}", file=sys.stderr)
    return 2 if failed else report(found, len(entries))


def control(cxx: str, source: str) -> int:
    """Compiles the fault's loop so that GCC 12 takes the faulty path, runs it, and requires the audit to flag
    its dump whenever the program's answer is wrong."""
    with tempfile.TemporaryDirectory() as tmp:
        exe, dump = os.path.join(tmp, "fault"), os.path.join(tmp, "fault.optimized")
        subprocess.run([cxx, *CONTROL_OPTIONS, source, "-o", exe, f"-fdump-tree-optimized={dump}"], check=True)
        run = subprocess.run([exe], capture_output=True, text=True)
        sites = masked_sites(dump)
    shared = sum(k for _, k in sites.values())
    miscompiled = run.returncode != 0
    print(f"{cxx} {' '.join(CONTROL_OPTIONS)}: {run.stdout.strip()}; the audit sees {shared} loads sharing a mask")
    if miscompiled and not shared:
        print("audit_mask_loads: the compiler miscompiled the fault's loop and the audit did not see it",
              file=sys.stderr)
        return 1
    if not miscompiled:
        print("this compiler computes the fault's loop right (nothing to catch)")
    return 0


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    mode = ap.add_mutually_exclusive_group(required=True)
    mode.add_argument("--dumps", metavar="DIR", help="scan the GCC tree dumps a build kept under DIR")
    mode.add_argument("--build", metavar="DIR", help="recompile the translation units of a CMake/ninja build")
    mode.add_argument("--control", nargs=2, metavar=("CXX", "SOURCE"),
                      help="compile and run the fault's loop; the audit must flag it where it is miscompiled")
    ap.add_argument("--only", nargs="*", default=["cpp_core/", "tests/"],
                    help="with --build: translation units whose path contains one of these (default cpp_core/ tests/)")
    ap.add_argument("--jobs", type=int, default=2, help="with --build: compilers at once")
    a = ap.parse_args(argv)
    root = a.dumps or a.build
    if root and not os.path.isdir(root):
        print(f"audit_mask_loads: no build directory {root}", file=sys.stderr)
        return 2
    if a.dumps:
        return scan_dumps(a.dumps)
    if a.build:
        return recompile(a.build, a.only, a.jobs)
    return control(*a.control)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
