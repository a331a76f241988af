#!/usr/bin/env python3
"""Two radiance distribution map files compared bin by bin against their own noise.

    .venv/bin/python scripts/compare_maps.py A.nyrdm B.nyrdm [--max-rel-se 0.3]

A change to the random walk that is meant to leave the maps' expectation alone (a faster sampler, issue 21)
cannot keep them bit for bit; what it must keep is the distribution. Gather both files with `--variance`
(independent seeds, same preset, bins and layouts). For P(T), R and M this prints, over the bins whose relative
standard error is at most --max-rel-se in both files (the standard error of a sparse bin is itself too noisy
to divide by), the z-scores z = (a - b) / sqrt(se_a^2 + se_b^2): their mean, their RMS (1 when the maps
differ by noise alone), the largest |z| and the share beyond 4; then the energies T, R, M of both summaries.
Two seeds of one build give the RMS that noise alone gives (a little below 1 at paper-like bins: the standard
errors' own noise and the selection of well-estimated bins; compare only beside such a pair); a change that moves the expectation by a fraction of the noise per bin shows as a larger RMS
over the millions of bins of a paper-resolution map.
"""
from __future__ import annotations

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import evaluate  # noqa: E402

DTYPES = {"u64": np.uint64, "f32": np.float32, "f64": np.float64}


def read_arrays(path: str, names: list[str]) -> dict[str, np.ndarray]:
    """The named arrays of a map file (memory-mapped, read-only); ValueError where one is missing."""
    header = evaluate.map_header(path)
    listed = {a["name"]: a for a in header["arrays"]}
    missing = [n for n in names if n not in listed]
    if missing:
        hint = " (gather with --variance)" if any(n.endswith("_se") for n in missing) else ""
        raise ValueError(f"{path}: no array {', '.join(missing)}{hint}")
    out = {}
    for n in names:
        a = listed[n]
        out[n] = np.memmap(path, dtype=DTYPES[a["dtype"]], mode="r", offset=header["payload_start"] + a["offset"],
                           shape=tuple(a["shape"]))
    return out


def same_settings(a: dict, b: dict) -> list[str]:
    """What differs between two headers that must not (the maps would estimate different things)."""
    problems = []
    if a["bins"] != b["bins"]:
        problems.append("bins")
    if a["preset"] != b["preset"]:
        problems.append("fiber parameters")
    ga, gb = a["geometry"], b["geometry"]
    for key in ("packing_seed", "layouts", "mirror_pair", "slab_length"):
        if ga.get(key) != gb.get(key):
            problems.append(f"geometry {key}")
    if a["gather"].get("symmetrized") != b["gather"].get("symmetrized"):
        problems.append("symmetrisation")
    return problems


def z_scores(a: np.ndarray, se_a: np.ndarray, b: np.ndarray, se_b: np.ndarray, max_rel_se: float) -> np.ndarray:
    """(a - b) / sqrt(se_a^2 + se_b^2) over the bins both estimate to within max_rel_se."""
    a, se_a, b, se_b = (np.asarray(x, dtype=np.float64).ravel() for x in (a, se_a, b, se_b))
    keep = (se_a > 0) & (se_b > 0) & (se_a <= max_rel_se * a) & (se_b <= max_rel_se * b)
    return (a[keep] - b[keep]) / np.sqrt(se_a[keep] ** 2 + se_b[keep] ** 2)


def compare(path_a: str, path_b: str, max_rel_se: float = 0.3) -> dict:
    """Per map (p_t, r, m): the bins compared and their z-scores' mean, RMS, largest |z| and share beyond 4; and
    both headers. Raises ValueError where the files' settings differ."""
    if not max_rel_se > 0:
        raise ValueError("--max-rel-se must be positive")
    ha, hb = evaluate.map_header(path_a), evaluate.map_header(path_b)
    problems = same_settings(ha, hb)
    if problems:
        raise ValueError(f"{path_a} and {path_b} differ in {', '.join(problems)}: their maps estimate different things")
    names = ["p_t", "p_t_se", "r", "r_se", "m", "m_se"]
    ma, mb = read_arrays(path_a, names), read_arrays(path_b, names)
    stats = {}
    for name in ("p_t", "r", "m"):
        z = z_scores(ma[name], ma[name + "_se"], mb[name], mb[name + "_se"], max_rel_se)
        stats[name] = {"bins": int(z.size)}
        if z.size:
            stats[name].update(mean=float(z.mean()), rms=float(np.sqrt(np.mean(z * z))), max=float(np.abs(z).max()),
                               beyond_4=float(np.mean(np.abs(z) > 4)))
    return {"maps": stats, "headers": (ha, hb)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("a")
    ap.add_argument("b")
    ap.add_argument("--max-rel-se", type=float, default=0.3,
                    help="compare only bins whose relative standard error is at most this in both files")
    args = ap.parse_args(argv)
    try:
        result = compare(args.a, args.b, args.max_rel_se)
    except ValueError as e:
        raise SystemExit(str(e))
    ha, hb = result["headers"]
    if ha["gather"]["seed"] == hb["gather"]["seed"]:
        print(f"warning: both files have path seed {ha['gather']['seed']}: their paths are not independent",
              file=sys.stderr)
    print(f"{'map':<4} {'bins':>10} {'mean z':>8} {'rms z':>7} {'max |z|':>8} {'|z|>4':>9}")
    for name, st in result["maps"].items():
        if not st["bins"]:
            print(f"{name:<4} {0:>10}")
            continue
        print(f"{name:<4} {st['bins']:>10} {st['mean']:>+8.4f} {st['rms']:>7.4f} {st['max']:>8.2f} {st['beyond_4']:>9.2e}")
    for label, h in (("A", ha), ("B", hb)):
        s = h["summary"]
        print(f"{label} seed {h['gather']['seed']}, {float(h['gather']['paths']):.3g} paths, energy (RGB): "
              + ", ".join(f"{k} " + " ".join(f"{v:.5f}" for v in s[f"energy_{k}"]) for k in ("T", "R", "M")))
    return 0


if __name__ == "__main__":
    sys.exit(main())
