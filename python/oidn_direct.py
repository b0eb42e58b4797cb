#!/usr/bin/env python3
"""Runs Intel Open Image Denoise through its own Python API (pyoidn.denoise: the package's
documented one-call entry, a different path from the `oidn` plug-in's ctypes calls) on a harness
frame's colour, albedo and normal, in the plug-in's default mode (RT filter, hdr, quality high,
no cleanAux), and compares the result with an image the plug-in wrote. The albedo is OIDN's
convention as the plug-in makes it with `albedo = "oidn"` (plugins/oidn/oidn_albedo.py), or with
--tracer the frame's albedo layer as stored (the plug-in's default, `albedo = "tracer"`).

    .venv/bin/python python/oidn_direct.py [--tracer] FRAME.exr PLUGIN_OUT.exr

Prints the largest absolute difference and the number of differing values; exits 0 when the two
are identical bit for bit, 1 when they differ, 2 on bad input. Used by
tests/apps/plugins_test.cpp (Plugins.OidnRowIsOidnItself).
"""
import os
import sys

import numpy as np
import OpenImageIO as oiio


sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "plugins", "oidn"))
import oidn_albedo  # noqa: E402


def layer(path, names, required=True):
    buf = oiio.ImageBuf(path)
    if buf.has_error:
        sys.exit(f"{path}: {buf.geterror()}")
    spec = buf.spec()
    chans = list(spec.channelnames)  # OIIO may reorder channels: look them up by name
    pixels = buf.get_pixels(oiio.FLOAT).reshape(spec.height, spec.width, spec.nchannels)
    missing = [n for n in names if n not in chans]
    if missing and not required:
        return None
    if missing:
        print(f"{path}: no channels {', '.join(missing)}", file=sys.stderr)
        sys.exit(2)
    return np.ascontiguousarray(np.stack([pixels[:, :, chans.index(n)] for n in names], axis=-1), dtype=np.float32)


def main():
    args = sys.argv[1:]
    tracer = "--tracer" in args
    args = [a for a in args if a != "--tracer"]
    if len(args) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    frame, plugin_out = args
    import pyoidn  # needs cffi (Debian's python3-cffi, scripts/setup)
    color = layer(frame, ["R", "G", "B"])
    albedo = layer(frame, ["albedo.R", "albedo.G", "albedo.B"])
    if not tracer:
        layers = {"albedo": albedo}
        for name in ("emission", "refl1.albedo", "refl1.tint"):
            a = layer(frame, [f"{name}.R", f"{name}.G", f"{name}.B"], required=False)
            if a is not None:
                layers[name] = a
        albedo = oidn_albedo.oidn_albedo(layers)
    normal = layer(frame, ["normal.X", "normal.Y", "normal.Z"])
    direct = pyoidn.denoise(color, albedo, normal, hdr=True, clean_aux=False, quality="high")
    plugin = layer(plugin_out, ["R", "G", "B"])
    if direct.shape != plugin.shape:
        print(f"shapes differ: OIDN {direct.shape}, plug-in {plugin.shape}")
        return 1
    diff = np.abs(direct.astype(np.float64) - plugin.astype(np.float64))
    differing = int(np.count_nonzero(direct.view(np.uint32) != plugin.view(np.uint32)))
    print(f"max abs difference {diff.max():.3g}, {differing} of {direct.size} values differ")
    return 0 if differing == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
