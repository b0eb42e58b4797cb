#!/usr/bin/python3
"""Pick each baseline method's default parameters by minimising MSE on a training scene.

Fair baselines: every method's defaults come from this sweep on a scene that is NOT
one of the four evaluation scenes (cornell-box, conference, bedroom, sponza). It renders the
training frame and its reference with the denoisebench CLI (or takes --frame/--reference), then
runs a coordinate descent over each method's parameter grid below: starting from the current
defaults, it tries every grid value of one parameter with the others fixed, keeps the best, and
goes round all parameters again until a round changes nothing (at most --rounds rounds).

Everything goes through the program (`denoisebench denoise`, `denoisebench metrics --json`), so
the sweep measures exactly what the experiment runs. The error minimised is `mse` (8-bit sRGB,
the paper's Table 1 scale: clamp to [0, 1], sRGB transfer, 0..255) as the metrics command
reports it; where that command does not report `mse` yet, the script computes it the same way
from 8-bit sRGB copies made by oiiotool (reported as `mse` with "source": "oiiotool").

The reference is rendered with `denoisebench reference` when that command is available, else
with `denoisebench render` at --ref-spp and another seed. A noisy reference adds the same
constant (its variance) to every candidate's expected MSE, so it does not move the minimum.

Several training scenes (the training room, the lamp room, the sun-lit court; every
--scene, or every --frame/--reference pair, is one): the error minimised is then the geometric
mean over the scenes of each scene's mse divided by its unfiltered input's, so that no scene
weighs more for being noisier; with one scene that is the plain mse up to a constant.

Writes OUT/sweep.json (every evaluation) and OUT/sweep.md (best parameters per method, their
error, the error at the previous defaults). Examples:

    scripts/sweep_params.py --scene veach-ajar --size 1024x768 --out results/sweep
    scripts/sweep_params.py --frame train.exr --reference train_ref.exr --methods guided
    scripts/sweep_params.py --scene configs/sweep/training-room.toml --scene configs/sweep/lamp-room.toml \
        --scene configs/sweep/sunlit-court.toml --size 512x384 --ref-spp 2048 --methods proposed --out results/sweep3
"""
import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

EVALUATION_SCENES = {"cornell-box", "conference", "bedroom", "sponza"}

# Parameter grids. "start" is each method's current default (as in its source file, i.e. the
# result of the last sweep); values are strings exactly as passed to --set. A best value at the
# end of its grid means the grid should be widened there and the sweep run again.
GRIDS = {
    "am": {
        "start": {"sigma_s": "16", "sigma_r": "0.1", "adjust_outliers": "false", "range_map": "reinhard"},
        "grid": {
            "sigma_s": ["4", "8", "16", "32"],
            "sigma_r": ["0.03", "0.05", "0.1", "0.2", "0.4"],
            "adjust_outliers": ["false", "true"],
            "range_map": ["reinhard", "log"],
        },
    },
    "proposed": {
        "start": {"sigma_s": "4", "sigma_r": "0.4", "tree_height": "4", "adjust_outliers": "true",
                  "sigma_nlm": "0.05", "sigma_normal": "0.3", "sigma_depth": "0.02", "nlm_dims": "3",
                  "detail_guard": "3"},
        "grid": {
            "detail_guard": ["0", "2", "3", "4", "6"],  # thin dark features (proposed.cpp, guard_details)
            "sigma_s": ["2", "4", "8", "16"],
            "sigma_r": ["0.25", "0.4", "0.6"],
            "tree_height": ["0", "3", "4"],
            "adjust_outliers": ["false", "true"],
            "sigma_nlm": ["0.025", "0.05", "0.1", "0.2"],
            "sigma_normal": ["0.1", "0.3", "0.6", "1"],
            "sigma_depth": ["0.01", "0.02", "0.05", "0.1"],
            "nlm_dims": ["3", "6"],
        },
    },
    "bilateral": {
        "start": {"sigma_space": "1.5", "sigma_color": "0.1", "range_map": "reinhard"},
        "grid": {
            "sigma_space": ["1", "1.5", "2", "3", "4", "6", "8", "12"],
            "sigma_color": ["0.05", "0.1", "0.2", "0.3", "0.5", "0.8", "1.2", "2", "4"],
            "range_map": ["log", "reinhard", "srgb"],
        },
    },
    "nlmeans": {
        "start": {"h": "5", "h_color": "1", "template_window": "5", "range_map": "srgb"},
        "grid": {
            "h": ["2", "3", "5", "8", "10", "15", "20", "30", "40"],
            "h_color": ["0", "0.5", "1", "2", "3", "5", "10", "15", "20", "30"],
            "template_window": ["5", "7", "9"],
            "range_map": ["srgb", "reinhard"],
        },
    },
    "guided": {
        "start": {"radius": "4", "eps": "0.0003", "albedo_weight": "0.3", "normal_weight": "1", "depth_weight": "3",
                  "filter_reflection": "false"},
        "grid": {
            "radius": ["2", "4", "6", "8", "12", "16", "24"],
            "eps": ["0.00001", "0.00003", "0.0001", "0.0003", "0.001", "0.003", "0.01", "0.03", "0.1", "0.3"],
            "albedo_weight": ["0", "0.3", "1", "3"],
            "normal_weight": ["0", "0.3", "1", "3", "10"],
            "depth_weight": ["0", "0.3", "1", "3", "10", "30"],
            "filter_reflection": ["false", "true"],
        },
    },
    "atrous": {
        "start": {"sigma_color": "0.5", "sigma_normal": "0.1", "sigma_depth": "0.01", "halve_color_sigma": "true",
                  "range_map": "reinhard", "filter_reflection": "false"},
        "grid": {
            "sigma_color": ["0.05", "0.1", "0.2", "0.5", "1", "2", "5", "10"],
            "sigma_normal": ["0.03", "0.1", "0.3", "1", "3"],
            "sigma_depth": ["0.003", "0.01", "0.03", "0.1", "0.3", "1", "3"],
            "halve_color_sigma": ["true", "false"],
            "range_map": ["log", "reinhard", "linear"],
            "filter_reflection": ["false", "true"],
        },
    },
    # SVGF's spatial filter. The first sweep started from the paper's values (5, 4, 128,
    # 1, true, true) and ended at iterations and sigma_normal's lower ends: widened there.
    "svgf": {
        "start": {"iterations": "3", "sigma_luminance": "2", "sigma_normal": "8", "sigma_depth": "1",
                  "separate": "false", "variance_prefilter": "true"},
        "grid": {
            "iterations": ["1", "2", "3", "4", "5", "6", "7"],
            "sigma_luminance": ["1", "2", "4", "8", "16", "32"],
            "sigma_normal": ["1", "2", "4", "8", "32", "128", "512"],
            "sigma_depth": ["0.25", "0.5", "1", "2", "4"],
            "separate": ["true", "false"],
            "variance_prefilter": ["true", "false"],
        },
    },
    # NFOR: the paper's values to start from. Not run yet: one evaluation at 1024x768
    # takes about a minute (docs/method-defaults.md, "nfor"), so the descent takes an hour or more.
    "nfor": {
        "start": {"radius": "9", "patch_radius": "1", "k_small": "0.75", "k_large": "2", "second_pass": "false"},
        "grid": {
            "radius": ["5", "7", "9", "12"],
            "patch_radius": ["1", "2", "3"],
            "k_small": ["0.25", "0.5", "0.75", "1"],
            "k_large": ["1", "1.5", "2", "3"],
            "second_pass": ["true", "false"],
        },
    },
    # A renderer (renders the training scene itself, so the sweep needs --scene). Its time is
    # bounded by the render time of the path-traced input (the frame's render_seconds): a
    # renderer slower than that is no speed-up. Candidates over it are recorded and never chosen.
    "irradiance_cache": {
        "renderer": True,
        "start": {"direct_samples": "16", "max_pixel_spacing": "15", "kappa": "1", "pixel_samples": "64"},
        "grid": {
            "direct_samples": ["2", "4", "8", "16", "32"],
            "max_pixel_spacing": ["10", "15", "20", "30"],
            "kappa": ["0.7", "1", "1.5", "2"],
            "pixel_samples": ["32", "64", "128"],
        },
    },
}


def run(cmd):
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if p.returncode != 0:
        sys.exit(f"sweep_params: command failed (exit {p.returncode}): {' '.join(cmd)}\n{p.stdout}")
    return p.stdout


def srgb8(exr, out_ppm):
    """The 8-bit sRGB image of an EXR's R,G,B (clamped to [0, 1]) as a numpy array."""
    run(["oiiotool", exr, "--ch", "R,G,B", "--clamp:min=0:max=1", "--colorconvert", "linear", "sRGB",
         "-d", "uint8", "-o", out_ppm])
    with open(out_ppm, "rb") as f:
        data = f.read()
    # Binary PPM: "P6\n<w> <h>\n255\n" then w*h*3 bytes.
    parts = data.split(b"\n", 3)
    w, h = map(int, parts[1].split())
    return np.frombuffer(parts[3][: w * h * 3], dtype=np.uint8).reshape(h, w, 3).astype(np.float64)


def render_seconds(frame):
    """The path-traced frame's render time from its metadata (None when absent)."""
    for line in run(["oiiotool", "--info", "-v", frame]).splitlines():
        if "denoisebench:render_seconds" in line:
            return float(line.split(":", 2)[2].strip().strip('"'))
    return None


class Evaluator:
    def __init__(self, binary, frame, reference, workdir, scene=None):
        self.binary, self.frame, self.reference, self.workdir = binary, frame, reference, workdir
        self.scene = scene
        self.budget = None  # seconds, for renderers: the input's render time
        self.cache = {}
        self.records = []
        self.metric = None

    def metrics(self, image):
        m = json.loads(run([self.binary, "metrics", image, self.reference, "--json"]))
        if "mse" not in m:
            if not hasattr(self, "ref8"):
                self.ref8 = srgb8(self.reference, os.path.join(self.workdir, "ref.ppm"))
            img8 = srgb8(image, os.path.join(self.workdir, "img.ppm"))
            m["mse"] = float(np.mean((img8 - self.ref8) ** 2))
            m["source"] = "oiiotool"
        if self.metric is None:
            self.metric = "mse"
            print(f"sweep_params: minimising 'mse' ({m.get('source', 'denoisebench metrics')})", flush=True)
        return m

    def __call__(self, method, params):
        key = (method, tuple(sorted(params.items())))
        if key in self.cache:
            return self.cache[key]
        out = os.path.join(self.workdir, "out.exr")
        cmd = [self.binary, "denoise", method, self.frame, "-o", out, "--json"]
        renderer = GRIDS[method].get("renderer", False)
        if renderer and self.scene:
            cmd += ["--scene", self.scene]
        for k, v in sorted(params.items()):
            cmd += ["--set", f"{k}={v}"]
        t0 = time.monotonic()
        stats = json.loads(run(cmd))
        wall = time.monotonic() - t0
        m = self.metrics(out)
        err = float(m[self.metric])
        over = renderer and self.budget is not None and stats["total_seconds"] > self.budget
        rec = {"method": method, "params": dict(params), self.metric: err, "metrics": m,
               "execute_seconds": stats["total_seconds"], "wall_seconds": wall}
        if renderer:
            rec["budget_seconds"] = self.budget
            rec["over_budget"] = bool(over)
        self.records.append(rec)
        if over:
            print(f"{method}: {params} takes {stats['total_seconds']:.1f} s, over the input's "
                  f"{self.budget:.1f} s: not a candidate ({self.metric} {err:.6g})", flush=True)
            err = float("inf")
        self.cache[key] = err
        return err


class SetEvaluator:
    """Several training scenes: the geometric mean over them of mse / the input's mse."""

    def __init__(self, evaluators, input_errs):
        self.evaluators, self.input_errs = evaluators, input_errs
        self.metric = "mse"

    def __call__(self, method, params):
        logs = []
        for ev, ie in zip(self.evaluators, self.input_errs):
            err = ev(method, params)
            if not math.isfinite(err):
                return float("inf")
            logs.append(math.log(err / ie))
        return math.exp(sum(logs) / len(logs))


def descend(evaluate, method, spec, rounds, only=()):
    best = dict(spec["start"])
    best_err = evaluate(method, best)
    start_err = best_err
    print(f"{method}: start {best} -> {best_err:.6g}", flush=True)
    for r in range(rounds):
        changed = False
        for name, values in spec["grid"].items():
            if only and name not in only:
                continue
            for v in values:
                trial = dict(best, **{name: v})
                err = evaluate(method, trial)
                if err < best_err:
                    best, best_err, changed = trial, err, True
            print(f"{method}: round {r + 1}, after {name}: {best} -> {best_err:.6g}", flush=True)
        if not changed:
            break
    return best, best_err, start_err


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scene", action="append", default=[],
                    help="training scene (built-in name or file; repeatable: a training set); not an evaluation scene")
    ap.add_argument("--size", default="1024x768")
    ap.add_argument("--spp", type=int, default=256, help="samples per pixel of the filter input")
    ap.add_argument("--ref-spp", type=int, default=4096, help="samples per pixel of the reference")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--frame", action="append", default=[], help="use this AOV frame instead of rendering one (repeatable)")
    ap.add_argument("--reference", action="append", default=[],
                    help="use this reference instead of rendering one (repeatable, one per --frame)")
    ap.add_argument("--methods", default=",".join(GRIDS), help="comma-separated subset of " + ",".join(GRIDS))
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--only", default="", help="comma-separated parameters to sweep (default: all in the grid)")
    ap.add_argument("--binary", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "build",
                                                     "denoisebench"))
    ap.add_argument("--out", default="results/sweep")
    a = ap.parse_args()

    methods = [m for m in a.methods.split(",") if m]
    for m in methods:
        if m not in GRIDS:
            sys.exit(f"sweep_params: no grid for method '{m}' (have: {', '.join(GRIDS)})")
    for sc in a.scene:
        if os.path.splitext(os.path.basename(sc))[0] in EVALUATION_SCENES:
            sys.exit(f"sweep_params: '{sc}' is an evaluation scene; tune on another one")
    if len(a.frame) != len(a.reference):
        sys.exit("sweep_params: give as many --reference as --frame")
    if not a.frame and not a.scene:
        sys.exit("sweep_params: give --scene, or both --frame and --reference")
    if a.frame and a.scene and len(a.frame) != len(a.scene):
        sys.exit("sweep_params: with --frame and --scene, give one --scene per --frame")
    os.makedirs(a.out, exist_ok=True)

    # One (scene, frame, reference) per training scene.
    sets = []
    count = max(len(a.frame), len(a.scene))
    for i in range(count):
        scene = a.scene[i] if a.scene else None
        tag = "" if count == 1 else f"_{i}"
        frame = a.frame[i] if a.frame else os.path.join(a.out, f"train_frame{tag}.exr")
        reference = a.reference[i] if a.reference else os.path.join(a.out, f"train_reference{tag}.exr")
        if not a.frame and not os.path.exists(frame):
            print(f"rendering {scene} at {a.spp} spp ...", flush=True)
            run([a.binary, "render", scene, "--spp", str(a.spp), "--size", a.size, "--seed", str(a.seed), "-o", frame])
        if not a.reference and not os.path.exists(reference):
            print(f"rendering the reference of {scene} at {a.ref_spp} spp ...", flush=True)
            probe = subprocess.run([a.binary, "reference", "--help"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                   text=True)
            if "not available" in probe.stdout:
                run([a.binary, "render", scene, "--spp", str(a.ref_spp), "--size", a.size, "--seed",
                     str(a.seed + 1000), "-o", reference])
            else:
                run([a.binary, "reference", scene, "--spp", str(a.ref_spp), "--size", a.size, "-o", reference])
        sets.append((scene, frame, reference))

    with tempfile.TemporaryDirectory() as tmp:
        evs, input_errs = [], []
        for i, (scene, frame, reference) in enumerate(sets):
            wd = os.path.join(tmp, str(i))
            os.makedirs(wd)
            ev = Evaluator(a.binary, frame, reference, wd, scene)
            ev.budget = render_seconds(frame)
            input_errs.append(ev.metrics(frame))
            evs.append(ev)
        one = len(evs) == 1
        evaluate = evs[0] if one else SetEvaluator(evs, [e["mse"] for e in input_errs])
        metric = "mse" if one else "mse_over_input_geomean"
        results = {}
        for m in methods:
            best, best_err, start_err = descend(evaluate, m, GRIDS[m], a.rounds, [p for p in a.only.split(",") if p])
            results[m] = {"best": best, metric: best_err, "previous_defaults": GRIDS[m]["start"],
                          "previous_" + metric: start_err}
            if not one:  # each scene's mse at the best and at the previous defaults
                results[m]["per_scene_mse"] = [{"scene": sc, "best": ev(m, best), "previous_defaults": ev(m, GRIDS[m]["start"])}
                                               for (sc, _, _), ev in zip(sets, evs)]

    summary = {"scenes": [sc for sc, _, _ in sets], "frames": [f for _, f, _ in sets],
               "references": [r for _, _, r in sets], "size": a.size, "spp": a.spp, "ref_spp": a.ref_spp,
               "metric": metric, "input": input_errs, "results": results,
               "evaluations": [dict(r, scene=sc) for (sc, _, _), ev in zip(sets, evs) for r in ev.records]}
    with open(os.path.join(a.out, "sweep.json"), "w") as f:
        json.dump(summary, f, indent=2)
    data = "; ".join(f"scene `{sc or '(given frame)'}`, frame `{fr}`, reference `{rf}`, unfiltered input mse "
                     f"{ie.get('mse', float('nan')):.6g}" for (sc, fr, rf), ie in zip(sets, input_errs))
    lines = [f"# Parameter sweep ({metric}, lower is better)", "", f"Training data: {data}.", "",
             f"| method | best parameters | {metric} | at previous defaults |", "|---|---|---|---|"]
    for m, r in results.items():
        params = " ".join(f"{k}={v}" for k, v in sorted(r["best"].items()))
        lines.append(f"| {m} | {params} | {r[metric]:.6g} | {r['previous_' + metric]:.6g} |")
    with open(os.path.join(a.out, "sweep.md"), "w") as f:
        f.write("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
