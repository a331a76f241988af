# SPDX-License-Identifier: Apache-2.0
"""The stability suite, scripts/stability.sh (issue 19): its measure on synthetic images (NaN, Inf, negative
and firefly pixels counted, bias and variance against a known reference), and the quick run as CI runs it:
every cell has every field; no render has a NaN, Inf or negative pixel; no model gains energy in the white
furnace; the native closure renders the same image at every scene unit; its noise falls with the samples;
the impossible packing fails within a minute naming the parameter; the layers and the references' samples can be
chosen on the command line.

Run by ctest (stability.pytest_quick) with .venv/bin/python -m pytest; NY_STABILITY_OUT names the output
directory (default: a pytest temporary directory), NY_BUILD_DIR the build.
"""
import json
import math
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), os.pardir, os.pardir))
sys.path.insert(0, os.path.join(ROOT, "scripts"))
import stability  # noqa: E402

RENDER_FIELDS = ["sweep", "method", "preset", "spp", "seeds", "nan_pixels", "inf_pixels", "negative_pixels",
                 "firefly_pixels", "bias", "variance", "failed"]


def test_measure_counts_bad_pixels_and_fireflies():
    ref = np.full((8, 16, 3), 0.5)
    a, b = ref.copy(), ref.copy()
    a[1, 1, 0] = np.nan
    a[2, 2, 1] = np.inf
    b[3, 3, 2] = -0.1
    b[5, 9] = 100.0  # above 10 x (the 5 x 5 maximum 0.5 + 5 % of the mean): a firefly
    b[6, 12] = 4.0  # below it: noise
    m = stability.measure([a, b], ref, None, environment=False)
    assert (m["nan_pixels"], m["inf_pixels"], m["negative_pixels"], m["firefly_pixels"]) == (1, 1, 1, 1)
    assert m["region"] == "frame"


def test_measure_bias_variance_and_furnace_against_known_values():
    ref = np.full((6, 6, 3), 0.4)
    lo, hi = np.full_like(ref, 0.3), np.full_like(ref, 0.5)  # mean 0.4: unbiased, per-pixel variance 0.02
    m = stability.measure([lo, hi], ref, (slice(1, 5), slice(1, 5)), environment=True)
    assert m["bias"] == pytest.approx(0.0, abs=1e-12)
    assert m["variance"] == pytest.approx(0.02 / 0.4 ** 2)
    assert m["furnace_max"] == pytest.approx(0.4)
    m = stability.measure([hi, hi], ref, (slice(1, 5), slice(1, 5)), environment=False)
    assert m["bias"] == pytest.approx(0.25) and m["variance"] == 0.0 and "furnace_max" not in m
    assert stability.measure([hi], ref, None, environment=False)["variance"] is None


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    out = os.environ.get("NY_STABILITY_OUT") or str(tmp_path_factory.mktemp("stability"))
    shutil.rmtree(out, ignore_errors=True)
    r = subprocess.run(["bash", os.path.join(ROOT, "scripts", "stability.sh"), "--quick", "--out", out],
                       capture_output=True, text=True, timeout=1500)
    assert r.returncode == 0, r.stderr[-3000:]
    with open(os.path.join(out, "results.json")) as f:
        return out, json.load(f)


def renders(results):
    return [c for c in results["cells"] if c["sweep"] in stability.SWEPT]


def test_every_cell_has_every_field_and_the_map_is_written(quick):
    out, results = quick
    assert {c["sweep"] for c in results["cells"]} == set(stability.SWEEPS)
    for c in renders(results):
        assert set(RENDER_FIELDS) <= set(c), (c, set(RENDER_FIELDS) - set(c))
        assert c["failed"] is False, c
        assert isinstance(c["bias"], float) and math.isfinite(c["bias"]), c
    assert os.path.getsize(os.path.join(out, "stability_map.png")) > 10000


def test_no_render_has_nan_inf_or_negative_pixels(quick):
    for c in renders(quick[1]):
        assert c["nan_pixels"] == c["inf_pixels"] == c["negative_pixels"] == 0, c


def test_no_model_gains_energy_at_the_bin_centres(quick):
    cells = [c for c in quick[1]["cells"] if c.get("furnace_max") is not None]
    assert {c["preset"] for c in cells if c["sweep"] == "furnace"} == set(quick[1]["settings"]["presets"])
    for c in cells:
        if c["sweep"] in ("furnace", "bakes"):
            # 1 % above 1 is pbrt's Hair.WhiteFurnace bound, at the bin centres where the calibration bounds
            # the sum; inside the bins the models still exceed it (furnace_max, docs/benchmarks.md).
            assert c["furnace_max_centres"] <= 1.01, c
            assert c["furnace_max"] >= c["furnace_max_centres"], c
        else:
            # An environment-lit render's brightest row of a 16-spp image.
            assert c["furnace_max"] <= 1.0, c


def test_the_native_closure_renders_the_same_image_at_every_scene_unit(quick):
    units = {c["unit_scale"]: c for c in quick[1]["cells"] if c["sweep"] == "units" and c["method"] == "native"}
    assert set(units) == {2.5e-4, 1.0, 1e3}
    for u, c in units.items():
        # Same seeds, same pixels: only float rounding of a scaled scene separates them.
        assert c["bias"] == pytest.approx(units[1.0]["bias"], abs=2e-3), (u, c)


def test_native_noise_falls_with_the_samples(quick):
    var = {c["spp"]: c["variance"] for c in quick[1]["cells"] if c["sweep"] == "samples" and c["method"] == "native"}
    assert sorted(var) == [1, 4, 16, 64]
    # Variance ~ 1/spp or faster (Cycles' tabulated Sobol is randomised quasi-Monte Carlo): 16x fewer between
    # 4 and 64 samples; a factor 4 leaves room for the two seeds' noise. Not from 1 spp: there the seeds barely
    # randomise the pattern (fleece: 8.6e-7 per pixel at 1 spp, 1.4e-5 at 4, 8.2e-7 at 16), so the variance
    # across seeds is no estimate of one render's noise.
    assert var[64] < var[4] / 4 and var[16] < var[4], var


def test_an_impossible_packing_fails_fast_naming_the_parameter(quick):
    bakes = {c["bake"]: c for c in quick[1]["cells"] if c["sweep"] == "bakes"}
    bad = bakes["unpackable"]
    assert bad["failed"] and "rho" in bad["failed"] and bad["seconds"] < 60, bad
    good = bakes["c_tt_one"]
    assert good["failed"] is False and good["furnace_max_centres"] <= 1.01, good


def test_append_replaces_the_cells_it_redoes_and_keeps_the_others(quick, tmp_path):
    # The quick run's references, as the cache these runs must reuse (rendering them again would be most of
    # this test's time): the native sweeps then render no explicit fibers.
    shutil.copytree(os.path.join(quick[0], "refs"), tmp_path / "refs")
    refs = sorted(os.listdir(tmp_path / "refs"))

    def run(*args):
        r = subprocess.run(["bash", os.path.join(ROOT, "scripts", "stability.sh"), "--quick", "--out", str(tmp_path),
                            *args], capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr[-2000:]
        with open(tmp_path / "results.json") as f:
            return json.load(f)
    native = ("--presets", "fleece", "--methods", "native")
    first = run("--sweeps", "views", *native)
    again = run("--sweeps", "views", *native, "--append")
    assert len(again["cells"]) == len(first["cells"]) == 6 and len(again["commands"]) == 2
    other = run("--sweeps", "units", *native, "--append")
    assert {c["sweep"] for c in other["cells"]} == {"views", "units"} and len(other["commands"]) == 3
    assert len(other["cells"]) == 6 + 3
    assert sorted(os.listdir(tmp_path / "refs")) == refs
    assert not [f for f in os.listdir(tmp_path / "scenes") if "_explicit_" in f]
    assert run("--sweeps", "units", *native)["commands"] == [["scripts/stability.sh", "--quick", "--out", str(tmp_path),
                                                             "--sweeps", "units", *native]]


def test_layers_and_reference_samples_can_be_chosen(tmp_path):
    """--layers, --ref-spp and --ref-rotations reach the run (the 32-layer row of docs/benchmarks.md was made
    with them); values outside their ranges exit 1 with one line naming the option."""
    def run(*args, timeout=300):
        return subprocess.run(["bash", os.path.join(ROOT, "scripts", "stability.sh"), "--quick", "--sweeps", "layers",
                               "--out", str(tmp_path), *args], capture_output=True, text=True, timeout=timeout)
    for bad, name in ((("--layers", "1"), "--layers"), (("--ref-spp", "0"), "--ref-spp"),
                      (("--ref-rotations", "2000"), "--ref-rotations")):
        r = run(*bad, timeout=60)
        assert r.returncode == 1 and name in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    r = run("--layers", "3", "--ref-spp", "8", "--ref-rotations", "1")
    assert r.returncode == 0, r.stderr[-2000:]
    with open(tmp_path / "results.json") as f:
        cells = json.load(f)["cells"]
    assert cells and {c["layers"] for c in cells} == {3}
    refs = [f for f in os.listdir(tmp_path / "refs") if f.endswith(".exr")]
    assert refs and all(f.endswith("_3_False_16.0_8spp_1rot.exr") for f in refs), refs
