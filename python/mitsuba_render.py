#!/usr/bin/env python3
"""Renders Mitsuba 3 scenes (denoisebench export-mitsuba folders) as K independent renders each,
and writes every pixel's mean and the variance of that mean: the numbers the tracer's frames
carry in their `color` and `variance` layers, so that the two renderers compare the same way.

    .venv/bin/python python/mitsuba_render.py SCENE.xml [SCENE.xml ...] -o OUT.json
        [--seeds K] [--spp N] [--variant scalar_rgb] [--threads T]

Render k (k = 0 .. K-1) of a scene uses the seed of the scene's sampler plus k and the sampler's
sample_count (or --spp) samples per pixel; the mean is over the K renders. The K renders of a
pixel are independent and identically distributed, so their sample variance s^2 (with K - 1 in
the denominator) is an unbiased estimate of one render's variance and s^2 / K of the variance of
the mean, with K - 1 degrees of freedom per pixel: the tracer's own estimate from its 8 sample
groups is the same construction (tracer/render.cpp's top), hence the default K = 8. (Mitsuba's
independent sampler draws each pixel from its own stream, so pixels are independent too, and a
mean over a block of pixels has the summed variances over the squared count.) The samples'
own spread would need a second-moment integrator and says nothing the seeds do not.

OUT.json: {"mitsuba": VERSION, "variant": V, "frames": [{"scene": PATH, "width": W, "height": H,
"spp": N, "seeds": K, "max_depth": D, "mean": [...], "variance_of_mean": [...]}]}, each list W * H * 3
numbers, row-major from the top-left pixel, RGB per pixel.

Runs with the project's virtual environment (scripts/setup installs Mitsuba there); the default
scalar_rgb variant needs neither LLVM nor a GPU. Exit status 2 on bad arguments or a scene
Mitsuba refuses.
"""
import argparse
import json
import os
import sys


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scenes", nargs="+", help="scene.xml files (denoisebench export-mitsuba)")
    ap.add_argument("-o", "--output", required=True, help="output JSON")
    ap.add_argument("--seeds", type=int, default=8, help="independent renders per scene (at least 2)")
    ap.add_argument("--spp", type=int, default=0, help="samples per pixel per render (0: the sampler's)")
    ap.add_argument("--variant", default="scalar_rgb", help="Mitsuba variant (an RGB one)")
    ap.add_argument("--threads", type=int, default=0, help="render threads (0: all cores)")
    a = ap.parse_args()
    if a.seeds < 2:
        ap.error("--seeds: at least 2 renders are needed for a variance")
    if a.spp < 0:
        ap.error("--spp: expected 0 or a positive count")
    for s in a.scenes:
        if not os.path.isfile(s):
            ap.error(f"{s}: no such scene file")

    import drjit as dr
    import mitsuba as mi
    import numpy as np

    if a.variant not in mi.variants():
        ap.error(f"--variant {a.variant}: not one of {', '.join(mi.variants())}")
    if "rgb" not in a.variant:
        ap.error(f"--variant {a.variant}: the frames are compared as RGB; use an *_rgb variant")
    mi.set_variant(a.variant)
    if a.threads > 0:
        dr.set_thread_count(a.threads)
    mi.set_log_level(mi.LogLevel.Warn)

    frames = []
    for path in a.scenes:
        try:
            scene = mi.load_file(path)
        except Exception as e:  # Mitsuba raises RuntimeError/ValueError with its parser's message
            print(f"mitsuba_render.py: {path}: Mitsuba could not load the scene: {e}", file=sys.stderr)
            sys.exit(2)
        sensor = scene.sensors()[0]
        sampler = sensor.sampler()
        spp = a.spp or sampler.sample_count()
        width, height = (int(v) for v in sensor.film().crop_size())
        # The exported sampler's seed is the first render's; the others follow it.
        base_seed = read_seed(path)
        renders = []
        for k in range(a.seeds):
            img = mi.render(scene, sensor=sensor, seed=base_seed + k, spp=spp)
            renders.append(np.array(img, dtype=np.float64)[:, :, :3])
        stack = np.stack(renders)  # K x H x W x 3
        mean = stack.mean(axis=0)
        var_of_mean = stack.var(axis=0, ddof=1) / a.seeds
        frames.append({
            "scene": path,
            "width": width,
            "height": height,
            "spp": spp,
            "seeds": a.seeds,
            "base_seed": base_seed,
            "max_depth": read_max_depth(path),
            "mean": mean.reshape(-1).tolist(),
            "variance_of_mean": var_of_mean.reshape(-1).tolist(),
        })
    out = {"mitsuba": mi.__version__, "variant": a.variant, "frames": frames}
    tmp = a.output + ".tmp"
    with open(tmp, "w") as f:
        json.dump(out, f)
    os.replace(tmp, a.output)


def read_seed(path):
    """The sampler's seed as the XML gives it (Mitsuba does not expose it through traverse)."""
    import xml.etree.ElementTree as ET
    for e in ET.parse(path).getroot().iter("integer"):
        if e.get("name") == "seed":
            return int(e.get("value"))
    return 0


def read_max_depth(path):
    import xml.etree.ElementTree as ET
    integ = ET.parse(path).getroot().find("integrator")
    if integ is not None:
        for e in integ.iter("integer"):
            if e.get("name") == "max_depth":
                return int(e.get("value"))
    return -1


if __name__ == "__main__":
    main()
