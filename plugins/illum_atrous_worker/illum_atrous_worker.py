"""Plug-in example (protocol "worker"): edge-avoiding a-trous filter of the illumination.

The harness starts `python3 illum_atrous_worker.py` once, then sends one JSON request per frame
on stdin; denoisebench_plugin.run answers each one."""
import numpy as np

from denoisebench_plugin import run

KERNEL = np.array([1 / 16, 1 / 4, 3 / 8, 1 / 4, 1 / 16], dtype=np.float32)  # B3 spline


def shifted(img, dy, dx):
    """img moved by (dy, dx), the border pixels repeated."""
    h, w = img.shape[:2]
    ys = np.clip(np.arange(h) + dy, 0, h - 1)
    xs = np.clip(np.arange(w) + dx, 0, w - 1)
    return img[ys][:, xs]


def atrous(illum, normal, depth, params):
    c = illum.astype(np.float32)
    z = np.maximum(np.abs(depth), 1e-6)
    for level in range(int(params["iterations"])):
        step = 1 << level
        lum = c.mean(axis=2, keepdims=True)
        scale = np.maximum(lum, 1e-3)
        acc = np.zeros_like(c)
        wsum = np.zeros_like(lum)
        for i, ky in enumerate(KERNEL):
            for j, kx in enumerate(KERNEL):
                dy, dx = (i - 2) * step, (j - 2) * step
                cq = shifted(c, dy, dx)
                w_c = np.exp(-np.abs(cq.mean(axis=2, keepdims=True) - lum) / (params["sigma_color"] * scale))
                dn = np.sum((shifted(normal, dy, dx) - normal) ** 2, axis=2, keepdims=True)
                w_n = np.exp(-dn / params["sigma_normal"] ** 2)
                w_z = np.exp(-np.abs(shifted(depth, dy, dx) - depth) / (params["sigma_depth"] * z))
                wq = ky * kx * w_c * w_n * w_z
                acc += wq * cq
                wsum += wq
        c = acc / np.maximum(wsum, 1e-12)
    return c


def denoise(frame, params):
    illum = frame["direct"] + frame["indirect"]
    filtered = atrous(illum, frame["normal"], frame["depth"], params)
    return filtered * frame["albedo"] + frame["reflection"] + frame["emission"]


run(denoise)
