# SPDX-License-Identifier: Apache-2.0
"""Image helpers shared by the render comparisons (scripts/evaluate.py, scripts/bench_render.py).

EXRs are read with the OpenEXR Python bindings (PyPI `OpenEXR` >= 3.3, installed into .venv by
scripts/setup.sh; Debian 12's oiiotool cannot write PFM). SSIM is computed as an artist would look at the
images: each scaled by the same exposure (the reference's 99.5th percentile maps to 1), clamped to [0, 1]
and encoded as sRGB, per channel, data range 1, Gaussian window sigma 1.5 (Wang et al. 2004).
"""
import numpy as np

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709


def read_exr(path: str) -> np.ndarray:
    """The RGB channels of an EXR as float64 (H, W, 3), top row first."""
    import OpenEXR
    with OpenEXR.File(path) as f:
        channels = f.channels()
        if "RGBA" in channels or "RGB" in channels:
            img = channels["RGBA" if "RGBA" in channels else "RGB"].pixels[..., :3]
        else:
            img = np.stack([channels[c].pixels for c in "RGB"], axis=-1)
    return np.asarray(img, dtype=np.float64)


def write_exr(path: str, img: np.ndarray, half: bool = False) -> None:
    """An (H, W, 3) image as a float32 (or with `half` float16) RGB EXR, written to a temporary name and moved
    into place."""
    import os
    import OpenEXR
    tmp = path + ".tmp.exr"
    with OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage},
                      {"RGB": np.ascontiguousarray(img[..., :3], dtype=np.float16 if half else np.float32)}) as f:
        f.write(tmp)
    os.replace(tmp, path)


def exposure_of(ref: np.ndarray) -> float:
    """The exposure that maps the reference's 99.5th percentile to 1."""
    level = float(np.percentile(ref, 99.5))
    return 1.0 / level if level > 0 else 1.0


def display(img: np.ndarray, exposure: float) -> np.ndarray:
    """Linear HDR -> the sRGB display image at that exposure, clamped to [0, 1]."""
    x = np.clip(img * exposure, 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def display_ssim(ref: np.ndarray, img: np.ndarray, exposure: float) -> float:
    """SSIM of the display images of `img` against `ref` at one exposure."""
    from skimage.metrics import structural_similarity
    return float(structural_similarity(display(ref, exposure), display(img, exposure), channel_axis=2,
                                       data_range=1.0, gaussian_weights=True, sigma=1.5,
                                       use_sample_covariance=False))
