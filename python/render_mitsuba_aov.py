#!/usr/bin/env python3
"""Renders Mitsuba 3's built-in Cornell box with its `aov` integrator, as docs/importing.md
describes: the path tracer's image as R,G,B and the AOVs albedo, nn (shading normal) and dd
(depth), the names configs/import/mitsuba.toml reads.

    .venv/bin/python python/render_mitsuba_aov.py OUT.exr [--size 64x48] [--spp 16] [--seed 0]

Runs with the project's virtual environment (scripts/setup installs Mitsuba there); the
scalar_rgb variant needs neither LLVM nor a GPU.
"""
import argparse

import mitsuba as mi


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("output")
    ap.add_argument("--size", default="64x48")
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--max-depth", type=int, default=8)
    a = ap.parse_args()
    w, h = (int(v) for v in a.size.split("x"))
    mi.set_variant("scalar_rgb")
    scene_dict = mi.cornell_box()
    scene_dict["sensor"]["film"]["width"] = w
    scene_dict["sensor"]["film"]["height"] = h
    # A box filter: each pixel the mean of its own samples, as the harness's frames (Mitsuba's
    # default Gaussian spreads a sample over neighbours, blurring the guides).
    scene_dict["sensor"]["film"]["rfilter"] = {"type": "box"}
    scene_dict["integrator"] = {
        "type": "aov",
        "aovs": "albedo:albedo,nn:sh_normal,dd:depth",
        "inner": {"type": "path", "max_depth": a.max_depth},
    }
    scene = mi.load_dict(scene_dict)
    mi.render(scene, spp=a.spp, seed=a.seed)
    scene.sensors()[0].film().bitmap().write(a.output)


if __name__ == "__main__":
    main()
