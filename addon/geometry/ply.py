# SPDX-License-Identifier: Apache-2.0
"""Plied yarns: K ply centrelines S-twisted around an arbitrary yarn centreline.

Conventions (docs/conventions.md, "Plied yarns"; C++: cpp_core/src/geometry/yarn.cpp). Around a straight
axis along +x, ply k's centreline is

    c_k(x) = (x, d cos(2 pi k / K - w x), d sin(2 pi k / K - w x)),   w = pi alpha_yarn / (d + R_ply),

so the plies turn left-handed about +x (S twist; the fibers inside each ply are Z-twisted). The centre
distance d is the smallest at which neighbouring ply tubes of radius R_ply do not intersect in 3D; tilted
plies need more room than the axis-normal-plane bound R_ply / sin(pi/K). By the screw symmetry that distance
is a 1-D minimisation; d is found by bisection exactly as `Yarn::Yarn` does, and scales linearly with R_ply.

For a curved yarn the fixed (y, z) axes become a parallel-transported (rotation-minimising) frame (N, B), with
B = T x N, and x becomes the arc length s. On a closed curve the transported frame does not return to itself
(holonomy) and the twist need not complete a whole number of turns; that mismatch is spread evenly over the
loop, so that every ply closes on itself.
"""
from __future__ import annotations

import math

import numpy as np

from .curves import MAX_POINTS, GeometryError, YarnCurve, _check_int, _check_positive, resample, validate

MAX_PLIES = 64
# Explicit fibers beyond this many curves get a warning (Blender and Cycles memory).
FIBER_WARNING_CURVES = 100_000


def _dist2(x: np.ndarray, d: float, phi: np.ndarray, w: float) -> np.ndarray:
    """Squared distance from ply 0's centre at x = 0, (0, d, 0), to a ply at phase phi at x."""
    return x * x + 2.0 * d * d * (1.0 - np.cos(phi - w * x))


def neighbour_ply_distance(K: int, d: float, ply_radius: float, alpha_yarn: float) -> float:
    """Smallest 3D distance between the centrelines of distinct plies at centre distance d (inf for K < 2).

    Same algorithm as the C++ `neighbour_ply_distance`: since dist^2 >= x^2, only |x| < dist(0) can beat
    x = 0; scan that interval with 2001 points, then refine the best bracket by golden-section search.
    """
    if K < 2:
        return math.inf
    w = math.pi * alpha_yarn / (d + ply_radius)
    phi = 2.0 * math.pi * np.arange(1, K) / K  # (K-1,)
    X = np.sqrt(_dist2(np.zeros_like(phi), d, phi, w))
    n = 2000
    u = np.arange(n + 1) / n
    xs = -X[:, None] + 2.0 * X[:, None] * u[None, :]
    f = _dist2(xs, d, phi[:, None], w)
    ib = np.argmin(f, axis=1)
    f_best = f[np.arange(K - 1), ib]
    a = -X + 2.0 * X * np.maximum(0, ib - 1) / n
    b = -X + 2.0 * X * np.minimum(n, ib + 1) / n
    g = 0.5 * (math.sqrt(5.0) - 1.0)
    for _ in range(100):
        x1 = b - g * (b - a)
        x2 = a + g * (b - a)
        left = _dist2(x1, d, phi, w) < _dist2(x2, d, phi, w)
        b = np.where(left, x2, b)
        a = np.where(left, a, x1)
    best = np.minimum(f_best, _dist2(0.5 * (a + b), d, phi, w))
    return float(math.sqrt(float(best.min())))


def ply_center_distance(K: int, ply_radius: float, alpha_yarn: float) -> float:
    """d: the smallest ply centre distance at which neighbouring ply tubes do not intersect (0 for K = 1).

    Bisection from the axis-normal-plane bound R/sin(pi/K) upwards, as the C++ `ply_center_distance` (the
    tests compare the two through `neuralyarn yarn-geometry`).
    """
    K = _check_int("K", K, 1, MAX_PLIES)
    R = _check_positive("ply_radius", ply_radius)
    alpha_yarn = _check_positive("alpha_yarn", alpha_yarn, allow_zero=True)
    if K == 1:
        return 0.0
    lo = R / math.sin(math.pi / K)
    hi = lo
    while neighbour_ply_distance(K, hi, R, alpha_yarn) < 2.0 * R:
        hi *= 1.5
    for _ in range(200):
        if hi - lo <= 1e-13 * hi:
            break
        mid = 0.5 * (lo + hi)
        if neighbour_ply_distance(K, mid, R, alpha_yarn) < 2.0 * R:
            lo = mid
        else:
            hi = mid
    return hi


def _vertex_tangents(P: np.ndarray, cyclic: bool) -> np.ndarray:
    # Chord-normalised central differences: equal weight to both neighbours' directions even when the
    # spacing is uneven, and never zero for a polyline without reversals.
    if cyclic:
        e_next = np.roll(P, -1, axis=0) - P
        e_prev = P - np.roll(P, 1, axis=0)
    else:
        e_next = np.concatenate([P[1:] - P[:-1], (P[-1] - P[-2])[None]])
        e_prev = np.concatenate([(P[1] - P[0])[None], P[1:] - P[:-1]])
    e_next /= np.linalg.norm(e_next, axis=1, keepdims=True)
    e_prev /= np.linalg.norm(e_prev, axis=1, keepdims=True)
    T = e_next + e_prev
    norm = np.linalg.norm(T, axis=1, keepdims=True)
    fallback = norm[:, 0] < 1e-12  # a 180-degree reversal: take the outgoing direction
    T[fallback] = e_next[fallback]
    norm[fallback] = 1.0
    return T / norm


def _reflection(v: np.ndarray) -> np.ndarray:
    """Householder matrices I - 2 v v^T / v^T v for rows of v (identity where v ~ 0)."""
    vv = np.einsum("ij,ij->i", v, v)
    safe = vv > 1e-300
    coef = np.where(safe, 2.0 / np.where(safe, vv, 1.0), 0.0)
    return np.eye(3)[None] - coef[:, None, None] * v[:, :, None] * v[:, None, :]


def parallel_transport_frames(
    points: np.ndarray, cyclic: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Rotation-minimising frames (T, N, B = T x N) at the vertices of a polyline, and the holonomy.

    Double reflection (Wang, Juettler, Zheng, Liu 2008): each step from vertex i to i+1 is a rotation A_i,
    so the frames are prefix products of rotations, computed with a log-depth scan instead of a Python loop.
    N_0 is the coordinate axis least aligned with T_0, orthogonalised (for a yarn along +x: N = +y, B = +z,
    which reproduces the C++ formula). holonomy (closed curves; 0 for open ones) is the angle, in the
    (N_0, B_0) plane, of N transported once around the loop: N_n = cos h N_0 + sin h B_0.
    """
    P = np.asarray(points, dtype=np.float64)
    T = _vertex_tangents(P, cyclic)
    e = np.zeros(3)
    e[int(np.argmin(np.abs(T[0])))] = 1.0
    N0 = e - np.dot(e, T[0]) * T[0]
    N0 /= np.linalg.norm(N0)
    # Steps i -> i+1 (and, when closed, n-1 -> 0 to measure the holonomy).
    Q = np.concatenate([P, P[:1]]) if cyclic else P
    TQ = np.concatenate([T, T[:1]]) if cyclic else T
    v1 = Q[1:] - Q[:-1]
    H1 = _reflection(v1)
    tL = np.einsum("sij,sj->si", H1, TQ[:-1])
    H2 = _reflection(TQ[1:] - tL)
    A = H2 @ H1  # (steps, 3, 3) rotations
    C = A.copy()
    step = 1
    while step < len(C):  # C[i] = A_i A_{i-1} ... A_0
        C[step:] = C[step:] @ C[:-step]
        step *= 2
    Ns = np.concatenate([N0[None], np.einsum("sij,j->si", C, N0)])
    if cyclic:
        N_end = Ns[-1]
        Ns = Ns[:-1]
    # Re-orthonormalise against the vertex tangents (removes the rounding drift of long products).
    Ns = Ns - np.einsum("ij,ij->i", Ns, T)[:, None] * T
    Ns /= np.linalg.norm(Ns, axis=1, keepdims=True)
    B = np.cross(T, Ns)
    holonomy = 0.0
    if cyclic:
        holonomy = math.atan2(float(np.dot(N_end, B[0])), float(np.dot(N_end, Ns[0])))
    return T, Ns, B, holonomy


def twist_plies(
    curve: YarnCurve,
    K: int,
    *,
    ply_radius: float | None = None,
    alpha_yarn: float,
    samples_per_turn: int = 32,
) -> list[YarnCurve]:
    """K ply centrelines S-twisted around `curve` (closed if it is closed).

    ply_radius None fits the plies inside the yarn's radius, R_ply = R_yarn / (1 + d/R_ply) per vertex (d/R
    depends only on K and alpha_yarn); a given ply_radius fixes R_ply and the yarn radius becomes d + R_ply.
    alpha_yarn >= 0 is the ply twist factor 2 R_yarn dn/dl (pitch 2 R_yarn / alpha_yarn, twist rate
    w = pi alpha_yarn / R_yarn). The axis is linearly resampled to at least samples_per_turn vertices per
    ply turn and one per ply radius. K = 1 returns the axis itself with the ply radius. Bending the yarn
    tighter than its radius makes inner plies self-intersect; that is not checked.
    """
    validate([curve], source="twist_plies")
    K = _check_int("K", K, 1, MAX_PLIES)
    alpha_yarn = _check_positive("alpha_yarn", alpha_yarn, allow_zero=True)
    samples_per_turn = _check_int("samples_per_turn", samples_per_turn, 4, 4096)
    if ply_radius is not None:
        ply_radius = _check_positive("ply_radius", ply_radius)
    if K == 1:
        r = curve.radius.copy() if ply_radius is None else np.full(len(curve.points), ply_radius)
        return [YarnCurve(curve.points.copy(), r, curve.cyclic)]

    delta = ply_center_distance(K, 1.0, alpha_yarn)  # d / R_ply
    r_ply = curve.radius / (1.0 + delta) if ply_radius is None else np.full(len(curve.points), ply_radius)
    r_yarn = (1.0 + delta) * r_ply
    w_max = math.pi * alpha_yarn / float(r_yarn.min())
    h = float(r_ply.min())
    if w_max > 0.0:
        h = min(h, 2.0 * math.pi / (w_max * samples_per_turn))
    n_est = curve.length / h
    if not n_est * K <= MAX_POINTS:
        raise GeometryError(
            f"twist_plies: {K} plies of about {int(n_est)} points exceed the limit of {MAX_POINTS}; lower "
            f"'samples_per_turn' (now {samples_per_turn})"
        )
    axis = resample(curve, h)
    P = axis.points
    # Drop repeated vertices: they have no tangent.
    keep = np.ones(len(P), dtype=bool)
    keep[1:] = np.linalg.norm(np.diff(P, axis=0), axis=1) > 0.0
    if axis.cyclic and len(P) > 1 and not np.any(P[-1] != P[0]):
        keep[-1] = False
    P = P[keep]
    R_axis = axis.radius[keep]
    if ply_radius is None:
        r_ply = R_axis / (1.0 + delta)
    else:
        r_ply = np.full(len(P), ply_radius)
    r_yarn = (1.0 + delta) * r_ply
    d = delta * r_ply

    T, N, B, holonomy = parallel_transport_frames(P, axis.cyclic)
    Q = np.concatenate([P, P[:1]]) if axis.cyclic else P
    seg = np.linalg.norm(np.diff(Q, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])  # arc length at vertices (and at the closing vertex)
    w = math.pi * alpha_yarn / r_yarn
    wq = np.concatenate([w, w[:1]]) if axis.cyclic else w
    theta = np.concatenate([[0.0], np.cumsum(0.5 * (wq[1:] + wq[:-1]) * seg)])  # integral of w ds
    if axis.cyclic:
        L = s[-1]
        mismatch = theta[-1] - holonomy
        correction = mismatch - 2.0 * math.pi * round(mismatch / (2.0 * math.pi))
        theta = theta - correction * s / L  # now theta_end - holonomy is a whole number of turns
        theta = theta[:-1]
    out = []
    for k in range(K):
        ang = 2.0 * math.pi * k / K - theta
        offset = np.cos(ang)[:, None] * N + np.sin(ang)[:, None] * B
        out.append(YarnCurve(P + d[:, None] * offset, r_ply.copy(), axis.cyclic))
    return out


def explicit_fiber_warning(
    n_curves: int, fibers_per_ply: int, *, points_per_fiber: int = 256, threshold: int = FIBER_WARNING_CURVES
) -> str | None:
    """A warning when explicit fibers (n_curves plies x fibers_per_ply) would be too many curves, else None.

    Blender stores a float3 position and a float radius per point (16 bytes), and Cycles builds its own copy
    plus a BVH, so the estimate below is a lower bound on the real memory.
    """
    n_curves = _check_int("n_curves", n_curves, 0, 2**62)
    fibers_per_ply = _check_int("fibers_per_ply", fibers_per_ply, 0, 2**40)
    points_per_fiber = _check_int("points_per_fiber", points_per_fiber, 1, 2**40)
    total = n_curves * fibers_per_ply
    if total <= threshold:
        return None
    gib = total * points_per_fiber * 16 / 2**30
    return (
        f"explicit fibers: {n_curves} plies x {fibers_per_ply} fibers = {total:,} curves, about "
        f"{total * points_per_fiber:,} points and {gib:.1f} GiB of curve data at {points_per_fiber} points per "
        f"fiber (more once Cycles builds its BVH); consider the neural yarn BSDF on the ply or yarn curves instead"
    )
