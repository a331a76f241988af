"""The visible surface fibers of a K-ply yarn as R-lobe frames (docs/decisions.md D51, an experiment).

Points on ply 0's surface (rho = R_ply) at x = 0, their fiber tangent T and ply-surface normal N in the yarn
frame of the envelope point above them (x = yarn axis, z = yarn radial, y = z x x), kept where a ray along the
yarn radial leaves the yarn without entering another ply; weighted by N . z (projected area at normal incidence).
Prints NQ frames at the midpoints of the weighted quantiles of the normal's rotation about the ridge, the central
SHRINK share of the distribution, as the comma-separated T, N floats that docs/experiments/yarn_r_nodes.diff reads
from NYX_FRAMES. The geometry is geometry/yarn.h's (fiber_point), repeated here in numpy.

    NQ=8 SHRINK=0.6 .venv/bin/python docs/experiments/yarn_surface_frames.py --alpha 0.2 --plies 3 --ply-twist 0.5
"""
import argparse
import json
import os
import subprocess

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
ap = argparse.ArgumentParser()
ap.add_argument("--alpha", type=float, required=True, help="the fibers' twist inside a ply (the preset's alpha)")
ap.add_argument("--plies", type=int, default=3)
ap.add_argument("--ply-twist", type=float, default=0.5)
args = ap.parse_args()
geo = json.loads(subprocess.run([os.path.join(ROOT, "build", "cpp_core", "neuralyarn"), "yarn-geometry", "--plies",
                                 str(args.plies), "--ply-twist", str(args.ply_twist)],
                                capture_output=True, text=True, check=True).stdout.splitlines()[0])
K, R, d = args.plies, 1.0, geo["ply_distance"]
w = np.pi * args.ply_twist / (d + R)
arc = np.sqrt(1 + d * d * w * w)
rate = np.pi * args.alpha / R + w / (1 + d * d * w * w)


def center(k, x):
    th = 2 * np.pi * k / K - w * x
    return np.array([x, d * np.cos(th), d * np.sin(th)])


def tangent(k, x):
    th = 2 * np.pi * k / K - w * x
    t = np.array([1, d * w * np.sin(th), -d * w * np.cos(th)])
    return t / np.linalg.norm(t)


def surface_point(k, psi0, x):
    th = 2 * np.pi * k / K - w * x
    e_r = np.array([0, np.cos(th), np.sin(th)])
    e_b = np.cross(tangent(k, x), e_r)
    psi = psi0 + rate * arc * x
    n = np.cos(psi) * e_r + np.sin(psi) * e_b
    return center(k, x) + R * n, n


xs = np.linspace(-4, 4, 1601)
centerlines = [np.stack([center(k, x) for x in xs]) for k in range(K)]


def inside_another_ply(q):
    return any(np.min(np.sum((centerlines[k] - q) ** 2, axis=1)) < R * R for k in range(1, K))


rows = []
for psi0 in np.linspace(-np.pi, np.pi, 361)[:-1]:
    p, n = surface_point(0, psi0, 0.0)
    h = 1e-5
    t = surface_point(0, psi0, h)[0] - surface_point(0, psi0, -h)[0]
    t /= np.linalg.norm(t)
    z = np.array([0, p[1], p[2]]) / np.hypot(p[1], p[2])
    e_phi = np.cross([1, 0, 0], z)
    if n @ z <= 0 or any(inside_another_ply(p + s * z) for s in np.arange(0.02, 3.0, 0.03)):
        continue
    T = np.array([t[0], -(t @ e_phi), t @ z])
    N = np.array([n[0], -(n @ e_phi), n @ z])
    N -= T * (T @ N)
    N /= np.linalg.norm(N)
    rows.append((np.arctan2(-N[1], N[2]), N[2], *T, *N))
rows = np.array(rows)
rows = rows[np.argsort(rows[:, 0])]
cdf = np.cumsum(rows[:, 1])
cdf /= cdf[-1]
nq, shrink = int(os.environ.get("NQ", "4")), float(os.environ.get("SHRINK", "1"))
frames = []
for q in range(nq):
    i = np.searchsorted(cdf, 0.5 + ((q + 0.5) / nq - 0.5) * shrink)
    frames += list(rows[i, 2:8])
print(",".join("%.5f" % f for f in frames))
