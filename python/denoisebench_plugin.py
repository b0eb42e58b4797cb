"""Helper for denoisebench plug-ins written in Python (docs/plugins.md).

A plug-in is any program that speaks one of two protocols; this module speaks both around one
function of yours, so that a plug-in is a manifest and a few lines:

    import numpy as np
    from denoisebench_plugin import run

    def denoise(frame, params):
        # frame["albedo"] is an H x W x 3 float32 array; frame.meta has scene, spp, seed
        return frame["color"]          # H x W x 3: the harness writes nothing else

    run(denoise)

`run` picks the protocol from the command line: `--input IN.exr --output OUT.exr [--param k=v]`
is protocol "frame" (one frame, then exit); no arguments is protocol "worker" (print the ready
line, then one JSON request per line on stdin until it closes). Anything your function prints
goes to the harness's log: in worker mode stdout carries the protocol, so `print` is sent to
stderr.

Needs NumPy and OpenImageIO's Python binding (Debian: python3-numpy, python3-openimageio; the
harness's scripts/setup installs both). The harness puts this folder on PYTHONPATH.
"""

import json
import os
import sys
import traceback

import numpy as np
import OpenImageIO as oiio

_ORDER = {"R": 0, "G": 1, "B": 2, "X": 0, "Y": 1, "Z": 2}


class Frame:
    """The layers of one input frame by the harness's layer names (docs/design.md): 'color',
    'direct', 'indirect', 'albedo', 'reflection', 'emission', 'normal', 'depth', 'variance',
    ..., 'refl1.color' ... Each is an H x W x C float32 array (C = 3, or 1 for depth, edge,
    samples). `meta` holds the frame's metadata: scene, spp, seed, size."""

    def __init__(self, layers, meta):
        self.layers = layers
        self.meta = meta
        # Worker protocol, frames of a sequence: {"id": ..., "index": t, "count": n}; None for a
        # still. A temporal plug-in (manifest `temporal = true`) keeps its history per id and
        # starts afresh at index 0 (docs/plugins.md, "Sequences").
        self.sequence = None
        first = next(iter(layers.values()))
        self.height, self.width = first.shape[0], first.shape[1]

    def __getitem__(self, name):
        if name not in self.layers:
            raise KeyError(f"the frame has no layer '{name}' (it has: {', '.join(sorted(self.layers))}); "
                           "declare it in the manifest's layers")
        return self.layers[name]

    def __contains__(self, name):
        return name in self.layers


def _layer_of(channel):
    # "R" -> ("color", "R"); "normal.X" -> ("normal", "X"); "refl1.color.G" -> ("refl1.color", "G")
    if "." not in channel:
        return "color", channel
    layer, _, comp = channel.rpartition(".")
    return layer, comp


def read_frame(path):
    """Reads an EXR written by the harness into a Frame (channels looked up by name)."""
    inp = oiio.ImageInput.open(path)
    if inp is None:
        raise RuntimeError(f"cannot open '{path}': {oiio.geterror()}")
    try:
        spec = inp.spec()
        pixels = inp.read_image(0, 0, 0, spec.nchannels, oiio.FLOAT)
        if pixels is None:
            raise RuntimeError(f"cannot read '{path}': {inp.geterror()}")
        pixels = np.asarray(pixels, dtype=np.float32).reshape(spec.height, spec.width, spec.nchannels)
        groups = {}
        for i, name in enumerate(spec.channelnames):
            layer, comp = _layer_of(name)
            groups.setdefault(layer, []).append((_ORDER.get(comp, 9), i))
        layers = {layer: np.ascontiguousarray(pixels[:, :, [i for _, i in sorted(chans)]])
                  for layer, chans in groups.items()}
        meta = {}
        for key in ("scene", "spp", "seed", "size", "tracer_version", "reflection_levels"):
            v = spec.getattribute("denoisebench:" + key)
            if v is not None:
                meta[key] = v
        return Frame(layers, meta)
    finally:
        inp.close()


def write_rgb(path, image):
    """Writes an H x W x 3 array as an EXR with channels R, G, B (to a temporary name, then
    renamed, so the harness never reads half a file)."""
    img = np.ascontiguousarray(np.asarray(image, dtype=np.float32))
    if img.ndim != 3 or img.shape[2] != 3:
        raise ValueError(f"the output must be H x W x 3, got shape {img.shape}")
    tmp = f"{path}.tmp-{os.getpid()}.exr"
    spec = oiio.ImageSpec(img.shape[1], img.shape[0], 3, oiio.FLOAT)
    spec.channelnames = ("R", "G", "B")
    spec.attribute("compression", "none")
    out = oiio.ImageOutput.create(tmp)
    if out is None or not out.open(tmp, spec) or not out.write_image(img) or not out.close():
        raise RuntimeError(f"cannot write '{path}': {oiio.geterror()}")
    os.replace(tmp, path)


def _parse_value(text):
    # The frame protocol passes every parameter as text; the harness has already checked it
    # against the manifest's type, so the text says which type it is.
    if text in ("true", "false"):
        return text == "true"
    for conv in (int, float):
        try:
            return conv(text)
        except ValueError:
            pass
    return text


def _run_frame(fn, argv):
    args = {"--input": None, "--output": None}
    params = {}
    i = 0
    while i < len(argv):
        a = argv[i]
        if a in args and i + 1 < len(argv):
            args[a] = argv[i + 1]
        elif a == "--param" and i + 1 < len(argv) and "=" in argv[i + 1]:
            k, _, v = argv[i + 1].partition("=")
            params[k] = _parse_value(v)
        else:
            sys.exit(f"unexpected argument '{a}' (expected --input IN.exr --output OUT.exr [--param key=value ...])")
        i += 2
    if not args["--input"] or not args["--output"]:
        sys.exit("expected --input IN.exr --output OUT.exr")
    write_rgb(args["--output"], fn(read_frame(args["--input"]), params))


def _run_worker(fn, setup, info):
    protocol = sys.stdout
    sys.stdout = sys.stderr  # the user's prints go to the log, never into the protocol
    state = setup() if setup else None

    def answer(obj):
        protocol.write(json.dumps(obj) + "\n")
        protocol.flush()

    ready = {"ready": True}
    if info is not None:
        ready["info"] = dict(info(state) if callable(info) else info)
    answer(ready)
    for line in sys.stdin:
        if not line.strip():
            continue
        try:
            req = json.loads(line)
            frame = read_frame(req["input"])
            frame.sequence = req.get("sequence")
            params = req.get("params", {})
            out = fn(frame, params, state) if setup else fn(frame, params)
            write_rgb(req["output"], out)
            answer({"ok": True})
        except Exception as e:  # one bad frame fails that frame, not the worker
            traceback.print_exc(file=sys.stderr)
            answer({"ok": False, "error": f"{type(e).__name__}: {e}"})


def unavailable(name, why):
    """Says plug-in `name` cannot run here (no weights, a missing library) and exits: in the worker
    protocol as its ready line {"ready": false, "unavailable": why}, so the harness skips its
    cells with that reason; in the frame protocol (arguments given) as an error."""
    if len(sys.argv) > 1:
        sys.exit(f"{name}: {why}")
    sys.__stdout__.write(json.dumps({"ready": False, "unavailable": why}) + "\n")
    sys.__stdout__.flush()
    sys.exit(0)


def require_torch(name):
    """Imports PyTorch for learned plug-in `name`, or says the plug-in is unavailable (Debian's
    python3-torch, which scripts/setup installs, is missing)."""
    try:
        import torch  # noqa: F401
    except ImportError as e:
        unavailable(name, f"PyTorch is not importable ({e}): install Debian's python3-torch (scripts/setup does)")


def torch_threads(n):
    """Sets PyTorch's intra-op threads (n <= 0: every core this process may use) and returns the
    count. For the learned plug-ins' `threads` parameter."""
    import torch

    if n <= 0:
        n = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    torch.set_num_threads(n)
    return n


def _validation_summary(rows):
    """One line from a weights manifest's held-out rows: the mean 8-bit mse of input and net."""
    a = sum(r["input_mse"] for r in rows) / len(rows)
    b = sum(r["net_mse"] for r in rows) / len(rows)
    scenes = len({r["scene"] for r in rows})
    return f"8-bit mse {a:.2f} -> {b:.2f} (mean of {len(rows)} held-out frames, {scenes} scenes)"


def learned_weights(name, folder, env, train, load, parameter_count):
    """The weights of learned plug-in `name` (kpcn, unet): the file named by the first set
    variable of `env`, else FOLDER/weights/NAME.pt; without it, `unavailable` saying to run
    `train`. Returns (model, info): `load(path)`'s model and what every cell records (the
    weights' SHA-256, the training's steps, scenes and held-out scores from the manifest NAME.json
    the training script wrote beside them)."""
    import hashlib

    path = next((os.environ[v] for v in env if os.environ.get(v)), os.path.join(folder, "weights", f"{name}.pt"))
    if not os.path.isfile(path):
        unavailable(name, f"no trained weights at '{path}': train them with {train}")
    with open(path, "rb") as f:
        digest = hashlib.sha256(f.read()).hexdigest()
    model = load(path)
    manifest = {}
    man_path = os.path.splitext(path)[0] + ".json"
    if os.path.isfile(man_path):
        with open(man_path) as f:
            manifest = json.load(f)
    print(f"{name}: weights {path} (sha256 {digest[:16]}, {parameter_count(model)} parameters, "
          f"{manifest.get('steps', '?')} training steps)")
    info = {"weights": os.path.relpath(path, folder) if path.startswith(folder) else path, "weights_sha256": digest,
            "parameters": parameter_count(model)}
    for key in ("steps", "train_seconds", "final_loss", "script_sha256", "model_sha256", "torch_version"):
        if key in manifest:
            info[key] = manifest[key]
    if "scenes" in manifest:
        info["trained_on"] = ", ".join(s["name"] for s in manifest["scenes"] if s.get("split") != "validation")
    if manifest.get("validation"):
        info["validation"] = _validation_summary(manifest["validation"])
    return model, info


def noise_clamp(color, variance, output, c):
    """Limits how far a denoiser moves each pixel from its noisy input to `c` standard
    deviations of the pixel's mean, per channel: out = color + clip(output - color, -c s, c s),
    s = sqrt(variance averaged over the pixel's 3x3 neighbourhood; the per-pixel estimate has 7
    degrees of freedom, the average about 60). A converged pixel (s ~ 0) keeps its value; a noisy
    one may move as far as its noise reaches. c <= 0 returns `output` unchanged. Arrays are
    H x W x 3. The learned plug-ins use it against erasing what a nearly converged input already
    holds (docs/method-defaults.md, "The learned baselines on scenes outside the corpus")."""
    if c <= 0:
        return output
    v = np.maximum(np.asarray(variance, np.float64), 0.0)
    p = np.pad(v, ((1, 1), (1, 1), (0, 0)), mode="edge")
    h, w = v.shape[:2]
    mean = sum(p[1 + dy:1 + dy + h, 1 + dx:1 + dx + w] for dy in (-1, 0, 1) for dx in (-1, 0, 1)) / 9.0
    bound = c * np.sqrt(mean)
    x = np.asarray(color, np.float64)
    return (x + np.clip(np.asarray(output, np.float64) - x, -bound, bound)).astype(np.float32)

def run(fn, setup=None, info=None):
    """Runs `fn(frame, params) -> H x W x 3 array` under the protocol the harness started this
    program with. With `setup` (worker protocol), `setup()` runs once before the ready line (load
    a model there: it is timed as start-up, not per frame) and `fn(frame, params, state)` gets
    its result. `info` (worker protocol; a dict of JSON values, or a function of setup's result
    that returns one) is sent in the ready line, `{"ready": true, "info": {...}}`: what was
    loaded, such as a library's version."""
    argv = sys.argv[1:]
    if argv:
        if setup:
            fn_frame = fn
            state = setup()
            fn = lambda frame, params: fn_frame(frame, params, state)  # noqa: E731
        _run_frame(fn, argv)
    else:
        _run_worker(fn, setup, info)
