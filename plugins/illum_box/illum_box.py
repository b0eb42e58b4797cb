"""Plug-in example (protocol "frame"): a box filter of the illumination, remodulated.

The harness runs `python3 illum_box.py --input IN.exr --output OUT.exr --param radius=3`."""
import numpy as np

from denoisebench_plugin import run


def box(img, r):
    """Mean over the (2r+1)^2 box around each pixel, the box clipped at the image's border."""
    if r == 0:
        return img
    h, w = img.shape[:2]
    s = np.zeros((h + 1, w + 1) + img.shape[2:], dtype=np.float64)  # summed-area table
    s[1:, 1:] = img.astype(np.float64).cumsum(0).cumsum(1)
    y0 = np.clip(np.arange(h) - r, 0, h)[:, None]
    y1 = np.clip(np.arange(h) + r + 1, 0, h)[:, None]
    x0 = np.clip(np.arange(w) - r, 0, w)[None, :]
    x1 = np.clip(np.arange(w) + r + 1, 0, w)[None, :]
    total = s[y1, x1] - s[y0, x1] - s[y1, x0] + s[y0, x0]
    count = ((y1 - y0) * (x1 - x0))[..., None]
    return (total / count).astype(np.float32)


def denoise(frame, params):
    illumination = frame["direct"] + frame["indirect"]
    return box(illumination, int(params["radius"])) * frame["albedo"] + frame["reflection"] + frame["emission"]


run(denoise)
