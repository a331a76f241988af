# SPDX-License-Identifier: Apache-2.0
"""examples/make_examples.py's explicit-fiber sweep (no Blender): fibers carried along a ply curve."""
from __future__ import annotations

import math
import os
import sys

import numpy as np

REPO = os.path.abspath(os.path.join(os.path.dirname(__file__), os.pardir, os.pardir))
sys.path.insert(0, os.path.join(REPO, "examples"))
import make_examples  # noqa: E402

geometry = make_examples.geometry


def layout(n=7, w=0.8, seed=3):
    rng = np.random.default_rng(seed)
    r = np.sqrt(rng.uniform(0.0, 0.9, n))
    phase = rng.uniform(-math.pi, math.pi, n)
    return r, phase, w, 0.03, "<khungurn_fiber_bsdf name=\"f\" />"


def test_sweep_along_a_straight_ply_gives_the_helices():
    R, L = 0.25, 10.0
    x = np.linspace(0.0, L, 11)
    ply = geometry.YarnCurve(np.stack([x, np.zeros_like(x), np.zeros_like(x)], axis=1), np.full(11, R), False)
    lay = layout()
    nkeys, keys, fiber_radius = make_examples.sweep_fibers([ply], lay, segments_per_turn=16)
    r, phase, w, _, _ = lay
    assert len(nkeys) == len(r) and fiber_radius == 0.03
    start = 0
    for ri, pi, n in zip(r, phase, nkeys):
        k = keys[start:start + n]
        start += n
        # Axis along +x: the rotation-minimising frame is (N, B) = (+y, +z), so each fiber is the helix
        # (s, R r cos(phi + w s / R), R r sin(phi + w s / R)).
        ang = pi + w * k[:, 0] / R
        np.testing.assert_allclose(k[:, 1], R * ri * np.cos(ang), atol=1e-9)
        np.testing.assert_allclose(k[:, 2], R * ri * np.sin(ang), atol=1e-9)
        # Enough keys per turn: turns = w L / (2 pi R).
        assert n >= 16 * w * L / (2 * math.pi * R)


def test_sweep_along_a_knit_stays_inside_each_ply():
    plies = make_examples.three_ply(geometry.plain_knit(1, 2, samples_per_loop=32))
    nkeys, keys, _ = make_examples.sweep_fibers(plies, layout(n=5), segments_per_turn=12)
    assert len(nkeys) == 5 * len(plies)
    start = 0
    for p, ply in enumerate(plies):
        R = float(np.mean(ply.radius))
        centre = ply.points
        n = nkeys[5 * p]  # the 5 fibers of a ply share its key count
        assert nkeys[5 * p:5 * p + 5] == [n] * 5
        block = keys[start:start + 5 * n]
        start += 5 * n
        # Every fiber key lies within r_max = 0.95 ply radii of the centreline, up to its longest chord.
        d = np.min(np.linalg.norm(block[:, None, :] - centre[None, :, :], axis=2), axis=1)
        seg = np.max(np.linalg.norm(np.diff(centre, axis=0), axis=1))
        assert np.all(d <= R * 0.95 + seg), p
