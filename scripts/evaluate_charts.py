#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Speed against error, from the evaluation harness's results.json (scripts/evaluate.py): the curves, the
speed-ups at equal error and the charts.

A method's curve in a (scene, preset, light) group is its points over the samples per pixel: render seconds
and mean HDR-FLIP against reference A, FLIP the mean over seeds (its spread over seeds kept). Render seconds
are spp times the method's time per sample, measured on its renders of the most samples (the median over
seeds of render seconds / spp): Cycles' cost is linear in the samples, and the render part of a few-sample
render of a small image is shorter than the noise of the wall time it is measured by (wall minus load). The time a
method needs to reach an error level is read off its curve by interpolating log time against log FLIP
between the first point at or below the level and the one before it; at or below the level at its first
point, the first point's time is an upper bound; never below it, there is no time.

Speed-up of a method over explicit fibers at equal FLIP, per group: at the lowest error both curves reach
(the larger of the two minima), explicit's time over the method's. A biased method levels off at its bias, so
that is the level where it stops improving; explicit fibers keep improving. Speed-up at equal samples: the
ratio of render times at each spp both have (their median). Memory ratio: peak memory above the empty
scene's, explicit over the method (median over the groups; Cycles' own memory is the baseline).

    .venv/bin/python scripts/evaluate_charts.py DIR    recomputes DIR/results.json's summary, redraws DIR/charts, prints it
"""
from __future__ import annotations

import json
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir, "addon"))
from geometry import lod  # noqa: E402  (addon/geometry: pure numpy; Auto's rule is the add-on's own)

REFERENCE_METHOD = "explicit"
CLOSEUP_DISTANCE = 12.0  # cycles-scene's default camera distance (ply radii)
#: The log axis's floor for render times (a method whose time per sample rounds to nothing).
MIN_SECONDS = 1e-4


def group_of(r: dict) -> tuple:
    """(scene, preset, light, camera distance) of a run or noise-floor record."""
    return r["scene"], r["preset"], r["light"], r.get("distance") or CLOSEUP_DISTANCE


def at_own_distance(group: tuple) -> bool:
    """Whether a group's camera is its scene's own (the close-ups' 12, or any garment's framing)."""
    return group[0] not in ("closeup", "yarn") or group[3] in (None, CLOSEUP_DISTANCE)


def label(group: tuple) -> str:
    """The scene in the tables: `closeup`, or `closeup d48` at another camera distance."""
    return group[0] if at_own_distance(group) else f"{group[0]} d{group[3]:g}"


def stem(group: tuple) -> str:
    """The file-name stem of a group's scenes, references, strips and charts."""
    return "_".join(group[:3]) + ("" if at_own_distance(group) else f"_d{group[3]:g}")


def curves(results: dict) -> dict:
    """(scene, preset, light, distance) -> method -> list of {"spp", "seconds", "flip", "flip_sd", "seeds"} sorted by spp,
    from the runs that did not fail."""
    acc: dict = {}
    for r in results["runs"]:
        if r["failed"] or r["flip"] is None or r["seconds_render"] is None:
            continue
        acc.setdefault(group_of(r), {}).setdefault(r["method"], {}).setdefault(
            r["spp"], []).append(r)
    out: dict = {}
    for group, methods in acc.items():
        for method, by_spp in methods.items():
            top = max(by_spp)
            per_sample = float(np.median([x["seconds_render"] / top for x in by_spp[top]]))
            pts = []
            for spp in sorted(by_spp):
                rs = by_spp[spp]
                flips = [x["flip"] for x in rs]
                pts.append({"spp": spp, "seconds": max(MIN_SECONDS, spp * per_sample),
                            "seconds_measured": float(np.mean([x["seconds_render"] for x in rs])),
                            "flip": float(np.mean(flips)), "flip_sd": float(np.std(flips)), "seeds": len(rs)})
            out.setdefault(group, {})[method] = pts
    return out


def time_to_reach(curve: list[dict], level: float) -> tuple[float | None, bool]:
    """(seconds, upper_bound) for the curve to reach FLIP `level`; (None, False) if it never does."""
    for i, p in enumerate(curve):
        if p["flip"] <= level:
            if i == 0:
                return p["seconds"], True
            q = curve[i - 1]
            lf0, lf1 = math.log(q["flip"]), math.log(p["flip"])
            w = (math.log(level) - lf0) / (lf1 - lf0) if lf1 != lf0 else 1.0
            return math.exp(math.log(q["seconds"]) + w * (math.log(p["seconds"]) - math.log(q["seconds"]))), False
    return None, False


def equal_flip_speedup(method_curve: list[dict], reference_curve: list[dict]) -> dict | None:
    """{"flip", "seconds_reference", "seconds_method", "speedup", "bound"} at the lowest FLIP both reach; bound
    "lower" or "upper" when the method's or the reference's time is only an upper bound there."""
    if not method_curve or not reference_curve:
        return None
    level = max(min(p["flip"] for p in method_curve), min(p["flip"] for p in reference_curve))
    t_m, m_bound = time_to_reach(method_curve, level)
    t_r, r_bound = time_to_reach(reference_curve, level)
    if t_m is None or t_r is None:
        return None
    bound = "lower" if m_bound and not r_bound else "upper" if r_bound and not m_bound else (
        "unknown" if m_bound and r_bound else None)
    return {"flip": level, "seconds_reference": t_r, "seconds_method": t_m, "speedup": t_r / t_m, "bound": bound}


def flip_at(curve: list[dict], seconds: float) -> float:
    """The curve's FLIP at a render time: log-log interpolation between its points, its end points' FLIP
    beyond them (a method given more time than its longest render is taken at that render's error)."""
    if seconds <= curve[0]["seconds"]:
        return curve[0]["flip"]
    for q, p in zip(curve, curve[1:]):
        if seconds <= p["seconds"]:
            w = math.log(seconds / q["seconds"]) / math.log(p["seconds"] / q["seconds"])
            return math.exp(math.log(q["flip"]) + w * (math.log(p["flip"]) - math.log(q["flip"])))
    return curve[-1]["flip"]


def against_others_at_equal_time(curve: list[dict], others: dict) -> dict | None:
    """At each point of `curve`, its FLIP over the best of `others` (method -> curve) at the same render time:
    {"worst_ratio" (the largest: below 1, closer at every time), "best_other" (the method of the worst point)}."""
    if not curve or not others:
        return None
    worst, who = 0.0, None
    for p in curve:
        best = min((flip_at(c, p["seconds"]), m) for m, c in others.items())
        if p["flip"] / best[0] > worst:
            worst, who = p["flip"] / best[0], best[1]
    return {"worst_ratio": worst, "best_other": who}


def memory_above_baseline(results: dict, group: tuple, method: str) -> float | None:
    rs = [r for r in results["runs"] if group_of(r) == group and r["method"] == method
          and not r["failed"] and r["peak_rss_mb"] and r["baseline_rss_mb"]]
    if not rs:
        return None
    return float(np.median([r["peak_rss_mb"] - r["baseline_rss_mb"] for r in rs]))


def speed_summary(results: dict, reference: str = REFERENCE_METHOD) -> dict:
    """results.json's `summary`: per scene (and distance: `closeup d48`), per method other than `reference` (explicit
    fibers; the levels of detail are also measured against the ply level, `native`: `summary_over_plies`),
    `speedup_equal_flip` and `speedup_equal_spp` (the median over groups, and every group's value), and
    `memory_ratio`."""
    cs = curves(results)
    # The artist's stock closures the run fitted (evaluate.py), against which the neural model is compared.
    baseline_methods = {b["method"] for b in results.get("baselines", [])}
    summary: dict = {}
    for group, methods in sorted(cs.items()):
        scene = label(group)
        ref = methods.get(reference)
        if not ref:
            continue
        ref_mem = memory_above_baseline(results, group, reference)
        for method, curve in methods.items():
            if method == reference:
                continue
            entry = summary.setdefault(scene, {}).setdefault(method, {"groups": []})
            eq = equal_flip_speedup(curve, ref)
            ref_t = {p["spp"]: p["seconds"] for p in ref}
            at_spp = [ref_t[p["spp"]] / p["seconds"] for p in curve if p["spp"] in ref_t]
            mem = memory_above_baseline(results, group, method)
            baselines = {m: c for m, c in methods.items() if m in baseline_methods}
            entry["groups"].append({
                "against_baselines_equal_time": against_others_at_equal_time(curve, baselines)
                if method not in baseline_methods else None,
                "preset": group[1], "light": group[2], "equal_flip": eq,
                "speedup_equal_spp": float(np.median(at_spp)) if at_spp else None,
                "memory_ratio": ref_mem / mem if ref_mem is not None and mem and mem > 0 else None})
    for scene in summary.values():
        for entry in scene.values():
            gs = entry["groups"]
            eq = [g["equal_flip"]["speedup"] for g in gs if g["equal_flip"]]
            spp = [g["speedup_equal_spp"] for g in gs if g["speedup_equal_spp"] is not None]
            mem = [g["memory_ratio"] for g in gs if g["memory_ratio"] is not None]
            entry["speedup_equal_flip"] = float(np.median(eq)) if eq else None
            entry["speedup_equal_spp"] = float(np.median(spp)) if spp else None
            entry["memory_ratio"] = float(np.median(mem)) if mem else None
    return summary


#: The levels of detail (D27, D44) are also measured against the ply level.
LEVELS_OVER = ("native", ("yarns", "surface"))


def level_summary(results: dict) -> dict | None:
    """`summary_over_plies`: speed_summary against the ply level (`native`) when a run has it and a coarser level."""
    methods = {r["method"] for r in results["runs"]}
    if LEVELS_OVER[0] not in methods or not methods & set(LEVELS_OVER[1]):
        return None
    return speed_summary(results, LEVELS_OVER[0])


def ply_widths(results: dict) -> dict:
    """(scene, camera distance) -> the ply's width in pixels there, from the run's cameras that record it."""
    return {(sc, float(d)): v["ply_pixels"] for sc, cam in results.get("scenes", {}).items()
            for d, v in cam.get("distances", {}).items() if v.get("ply_pixels") is not None}


#: The harness's methods that are levels of detail (D27), as the add-on's Auto names them (the surface level is
#: drawn only when asked for: Auto never chooses it).
LEVEL_OF_METHOD = {"explicit": "fibers", "native": "plies", "yarns": "yarns"}
#: Issue 18's goal: Auto within 10 % of the most accurate level's FLIP, and of the fastest time to that FLIP.
AUTO_TOLERANCE = 0.10


def auto_summary(results: dict) -> list[dict]:
    """results.json's `auto`: per group with two or more levels and a camera whose ply width is known, the level
    the add-on's Auto draws for that width (addon/geometry/lod.py, the same function the add-on calls), its
    FLIP at the run's most samples against the most accurate level's, and its time to that FLIP against the
    fastest level's that reaches it (times from the curves, as for the speed-ups). `flip_ok` / `time_ok`: within
    AUTO_TOLERANCE; None where Auto's level was not rendered."""
    widths = ply_widths(results)
    rows = []
    for group, methods in sorted(curves(results).items()):
        levels = {LEVEL_OF_METHOD[m]: c for m, c in methods.items() if m in LEVEL_OF_METHOD}
        px = widths.get((group[0], float(group[3])))
        if len(levels) < 2 or px is None:
            continue
        flip = {lv: c[-1]["flip"] for lv, c in levels.items()}  # at the run's most samples
        best = min(flip, key=flip.get)
        auto = lod.level_for_ply_pixels(px)
        row = {"scene": group[0], "preset": group[1], "light": group[2], "distance": group[3], "ply_pixels": px,
               "auto": auto, "best": best, "flip": flip, "flip_ratio": None, "flip_ok": None,
               "fastest": None, "time_ratio": None, "time_ok": None}
        if auto in flip:
            row["flip_ratio"] = flip[auto] / flip[best]
            row["flip_ok"] = row["flip_ratio"] <= 1.0 + AUTO_TOLERANCE
            reach = {lv: time_to_reach(c, flip[auto])[0] for lv, c in levels.items()}
            reach = {lv: t for lv, t in reach.items() if t is not None}
            row["fastest"] = min(reach, key=reach.get)
            row["time_ratio"] = reach[auto] / reach[row["fastest"]]
            row["time_ok"] = row["time_ratio"] <= 1.0 + AUTO_TOLERANCE
        rows.append(row)
    return rows


def auto_table(rows: list[dict]) -> str:
    """Markdown of auto_summary's rows."""
    lines = ["| scene | preset | light | ply px | FLIP per level | Auto | most accurate | Auto / best FLIP | "
             "fastest to Auto's FLIP | Auto / its time |", "|---|---|---|---|---|---|---|---|---|---|"]

    def ok(v, good):
        return "-" if v is None else f"{v:.2f}" + ("" if good else " ✗")

    for r in rows:
        flips = ", ".join(f"{lv} {f:.3f}" for lv, f in sorted(r["flip"].items()))
        lines.append(f"| {r['scene']} | {r['preset']} | {r['light']} | {r['ply_pixels']:.2f} | {flips} | {r['auto']} | "
                     f"{r['best']} | {ok(r['flip_ratio'], r['flip_ok'])} | {r['fastest'] or '-'} | "
                     f"{ok(r['time_ratio'], r['time_ok'])} |")
    return "\n".join(lines) + "\n"


def summary_table(results: dict, key: str = "summary", reference: str = REFERENCE_METHOD) -> str:
    """Markdown: per group and method, the equal-FLIP level, both times and the speed-ups; then per scene."""
    summ = results.get(key) or {}
    lines = [f"| scene | preset | light | method | equal FLIP | {reference} s | method s | speed-up at equal FLIP "
             "| speed-up at equal spp | memory ratio | FLIP / best baseline's at equal time (worst) |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    mark = {"lower": "≥ ", "upper": "≤ ", "unknown": "~ ", None: ""}

    def fmt(v, spec):
        return format(v, spec) if v is not None else "-"

    for scene, methods in summ.items():
        for method, e in methods.items():
            for g in e["groups"]:
                q = g["equal_flip"] or {}
                lines.append(f"| {scene} | {g['preset']} | {g['light']} | {method} | {fmt(q.get('flip'), '.3f')} | "
                             f"{fmt(q.get('seconds_reference'), '.2f')} | {fmt(q.get('seconds_method'), '.2f')} | "
                             f"{mark[q.get('bound')] if q else ''}{fmt(q.get('speedup'), '.1f')} | "
                             f"{fmt(g['speedup_equal_spp'], '.1f')} | {fmt(g['memory_ratio'], '.2f')} | "
                             + (f"{g['against_baselines_equal_time']['worst_ratio']:.2f} "
                                f"({g['against_baselines_equal_time']['best_other']}) |"
                                if g.get("against_baselines_equal_time") else "- |"))
    lines += ["", "| scene | method | speed-up at equal FLIP (median) | at equal spp (median) | memory ratio (median) |",
              "|---|---|---|---|---|"]
    for scene, methods in summ.items():
        for method, e in methods.items():
            lines.append(f"| {scene} | {method} | {fmt(e['speedup_equal_flip'], '.1f')} | "
                         f"{fmt(e['speedup_equal_spp'], '.1f')} | {fmt(e['memory_ratio'], '.2f')} |")
    return "\n".join(lines) + "\n"


def pareto(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """The points no other point beats in both time and error, by time."""
    front, best = [], math.inf
    for t, f in sorted(points):
        if f < best:
            front.append((t, f))
            best = f
    return front


def error_time_charts(out: str, results: dict) -> list[str]:
    """DIR/charts/<scene>_<preset>_<light>_flip_time.png per group (FLIP against render seconds, log-log, one
    curve per method with its spread over seeds, the Pareto front, the references' noise floor) and
    DIR/charts/flip_time.png (all groups). Returns the paths."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    cs = curves(results)
    floors = {group_of(f): f["flip"] for f in results["noise_floor"]}
    os.makedirs(os.path.join(out, "charts"), exist_ok=True)
    methods = sorted({m for g in cs.values() for m in g}, key=lambda m: (m != REFERENCE_METHOD, m))
    colour = {m: plt.get_cmap("tab10")(k) for k, m in enumerate(methods)}
    groups = sorted(cs)
    paths = []

    def draw(ax, group, legend):
        pts = []
        for m in methods:
            c = cs[group].get(m)
            if not c:
                continue
            t = [p["seconds"] for p in c]
            f = [p["flip"] for p in c]
            ax.errorbar(t, f, yerr=[p["flip_sd"] for p in c], color=colour[m], marker="o", ms=3, lw=1, capsize=2,
                        label=m)
            for p in c:
                ax.annotate(str(p["spp"]), (p["seconds"], p["flip"]), fontsize=5, color=colour[m],
                            xytext=(2, 2), textcoords="offset points")
            pts += list(zip(t, f))
        front = pareto(pts)
        ax.step([p[0] for p in front], [p[1] for p in front], where="post", color="k", lw=2, alpha=0.25,
                label="Pareto front")
        if floors.get(group):
            ax.axhline(floors[group], color="grey", ls=":", lw=1, label="reference noise floor")
        ax.set_xscale("log")
        ax.set_yscale("log")
        scene = f"{group[0]}: " if len({g[0] for g in groups}) > 1 else ""  # (several scenes in one chart)
        ax.set_title(f"{scene}{group[1]}, {group[2]}" + ("" if at_own_distance(group) else f", distance {group[3]:g}"),
                     fontsize=8)
        ax.tick_params(labelsize=6)
        if legend:
            ax.legend(fontsize=6)

    for group in groups:
        fig, ax = plt.subplots(figsize=(5, 3.6))
        draw(ax, group, True)
        ax.set_xlabel("render seconds (load excluded)")
        ax.set_ylabel("mean HDR-FLIP against the reference")
        fig.tight_layout()
        path = os.path.join(out, "charts", f"{stem(group)}_flip_time.png")
        fig.savefig(path, dpi=120)
        plt.close(fig)
        paths.append(path)
    if groups:
        lights = sorted({g[2] for g in groups}, key=[g[2] for g in groups].index)
        rows = sorted({(g[0], g[1], g[3]) for g in groups}, key=[(g[0], g[1], g[3]) for g in groups].index)
        fig, axes = plt.subplots(len(rows), len(lights), squeeze=False,
                                 figsize=(3.0 * len(lights), 2.4 * len(rows) + 0.5))
        for i, row in enumerate(rows):
            for j, light in enumerate(lights):
                group = (row[0], row[1], light, row[2])
                if group in cs:
                    draw(axes[i][j], group, i == 0 and j == 0)
                else:
                    axes[i][j].axis("off")
        fig.suptitle("mean HDR-FLIP (log) against render seconds (log); numbers: samples per pixel", fontsize=9)
        fig.tight_layout()
        path = os.path.join(out, "charts", "flip_time.png")
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths


def error_distance_charts(out: str, results: dict) -> list[str]:
    """With two or more camera distances: DIR/charts/<scene>_<preset>_<light>_distance.png, FLIP and the mean
    luminance error (of the central region, or the frame where the ply is under 3 rows) at the highest spp
    against the ply's width in pixels, one line per method, the references' noise floor dotted. Returns the
    paths."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    widths = ply_widths(results)
    by: dict = {}
    for r in results["runs"]:
        if r["failed"] or r["flip"] is None:
            continue
        g = group_of(r)
        by.setdefault(g[:3], {}).setdefault(r["method"], {}).setdefault(g[3], {}).setdefault(r["spp"], []).append(r)
    floors = {group_of(f): f for f in results["noise_floor"]}
    os.makedirs(os.path.join(out, "charts"), exist_ok=True)
    paths = []
    for base, methods in sorted(by.items()):
        if len({d for m in methods.values() for d in m}) < 2:
            continue
        fig, (ax_f, ax_l) = plt.subplots(1, 2, figsize=(9, 3.4))
        for k, (method, per_d) in enumerate(sorted(methods.items(), key=lambda kv: (kv[0] != REFERENCE_METHOD, kv[0]))):
            ds = sorted(per_d, key=lambda d: -widths.get((base[0], d), 0.0))
            px = [widths.get((base[0], d), float("nan")) for d in ds]
            top = [per_d[d][max(per_d[d])] for d in ds]
            flip = [float(np.mean([x["flip"] for x in rs])) for rs in top]
            lum = [100 * abs(float(np.mean([x["mean_luminance_error"] for x in rs]))) for rs in top]
            c = plt.get_cmap("tab10")(k)
            ax_f.plot(px, flip, "o-", color=c, ms=3, label=f"{method} ({max(per_d[ds[0]])} spp)")
            ax_l.plot(px, lum, "o-", color=c, ms=3, label=method)
        fl = sorted((widths.get((base[0], g[3]), float("nan")), f) for g, f in floors.items() if g[:3] == base)
        ax_f.plot([w for w, _ in fl], [f["flip"] for _, f in fl], ":", color="grey", label="reference noise floor")
        ax_l.plot([w for w, _ in fl], [100 * abs(f["mean_luminance_error"]) for _, f in fl], ":", color="grey")
        for ax, name in ((ax_f, "mean HDR-FLIP"), (ax_l, "|mean luminance error| %")):
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.invert_xaxis()
            ax.set_xlabel("ply width, pixels (camera farther to the right)")
            ax.set_ylabel(name)
            ax.tick_params(labelsize=7)
        ax_f.legend(fontsize=6)
        fig.suptitle(f"{base[1]}, {base[2]}: error against the ply's size on screen", fontsize=9)
        fig.tight_layout()
        path = os.path.join(out, "charts", f"{'_'.join(base)}_distance.png")
        fig.savefig(path, dpi=120)
        plt.close(fig)
        paths.append(path)
    return paths


def main(argv: list[str]) -> int:
    if len(argv) != 1 or not os.path.isfile(os.path.join(argv[0], "results.json")):
        print("usage: evaluate_charts.py DIR (with DIR/results.json)", file=sys.stderr)
        return 1
    with open(os.path.join(argv[0], "results.json")) as f:
        results = json.load(f)
    results["summary"] = speed_summary(results)
    results["summary_over_plies"] = level_summary(results)
    results["auto"] = auto_summary(results)
    with open(os.path.join(argv[0], "results.json"), "w") as f:
        json.dump(results, f, indent=1)
    for p in error_time_charts(argv[0], results) + error_distance_charts(argv[0], results):
        print(f"wrote {p}", file=sys.stderr)
    print(summary_table(results), end="")
    if results["summary_over_plies"]:
        print("\nAgainst the ply level (native):\n\n" + summary_table(results, "summary_over_plies", "native"), end="")
    if results["auto"]:
        print("\nThe add-on's Auto level against the levels rendered:\n\n" + auto_table(results["auto"]), end="")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
