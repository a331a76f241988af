"""Image comparison for scripts/bench_render.sh: SSIM of renders against a reference.

    python bench_render.py REFERENCE.exr A.exr B.exr [--png COMPARE.png] [--largest-difference]

Prints: SSIM(A, ref)  SSIM(B, ref)  mean relative difference of B's mean colour to ref's, and with
--largest-difference the largest absolute difference of a pixel channel between A and B (two renders that
must be the same image).

The EXRs are linear; SSIM is computed on the display images (scripts/images.py).
"""
import argparse
import os
import subprocess
import sys
import tempfile

import numpy as np

from images import display_ssim, exposure_of, read_exr


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("reference")
    ap.add_argument("a")
    ap.add_argument("b")
    ap.add_argument("--png")
    ap.add_argument("--largest-difference", action="store_true")
    args = ap.parse_args()
    ref, a, b = (read_exr(p) for p in (args.reference, args.a, args.b))
    if not (ref.shape == a.shape == b.shape):
        sys.exit("bench_render.py: the images differ in size")
    exposure = exposure_of(ref)
    s_a, s_b = display_ssim(ref, a, exposure), display_ssim(ref, b, exposure)
    diff = abs(b.mean() - ref.mean()) / ref.mean() if ref.mean() > 0 else 0.0
    line = f"{s_a:.4f} {s_b:.4f} {diff:.4f}"
    if args.largest_difference:
        line += f" {float(np.abs(b - a).max()):.3g}"
    print(line)
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
