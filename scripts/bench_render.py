"""Image comparison for scripts/bench_render.sh: SSIM of renders against a reference.

    python bench_render.py REFERENCE.exr A.exr B.exr [--png COMPARE.png]

Prints: SSIM(A, ref)  SSIM(B, ref)  mean relative difference of B's mean colour to ref's.

The EXRs are linear; SSIM is computed (scikit-image, Gaussian window sigma 1.5, as Wang et al. 2004) on the
display images an artist would look at: each image scaled by the same exposure (the reference's 99.5th
percentile maps to 1), clamped to [0, 1] and encoded as sRGB, per channel, data range 1. EXRs are read with
the OpenEXR Python bindings (PyPI `OpenEXR` >= 3.3; Debian 12's oiiotool cannot write PFM).
"""
import argparse
import os
import subprocess
import sys
import tempfile

import numpy as np
import OpenEXR
from skimage.metrics import structural_similarity


def read_exr(path):
    """The RGB channels of an EXR as float64 (H, W, 3), top row first (the OpenEXR bindings)."""
    with OpenEXR.File(path) as f:
        channels = f.channels()
        if "RGBA" in channels or "RGB" in channels:
            img = channels["RGBA" if "RGBA" in channels else "RGB"].pixels[..., :3]
        else:
            img = np.stack([channels[c].pixels for c in "RGB"], axis=-1)
    return np.asarray(img, dtype=np.float64)


def display(img, exposure):
    x = np.clip(img * exposure, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("reference")
    ap.add_argument("a")
    ap.add_argument("b")
    ap.add_argument("--png")
    args = ap.parse_args()
    ref, a, b = (read_exr(p) for p in (args.reference, args.a, args.b))
    if not (ref.shape == a.shape == b.shape):
        sys.exit("bench_render.py: the images differ in size")
    level = np.percentile(ref, 99.5)
    exposure = 1.0 / level if level > 0 else 1.0
    d_ref, d_a, d_b = (display(x, exposure) for x in (ref, a, b))
    s_a = structural_similarity(d_ref, d_a, channel_axis=2, data_range=1.0, gaussian_weights=True, sigma=1.5,
                                use_sample_covariance=False)
    s_b = structural_similarity(d_ref, d_b, channel_axis=2, data_range=1.0, gaussian_weights=True, sigma=1.5,
                                use_sample_covariance=False)
    diff = abs(b.mean() - ref.mean()) / ref.mean() if ref.mean() > 0 else 0.0
    print(f"{s_a:.4f} {s_b:.4f} {diff:.4f}")
    if args.png:
        with tempfile.TemporaryDirectory() as tmp:
            paths = []
            for i, src in enumerate((args.reference, args.a, args.b)):
                png = os.path.join(tmp, f"{i}.png")
                subprocess.run(["oiiotool", src, "--ch", "R,G,B", "--mulc", str(exposure), "--clamp:min=0:max=1",
                                "--colorconvert", "linear", "sRGB", "-d", "uint8", "-o", png], check=True)
                paths.append(png)
            subprocess.run(["oiiotool", *paths, "--mosaic", "1x3", "-o", args.png], check=True)


if __name__ == "__main__":
    main()
