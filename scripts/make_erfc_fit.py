#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Fits the coefficients of the kernel's erfc (ny::fast_erfc, kernel/special.h) and prints them.

For a = |x| >= 0, erfc(a) = exp(-a^2) erfcx(a), and h(a) = (1 + 2 a) erfcx(a) runs from 1 at a = 0 to 2 / sqrt(pi)
at infinity, smooth and bounded, so it is a polynomial in t = (a - 2) / (a + 2), which maps [0, inf) onto [-1, 1).
It is written h = 1 + (1 + t) Q(t), 1 + t = 2a / (a + 2), so that erfc(0) is 1 exactly and the small correction
near 0 carries its own rounding, not that of a sum of coefficients near 1. Q's fit is minimax in h's relative error
(Lawson's iteratively reweighted least squares on Chebyshev points) over the arguments the kernel can meet before
erfc underflows in float, a <= 10.1. Reference values by scipy's erfcx (double, ~1e-15 relative). The kernel
evaluates (1 + 2a/(a+2) Q(t)) / (1 + 2a) * exp(-a^2) in float; its accuracy against Boost.Math is checked by
tests/cpp/test_special.cpp (docs/decisions.md D59).

    .venv/bin/python scripts/make_erfc_fit.py              # print the coefficients and the fit's error
    .venv/bin/python scripts/make_erfc_fit.py --degree 9    # another degree
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy import special

A_MAX = 10.1  # erfc(10.1) ~ 2e-46: below float's smallest denormal, so the kernel returns 0 past it
K = 2.0       # t = (a - K) / (a + K)


def fit(degree: int, points: int = 4000, iterations: int = 60) -> tuple[np.ndarray, float]:
    t_max = (A_MAX - K) / (A_MAX + K)
    # Chebyshev points of the interval [-1, t_max] in t.
    k = np.arange(points)
    t = -1.0 + (t_max + 1.0) * 0.5 * (1.0 - np.cos(np.pi * (k + 0.5) / points))
    a = K * (1.0 + t) / (1.0 - t)
    h = (1.0 + 2.0 * a) * special.erfcx(a)
    V = np.vander(t, degree + 1, increasing=True) * (1.0 + t)[:, None]  # h - 1 = (1 + t) Q(t)
    w = np.ones_like(t)
    for _ in range(iterations):  # Lawson: weights grow where the error is largest, towards equioscillation
        sw = np.sqrt(w) / h
        c, *_ = np.linalg.lstsq(V * sw[:, None], (h - 1.0) * sw, rcond=None)
        err = np.abs(1.0 + V @ c - h) / h
        w = w * err
        w /= w.sum()
    return c, float(err.max())  # the error of the last fit


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--degree", type=int, default=8, help="degree of Q in t (default 8)")
    args = ap.parse_args()
    c, err = fit(args.degree)
    print(f"Q of degree {args.degree}: largest relative error of h in double {err:.3g}")
    for i, v in enumerate(c):
        print(f"  c{i} = {float(np.float32(v)):.9g}f  ({v:.17g})")


if __name__ == "__main__":
    main()
