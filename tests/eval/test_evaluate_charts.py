# SPDX-License-Identifier: Apache-2.0
"""Speed against error (scripts/evaluate_charts.py) on synthetic curves whose answers are known: explicit
fibers converge as FLIP = 0.2 (t / 4)^-1/2 (unbiased noise), a biased method levels off at 0.12."""
import math
import os
import sys

import pytest

sys.path.insert(0, os.path.join(os.path.dirname(__file__), os.pardir, os.pardir, "scripts"))
import evaluate_charts as ec  # noqa: E402

EXPLICIT = [{"spp": 1, "seconds": 1.0, "flip": 0.4}, {"spp": 4, "seconds": 4.0, "flip": 0.2},
            {"spp": 16, "seconds": 16.0, "flip": 0.1}]
BIASED = [{"spp": 1, "seconds": 0.1, "flip": 0.3}, {"spp": 4, "seconds": 0.4, "flip": 0.15},
          {"spp": 16, "seconds": 1.6, "flip": 0.12}, {"spp": 64, "seconds": 6.4, "flip": 0.12}]


def test_time_to_reach_interpolates_log_time_against_log_error():
    assert ec.time_to_reach(EXPLICIT, 0.2) == (pytest.approx(4.0), False)
    assert ec.time_to_reach(EXPLICIT, 0.2 / math.sqrt(2)) == (pytest.approx(8.0), False)
    assert ec.time_to_reach(EXPLICIT, 0.5) == (1.0, True)  # below it at once: an upper bound
    assert ec.time_to_reach(EXPLICIT, 0.05) == (None, False)


def test_equal_flip_speedup_at_the_lowest_error_both_reach():
    q = ec.equal_flip_speedup(BIASED, EXPLICIT)
    assert q["flip"] == pytest.approx(0.12)  # the biased method's floor, above explicit's 0.1
    assert q["seconds_method"] == pytest.approx(1.6)
    assert q["seconds_reference"] == pytest.approx(4.0 * (0.2 / 0.12) ** 2)
    assert q["speedup"] == pytest.approx(4.0 * (0.2 / 0.12) ** 2 / 1.6)
    assert q["bound"] is None
    # A method better than explicit's best at its first point: its time is an upper bound, the speed-up a lower one.
    good = [{"spp": 1, "seconds": 0.5, "flip": 0.05}]
    q = ec.equal_flip_speedup(good, EXPLICIT)
    assert (q["flip"], q["seconds_reference"], q["bound"]) == (0.1, pytest.approx(16.0), "lower")
    assert ec.equal_flip_speedup([], EXPLICIT) is None


def test_pareto_front():
    pts = [(1, 0.4), (2, 0.5), (4, 0.2), (0.5, 0.6), (8, 0.2), (16, 0.1)]
    assert ec.pareto(pts) == [(0.5, 0.6), (1, 0.4), (4, 0.2), (16, 0.1)]


def results_of(curves_by_method, peak):
    runs = []
    for method, curve in curves_by_method.items():
        for p in curve:
            for seed, d in ((1, -0.01), (2, 0.01)):  # two seeds around the mean
                runs.append({"scene": "closeup", "preset": "fleece", "light": "grazing", "method": method,
                             "spp": p["spp"], "seed": seed, "seconds_render": p["seconds"], "flip": p["flip"] + d,
                             "peak_rss_mb": peak[method], "baseline_rss_mb": 100.0, "failed": False})
    # A failed run counts nowhere.
    runs.append({**runs[0], "seed": 3, "flip": None, "seconds_render": None, "failed": "cycles exited with 1"})
    return {"runs": runs, "noise_floor": [{"scene": "closeup", "preset": "fleece", "light": "grazing", "flip": 0.05}]}


def test_speed_summary_and_charts(tmp_path):
    res = results_of({"explicit": EXPLICIT, "native": BIASED}, {"explicit": 500.0, "native": 110.0})
    s = ec.speed_summary(res)
    native = s["closeup"]["native"]
    assert native["speedup_equal_flip"] == pytest.approx(4.0 * (0.2 / 0.12) ** 2 / 1.6)
    assert native["speedup_equal_spp"] == pytest.approx(10.0)  # 1/0.1, 4/0.4, 16/1.6
    assert native["memory_ratio"] == pytest.approx(40.0)  # (500 - 100) / (110 - 100)
    assert "explicit" not in s["closeup"]
    c = ec.curves(res)[("closeup", "fleece", "grazing", 12.0)]["explicit"]
    assert [p["seeds"] for p in c] == [2, 2, 2] and c[0]["flip_sd"] == pytest.approx(0.01)
    res["summary"] = s
    assert "| closeup | native | 6.9 | 10.0 | 40.00 |" in ec.summary_table(res)
    paths = ec.error_time_charts(str(tmp_path), res)
    assert [os.path.basename(p) for p in paths] == ["closeup_fleece_grazing_flip_time.png", "flip_time.png"]
    assert all(os.path.getsize(p) > 10000 for p in paths)


def test_error_against_distance_chart(tmp_path):
    """Two camera distances: one chart per (scene, preset, light), the ply's width read from the scenes."""
    res = results_of({"explicit": EXPLICIT, "native": BIASED}, {"explicit": 500.0, "native": 110.0})
    far = [{**r, "distance": 96.0} for r in res["runs"]]
    res["runs"] += far
    res["noise_floor"].append({**res["noise_floor"][0], "distance": 96.0, "mean_luminance_error": 0.01})
    res["noise_floor"][0]["mean_luminance_error"] = 0.02
    for r in res["runs"]:
        r["mean_luminance_error"] = 0.05
    res["scenes"] = {"closeup": {"distances": {"12": {"ply_pixels": 13.8}, "96": {"ply_pixels": 1.7}}}}
    paths = ec.error_distance_charts(str(tmp_path), res)
    assert [os.path.basename(p) for p in paths] == ["closeup_fleece_grazing_distance.png"]
    assert os.path.getsize(paths[0]) > 10000
    # The far groups are their own curves, labelled with the distance.
    assert ("closeup", "fleece", "grazing", 96.0) in ec.curves(res)
    assert "closeup d96" in ec.speed_summary(res)
    # One distance: no chart.
    assert ec.error_distance_charts(str(tmp_path / "one"), results_of({"native": BIASED}, {"native": 110.0})) == []


def test_curve_times_are_spp_times_the_time_per_sample_of_the_longest_renders():
    """A 4-sample render's measured time is noise (here 0, wall time below the load's); the curve's time is
    4 x the time per sample of the 16-sample renders."""
    res = results_of({"explicit": EXPLICIT}, {"explicit": 500.0})
    for r in res["runs"]:
        if r["spp"] == 4:
            r["seconds_render"] = 0.0
    c = ec.curves(res)[("closeup", "fleece", "grazing", 12.0)]["explicit"]
    assert [p["seconds"] for p in c] == pytest.approx([1.0, 4.0, 16.0])
    assert c[1]["seconds_measured"] == 0.0


def test_against_the_baselines_at_equal_render_time():
    chiang = [{"spp": 4, "seconds": 0.05, "flip": 0.25}, {"spp": 16, "seconds": 0.2, "flip": 0.2}]
    assert ec.flip_at(chiang, 0.1) == pytest.approx(math.sqrt(0.25 * 0.2))  # log-log between its points
    assert ec.flip_at(chiang, 10.0) == 0.2 and ec.flip_at(chiang, 0.01) == 0.25  # its ends beyond them
    q = ec.against_others_at_equal_time(BIASED, {"chiang": chiang})
    # Worst at the biased method's first point (0.3 at 0.1 s against chiang's 0.224 then).
    assert q == {"worst_ratio": pytest.approx(0.3 / math.sqrt(0.05)), "best_other": "chiang"}
    assert ec.against_others_at_equal_time(BIASED, {}) is None


def test_auto_against_the_levels_rendered():
    """The add-on's Auto (addon/geometry/lod.py) at each camera of the run: where a ply is 13.8 px it draws plies,
    the most accurate level here: within the goal; below its threshold it draws yarns, whose FLIP is 30 % above
    the ply level's: flagged, and the ply level is also the faster to the yarn level's FLIP (its first point, at
    16 spp, is already below it)."""
    sys.path.insert(0, os.path.join(os.path.dirname(__file__), os.pardir, os.pardir, "addon"))
    from geometry import lod
    far_px = 0.7 * lod.YARNS_BELOW_PLY_PIXELS
    plies = [{"spp": 16, "seconds": 0.4, "flip": 0.05}, {"spp": 64, "seconds": 1.6, "flip": 0.04}]
    yarns = [{"spp": 16, "seconds": 0.2, "flip": 0.053}, {"spp": 64, "seconds": 0.8, "flip": 0.052}]
    res = results_of({"native": plies, "yarns": yarns}, {"native": 110.0, "yarns": 105.0})
    far = [{**r, "distance": 120.0} for r in res["runs"]]
    res["runs"] = [{**r, "scene": "yarn"} for r in res["runs"] + far]
    res["scenes"] = {"yarn": {"distances": {"12": {"ply_pixels": 13.8}, "120": {"ply_pixels": far_px}}}}
    rows = ec.auto_summary(res)
    assert [(r["distance"], r["auto"], r["best"]) for r in rows] == [(12.0, "plies", "plies"), (120.0, "yarns", "plies")]
    near, far = rows
    assert near["flip_ratio"] == pytest.approx(1.0) and near["flip_ok"] and near["time_ok"]
    assert far["flip_ratio"] == pytest.approx(0.052 / 0.04) and far["flip_ok"] is False
    # The ply level reaches 0.052 at its first point (0.4 s, an upper bound), the yarn level at 0.8 s.
    assert far["fastest"] == "plies" and far["time_ratio"] == pytest.approx(0.8 / 0.4) and far["time_ok"] is False
    table = ec.auto_table(rows)
    assert f"| yarn | fleece | grazing | {far_px:.2f} |" in table and "1.30 ✗" in table
    # One level, or a camera of unknown width: nothing to compare.
    assert ec.auto_summary(results_of({"native": plies}, {"native": 110.0})) == []
    res.pop("scenes")
    assert ec.auto_summary(res) == []
