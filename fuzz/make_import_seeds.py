#!/usr/bin/python3
"""Writes the seed corpus of the `import` fuzz target (fuzz/import_fuzz.cpp) into
fuzz/corpus/import/: 4x3 EXRs with Blender Cycles', pbrt-v4's (both spellings) and Mitsuba 3's
channel names and header attributes, as tests/interop/import_test.cpp builds them, each after a
mapping (a preset's text, a hand-written mapping using every source key, or none).

Uncompressed, so that mutations reach the header and the channel data rather than stopping in
the decompressor; one ZIP-compressed seed keeps that path covered. Run from the repository root:
  /usr/bin/python3 fuzz/make_import_seeds.py
"""
import os
import tempfile

import numpy as np
import OpenImageIO as oiio

W, H = 4, 3
OUT = "fuzz/corpus/import"
SEP = b"\n#@@ f.exr\n"


def plane(seed, lo=0.0, hi=1.0):
    rng = np.random.default_rng(seed)
    return (lo + (hi - lo) * rng.random((H, W))).astype(np.float32)


def exr_bytes(channels, attributes=(), compression="none"):
    names = [n for n, _ in channels]
    pixels = np.stack([v for _, v in channels], axis=-1)
    spec = oiio.ImageSpec(W, H, len(names), oiio.FLOAT)
    spec.channelnames = tuple(names)
    spec.attribute("compression", compression)
    for key, value in attributes:
        spec.attribute(key, value)
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "f.exr")
        out = oiio.ImageOutput.create(path)
        if not out.open(path, spec) or not out.write_image(pixels):
            raise SystemExit(f"cannot write {path}: {oiio.geterror()}")
        out.close()
        with open(path, "rb") as f:
            return f.read()


def cycles(vl="ViewLayer"):
    ch, seed = [], 1
    passes = {}
    for p in ["DiffDir", "DiffInd", "DiffCol", "GlossDir", "GlossInd", "GlossCol", "Emit", "TransDir", "TransInd", "TransCol"]:
        for c in "RGB":
            passes[f"{p}.{c}"] = plane(seed, 0, 0.2 if p == "Emit" else 1)
            seed += 1
    for c in "RGB":
        g = lambda p: passes[f"{p}.{c}"]
        comb = (g("DiffDir") + g("DiffInd")) * g("DiffCol") + (g("GlossDir") + g("GlossInd")) * g("GlossCol") + \
            (g("TransDir") + g("TransInd")) * g("TransCol") + g("Emit")
        ch.append((f"{vl}.Combined.{c}", comb))
    ch.append((f"{vl}.Combined.A", np.ones((H, W), np.float32)))
    ch += [(f"{vl}.{n}", v) for n, v in passes.items()]
    for c in "XYZ":
        ch.append((f"{vl}.Normal.{c}", plane(seed, -1, 1)))
        seed += 1
    depth = plane(seed, 1, 5)
    depth[0, 3] = 1e10  # a miss, as Cycles writes it
    ch.append((f"{vl}.Depth.Z", depth))
    return ch


def pbrt(old_names):
    ch, seed = [], 50
    ch += [(c, plane(seed + i)) for i, c in enumerate("RGB")]
    ch += [(f"Albedo.{c}", plane(seed + 3 + i)) for i, c in enumerate("RGB")]
    seed += 6
    for g in ["P", "N", "Ns"]:
        for k, (u, l) in enumerate(zip("XYZ", "xyz")):
            lo, hi = (-3, 3) if g == "P" else (-1, 1)
            ch.append((g + l if old_names else f"{g}.{u}", plane(seed, lo, hi)))
            seed += 1
    ch += [(n, plane(seed + i)) for i, n in enumerate(["dzdx", "dzdy", "u", "v"])]
    ch += [(f"Variance.{c}", plane(seed + 4 + i)) for i, c in enumerate("RGB")]
    ch += [(f"RelativeVariance.{c}", plane(seed + 7 + i)) for i, c in enumerate("RGB")]
    return ch


def mitsuba():
    ch, seed = [], 90
    ch += [(c, plane(seed + i)) for i, c in enumerate("RGB")]
    ch += [(f"inner.{c}", plane(seed + 3 + i)) for i, c in enumerate("RGBA")]
    ch += [(f"albedo.{c}", plane(seed + 7 + i)) for i, c in enumerate("RGB")]
    ch += [(f"nn.{c}", plane(seed + 10 + i, -1, 1)) for i, c in enumerate("XYZ")]
    ch.append(("dd.T", plane(seed + 13, 1, 4)))
    return ch


def preset(name):
    with open(f"configs/import/{name}.toml", "rb") as f:
        return f.read()


# A mapping with every source key: channels, terms and optional terms, transform, scale,
# divide_by_spp, miss_above, space and note, alternatives, optional and ignored passes.
CUSTOM = b"""[import]
name = "mine"
description = "every key"
prefix = ""
detect = ["R"]
spp_attributes = ["samplesPerPixel"]
optional = ["albedo", "variance", "depth"]
ignore = ["u", "v", "dzdx", "dzdy"]
[layers]
color = { channels = ["R", "G", "B"], scale = 1.0 }
variance = { terms = ["Variance"], divide_by_spp = true, note = "per sample" }
normal = { terms = ["Ns"], space = "camera" }
[[layers.albedo]]
terms = ["Albedo * Albedo"]
optional_terms = ["RelativeVariance"]
[[layers.depth]]
terms = ["P"]
transform = "length"
miss_above = 1e9
"""


def main():
    os.makedirs(OUT, exist_ok=True)
    seeds = {
        "cycles-preset": (preset("cycles"), exr_bytes(cycles(), [("cycles.ViewLayer.samples", "128")])),
        "cycles-named-layer-no-mapping": (b"", exr_bytes(cycles("My View Layer"))),
        "cycles-zip": (b"", exr_bytes(cycles(), [("cycles.ViewLayer.samples", "32")], "zip")),
        "pbrt-preset": (preset("pbrt"), exr_bytes(pbrt(False), [("samplesPerPixel", "4")])),
        "pbrt-old-names": (b"", exr_bytes(pbrt(True))),
        "pbrt-custom-mapping": (CUSTOM, exr_bytes(pbrt(False), [("samplesPerPixel", "16")])),
        "mitsuba-preset": (preset("mitsuba"), exr_bytes(mitsuba(), [("generatedBy", "Mitsuba version 3.5.2")])),
    }
    for name, (mapping, exr) in seeds.items():
        with open(os.path.join(OUT, name), "wb") as f:
            f.write(mapping + SEP + exr)
    # A mapping alone (no separator): only parse_mapping runs.
    with open(os.path.join(OUT, "mapping-only"), "wb") as f:
        f.write(CUSTOM)


if __name__ == "__main__":
    main()
