#!/usr/bin/python3
"""The report page's image data, from results.json and the EXRs it names (run by `denoisebench report`).

For every scene, at the tables' input spp and the first input seed, every image of the scene:
the input, the reference, every method and variant, and each one's error maps (FLIP, HDR-FLIP,
relMSE). Each is written as linear half floats (little-endian, row-major, RGB or one channel),
base64 in a small script file, because a page opened from file:// may load scripts but not
fetch files; the page decodes them and applies exposure and tone mapping to the radiance.

  web/viewer/manifest.js      DNB_MANIFEST: scenes, images (label, kind, file, metrics from
                              results.json, the tiles where a method is worse than its input), crops with per-method means of the error maps,
                              colour maps, each method's colour (reports/method_style.py), and the
                              sequences: {name, frames, rows, scenes} per sequence of the config,
                              `scenes` the positions in `scenes` of its frame rows in frame order
                              (each such scene has `sequence` and `frame`); viewer.js shows them as
                              one viewer with a frame slider
  web/viewer/s<i>/<j>.js      DNB.image("<i>/<j>", width, height, channels, "deflate", "<base64>"):
                              the half floats zlib-compressed (about a third smaller for noisy
                              renders; the page inflates them with DecompressionStream)

A sequence's frames share their error maps' colour scales (the widest of its frames' relMSE
decades), so that scrubbing through the frames does not change what a colour means.

Crops: the 1/6-size window where Table 2's CPU method's FLIP error is largest, and the one (not
overlapping it) where its relMSE is largest.

Exit 2 (bad input) naming the file and the key when results.json names an image that is not
there or cannot be read.

Usage: /usr/bin/python3 reports/viewer.py RESULTS_DIR
"""
import base64
import json
import math
import os
import sys
import zlib

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import method_style  # noqa: E402

# A record's error maps are its files "error_<metric>" (the metrics with run_keeps_map in
# metrics/metrics.cpp); shown under these labels, or the metric's name.
ERROR_LABELS = {"flip": "FLIP", "hdrflip": "HDR-FLIP", "relmse": "relMSE"}


def error_kinds(record):
    """[(files key, metric, label)] of the record's error maps, in files-key order."""
    return [(k, k[len("error_"):], ERROR_LABELS.get(k[len("error_"):], k[len("error_"):]))
            for k in sorted(record.get("files", {})) if k.startswith("error_")]


class BadInput(Exception):
    pass


def read_exr(dir_, rel, key):
    import OpenImageIO as oiio
    path = os.path.join(dir_, rel)
    if not rel or not os.path.exists(path):
        raise BadInput(f"{os.path.join(dir_, 'results.json')}: {key}: '{path}' not found")
    inp = oiio.ImageInput.open(path)
    if not inp:
        raise BadInput(f"{os.path.join(dir_, 'results.json')}: {key}: cannot read '{path}': {oiio.geterror()}")
    spec = inp.spec()
    names = list(spec.channelnames)
    px = inp.read_image(0, 0, 0, spec.nchannels, "float")
    inp.close()
    if px is None:
        raise BadInput(f"{os.path.join(dir_, 'results.json')}: {key}: cannot read '{path}'")
    px = np.asarray(px, dtype=np.float32).reshape(spec.height, spec.width, spec.nchannels)
    idx = []
    for c in ("R", "G", "B"):
        if c not in names:
            raise BadInput(f"{os.path.join(dir_, 'results.json')}: {key}: '{path}' has no channel '{c}' ({', '.join(names)})")
        idx.append(names.index(c))
    return px[:, :, idx]


def write_image(out_dir, scene_i, j, px):
    """Half floats, deflated, base64, as a script; returns the page-relative file name."""
    h, w, c = px.shape
    half = np.clip(np.nan_to_num(px, nan=0.0, posinf=65504.0, neginf=-65504.0), -65504, 65504).astype("<f2")
    b64 = base64.b64encode(zlib.compress(half.tobytes(), 6)).decode("ascii")
    rel = f"web/viewer/s{scene_i}/{j}.js"
    path = os.path.join(out_dir, rel)
    os.makedirs(os.path.dirname(path), exist_ok=True)
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        f.write(f'DNB.image("{scene_i}/{j}", {w}, {h}, {c}, "deflate", "{b64}");\n')
    os.replace(tmp, path)
    return rel


def window_means(m, cw, ch):
    """Mean of m over every cw x ch window, indexed by its top-left corner."""
    s = np.zeros((m.shape[0] + 1, m.shape[1] + 1))
    s[1:, 1:] = np.cumsum(np.cumsum(m, 0), 1)
    return (s[ch:, cw:] - s[:-ch, cw:] - s[ch:, :-cw] + s[:-ch, :-cw]) / (cw * ch)


def pick_crops(maps, w, h):
    """The worst-FLIP window of the chosen method, and the worst-relMSE one not overlapping it."""
    cw, ch = max(8, w // 6), max(8, h // 6)
    cw, ch = min(cw, w), min(ch, h)
    crops = []
    for kind, why in (("flip", "largest FLIP error"), ("relmse", "largest relMSE")):
        if kind not in maps:
            continue
        mm = window_means(maps[kind].astype(np.float64), cw, ch)
        for c in crops:  # windows overlapping an earlier crop are out
            mm[max(0, c["y"] - ch + 1):c["y"] + c["h"], max(0, c["x"] - cw + 1):c["x"] + c["w"]] = -np.inf
        if not np.isfinite(mm).any():
            continue
        y, x = np.unravel_index(int(np.argmax(mm)), mm.shape)
        crops.append({"x": int(x), "y": int(y), "w": cw, "h": ch, "why": why})
    if not crops:
        crops.append({"x": 0, "y": 0, "w": cw, "h": ch, "why": "no error map: the top-left corner"})
    return crops


def finite(v):
    return v if v is not None and math.isfinite(v) else None


def scene_records(res, scene, spp, seed):
    out = []
    for i, r in enumerate(res["records"]):
        if r["scene"] != scene or r.get("role") == "plain" or r["spp"] != spp:
            continue
        if seed is not None and r.get("seed") not in (None, seed):
            continue
        if not r.get("files", {}).get("image"):
            continue
        out.append((i, r))
    # The input first, then the methods in record order, then the ablation variants.
    order = {"input": 0, "method": 1, "ablation": 2}
    out.sort(key=lambda ir: order.get(ir[1].get("role"), 3))
    return out


def worse_tiles(r, i):
    """The record's tiles where the method is worse than its input ([x, y, w, h, ratio], worst first)."""
    out = []
    for k, t in enumerate(r.get("worse_tiles", [])):
        if not (isinstance(t, list) and len(t) == 5 and all(isinstance(v, (int, float)) for v in t)):
            raise BadInput(f"records[{i}].worse_tiles[{k}]: expected [x, y, w, h, ratio] numbers, got {t!r}")
        out.append([int(t[0]), int(t[1]), int(t[2]), int(t[3]), float(t[4])])
    return out


def colour_map(name):
    import matplotlib
    cmap = matplotlib.colormaps[name]
    return [[int(round(255 * v)) for v in cmap(i / 255)[:3]] for i in range(256)]


def build_scene(dir_, res, scene_i, scene, spp, seed, pick_method):
    recs = scene_records(res, scene, spp, seed)
    if not recs:
        return None
    images = []
    maps_of = {}  # method -> kind -> 2-D map (for crops)
    ref_rel = recs[0][1]["reference"].get("image", "")
    ref_key = f"records[{recs[0][0]}].reference.image"
    if not ref_rel:
        return None  # a hand-written document without its reference: nothing to compare against
    ref = read_exr(dir_, ref_rel, ref_key)
    h, w, _ = ref.shape
    j = 0

    def add(px, **entry):
        nonlocal j
        if px.shape[0] != h or px.shape[1] != w:
            raise BadInput(f"{os.path.join(dir_, 'results.json')}: {entry['key']}: {px.shape[1]}x{px.shape[0]}, "
                           f"the reference is {w}x{h}")
        entry["file"] = write_image(dir_, scene_i, j, px)
        entry["id"] = f"{scene_i}/{j}"
        j += 1
        images.append(entry)

    for i, r in recs:
        m = r["method"]
        key = f"records[{i}].files.image"
        px = read_exr(dir_, r["files"]["image"], key)
        metrics = {k: finite(r["metrics"].get(k)) for k in ("mse", "relmse", "flip", "ssim", "psnr")}
        label = m if r.get("role") != "input" else f"input ({spp} spp)"
        add(px, key=key, label=label, method=m, kind="radiance", role=r.get("role"), metrics=metrics,
            filter_seconds=finite(r.get("times", {}).get("filter")), worse_tiles=worse_tiles(r, i))
        if len(images) == 1:
            add(ref, key=ref_key, label=f"reference ({r['reference'].get('spp')} spp)", method="reference",
                kind="radiance", role="reference", metrics={})
    for i, r in recs:
        m = r["method"]
        for files_key, kind, klabel in error_kinds(r):
            rel = r.get("files", {}).get(files_key)
            if not rel:
                continue
            key = f"records[{i}].files.{files_key}"
            px = read_exr(dir_, rel, key)[:, :, :1]
            maps_of.setdefault(m, {})[kind] = px[:, :, 0]
            add(px, key=key, label=f"{klabel} error: {m}", method=m, kind=kind, role="error",
                metrics={kind: finite(r["metrics"].get(kind))})

    names = [r["method"] for _, r in recs]
    pick = pick_method if pick_method in maps_of else next((n for n in names if n in maps_of and n != "input"),
                                                           next(iter(maps_of), None))
    crops = pick_crops(maps_of.get(pick, {}), w, h)
    for c in crops:
        c["of"] = pick
        c["metrics"] = {}
        for m, kinds in maps_of.items():
            c["metrics"][m] = {k: float(mp[c["y"]:c["y"] + c["h"], c["x"]:c["x"] + c["w"]].mean())
                               for k, mp in kinds.items()}
    # relMSE's colour scale: whole decades spanning the scene's maps (1st to 99.9th percentile).
    rel = [mp["relmse"] for mp in maps_of.values() if "relmse" in mp]
    scales = {"flip": {"min": 0.0, "max": 1.0, "log": False, "colormap": "magma"},
              "hdrflip": {"min": 0.0, "max": 1.0, "log": False, "colormap": "magma"}}
    if rel:
        allv = np.concatenate([r.ravel() for r in rel])
        pos = allv[allv > 0]
        hi = math.ceil(math.log10(float(np.percentile(pos, 99.9)))) if pos.size else 0
        lo = math.floor(math.log10(float(np.percentile(pos, 1)))) if pos.size else -4
        lo = max(lo, hi - 6)
        if lo >= hi:
            lo = hi - 1
        scales["relmse"] = {"min": 10.0 ** lo, "max": 10.0 ** hi, "log": True, "colormap": "viridis"}
    # Table 2's CPU method (the one the crops follow) on the left when it ran, else the first method.
    first_method = next((e for e in images if e["kind"] == "radiance" and e["method"] == pick),
                        next((e for e in images if e["role"] in ("method", "ablation")), images[0]))
    return {
        "name": scene, "index": scene_i, "width": w, "height": h, "spp": spp, "seed": seed,
        "reference_spp": recs[0][1]["reference"].get("spp"),
        "images": images, "crops": crops, "scales": scales,
        "left": first_method["id"], "right": images[1]["id"] if len(images) > 1 else images[0]["id"],
    }


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: viewer.py RESULTS_DIR")
    dir_ = sys.argv[1]
    path = os.path.join(dir_, "results.json")
    with open(path) as f:
        res = json.load(f)
    cfg = res.get("config", {})
    recs = res.get("records", [])
    spp = (cfg.get("spp") or [r["spp"] for r in recs if r.get("role") != "plain"] or [0])[0]
    seeds = cfg.get("seeds") or []
    seed = seeds[0] if seeds else None
    scenes = cfg.get("scenes") or list(dict.fromkeys(r["scene"] for r in recs))
    pick = cfg.get("table2", {}).get("filter_cpu", "proposed")
    # Frame rows of the config's sequences (experiment/config.cpp sequence_row: name.fNN).
    row_of = {f"{name}.f{t:02d}": (name, t) for name, n in (cfg.get("sequences") or {}).items() for t in range(int(n))}
    try:
        out = []
        for i, s in enumerate(scenes):
            sc = build_scene(dir_, res, i, s, spp, seed, pick)
            if sc:
                if s in row_of:
                    sc["sequence"], sc["frame"] = row_of[s]
                out.append(sc)
    except BadInput as e:
        print(f"error: {e}", file=sys.stderr)
        sys.exit(2)
    sequences = []
    for name, n in (cfg.get("sequences") or {}).items():
        at = sorted((sc["frame"], k) for k, sc in enumerate(out) if sc.get("sequence") == name)
        if not at:
            continue
        frames = [out[k] for _, k in at]
        for kind in ("relmse",):  # one colour scale over the frames
            sc_ = [f["scales"][kind] for f in frames if kind in f["scales"]]
            if sc_:
                lo, hi = min(x["min"] for x in sc_), max(x["max"] for x in sc_)
                lo = max(lo, hi / 1e6)
                for f in frames:
                    if kind in f["scales"]:
                        f["scales"][kind] = dict(f["scales"][kind], min=lo, max=hi)
        sequences.append({"name": name, "frames": int(n), "rows": [out[k]["name"] for _, k in at],
                          "scenes": [k for _, k in at]})
    parents = method_style.parents(recs)
    manifest = {
        "scenes": out,
        "sequences": sequences,
        "colormaps": {"magma": colour_map("magma"), "viridis": colour_map("viridis")},
        "styles": {m: method_style.style(m, p)["colour"] for m, p in list(parents.items()) + [("reference", None)]},
    }
    mpath = os.path.join(dir_, "web/viewer/manifest.js")
    os.makedirs(os.path.dirname(mpath), exist_ok=True)
    with open(mpath + ".tmp", "w") as f:
        f.write("var DNB_MANIFEST = " + json.dumps(manifest) + ";\n")
    os.replace(mpath + ".tmp", mpath)


if __name__ == "__main__":
    main()
