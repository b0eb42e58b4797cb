#!/usr/bin/env python3
"""Times Mitsuba 3 on a scene of `denoisebench export-mitsuba` (the same scene, size, spp and path
depth the tracer renders), for bench/tracer_bench.cpp's BM_Mitsuba: one render first (the LLVM
variants compile their kernels then), then `repeats` timed renders, each made to finish
(dr.eval and dr.sync_thread) before its clock stops.

    .venv/bin/python python/mitsuba_speed.py SCENE.xml [--variant llvm_ad_rgb] [--repeats 3]
        [--threads T]

Prints one JSON line: {"variant", "mitsuba", "width", "height", "spp", "max_depth", "seconds":
[...], "paths_per_second": median}. The llvm variants need libLLVM (Debian's libllvm15):
DRJIT_LIBLLVM_PATH names it when Dr.Jit's own search does not find it. Exit status 2 on bad
arguments or a variant this Mitsuba lacks.
"""
import argparse
import json
import os
import statistics
import sys
import time


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene")
    ap.add_argument("--variant", default="llvm_ad_rgb")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--threads", type=int, default=0, help="0: all cores")
    a = ap.parse_args()
    if not os.path.isfile(a.scene):
        ap.error(f"{a.scene}: no such scene file")
    if a.repeats < 1:
        ap.error("--repeats: at least 1")
    import drjit as dr
    import mitsuba as mi

    if a.variant not in mi.variants():
        ap.error(f"--variant {a.variant}: not one of {', '.join(mi.variants())}")
    try:
        mi.set_variant(a.variant)
    except Exception as e:  # an llvm variant without libLLVM
        print(f"--variant {a.variant}: {e}", file=sys.stderr)
        return 2
    if a.threads > 0:
        dr.set_thread_count(a.threads)
    scene = mi.load_file(a.scene)
    sensor = scene.sensors()[0]
    film = sensor.film()
    w, h = film.size()
    spp = sensor.sampler().sample_count()
    # The path depth as the scene file gives it (the integrator does not expose it to traverse()).
    import xml.etree.ElementTree as ET
    node = ET.parse(a.scene).getroot().find("./integrator/integer[@name='max_depth']")
    max_depth = int(node.get("value")) if node is not None else -1

    def render(seed):
        img = mi.render(scene, seed=seed)
        dr.eval(img)
        dr.sync_thread()
        return img

    render(0)  # warm-up: the kernels are compiled here
    seconds = []
    for k in range(a.repeats):
        t0 = time.perf_counter()
        render(k + 1)
        seconds.append(time.perf_counter() - t0)
    med = statistics.median(seconds)
    print(json.dumps({"variant": a.variant, "mitsuba": mi.__version__, "width": w, "height": h, "spp": spp,
                      "max_depth": max_depth, "seconds": seconds, "paths_per_second": w * h * spp / med}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
