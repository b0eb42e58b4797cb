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


def display(x):
    """The harness's display transform (docs/design.md, `mse`): clamp to [0, 1], sRGB."""
    c = np.clip(np.asarray(x, np.float64), 0.0, 1.0)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1 / 2.4) - 0.055)


def box_mean(a, r):
    """The mean of H x W array `a` over each pixel's (2r + 1)^2 window, the border replicated
    (an integral image: O(1) per pixel whatever r)."""
    p = np.pad(np.asarray(a, np.float64), r + 1, mode="edge")
    s = p.cumsum(0).cumsum(1)
    h, w = a.shape
    n = 2 * r + 1
    return (s[n:n + h, n:n + w] - s[:h, n:n + w] - s[n:n + h, :w] + s[:h, :w]) / (n * n)


# The two halves of a tracer frame (layer::at_half): the even and the odd samples, independent
# estimates of each pixel. A layer the halves lack is made for one half as follows.
HALF_LAYERS = ("color", "direct", "indirect", "albedo", "normal", "depth")


def half_frame(frame, h, layers):
    """Half h (0, 1) of `frame` as a dict of the named `layers`, for running a network on half of
    the samples. Layers in the halves are the half's own; `variance` is twice the frame's (the
    variance of a mean of half the samples); `emission` is the frame's (the emitter seen first,
    nearly noise-free); `reflection` is what is left of the half's colour after its diffuse
    part and the emission, F_h - (D_h + I_h) T_h - E (the tracer's split is exact on pixel
    means: F = (D + I) T + R + E). None when the frame lacks a half layer this needs (an
    imported frame)."""
    if any(name not in frame for name in half_layers(layers)):
        return None
    out = {}
    for name in layers:
        if name in HALF_LAYERS:
            out[name] = frame[f"half{h}.{name}"]
        elif name == "variance":
            out[name] = 2.0 * np.asarray(frame["variance"], np.float32)
        elif name == "emission":
            out[name] = frame["emission"]
        elif name == "reflection":
            c, t = frame[f"half{h}.color"], frame[f"half{h}.albedo"]
            out[name] = c - (frame[f"half{h}.direct"] + frame[f"half{h}.indirect"]) * t - frame["emission"]
        else:
            raise KeyError(f"half_frame: no half of layer '{name}'")
    return out


def half_layers(layers):
    """The manifest's optional layers `half_frame` reads to build both halves of `layers`."""
    need = set(n for n in layers if n in HALF_LAYERS)
    if "reflection" in layers:
        need |= {"color", "direct", "indirect", "albedo"}
    return [f"half{h}.{n}" for h in (0, 1) for n in HALF_LAYERS if n in need]


# The significance gate of `cross_validated_weight`: a window's estimated gain counts in full
# from GATE_FULL standard errors of its estimate up, not at all below GATE_ZERO, linearly between.
GATE_ZERO, GATE_FULL = 1.0, 2.0


def cross_validated_weight(den, x, y, var_y, radius):
    """How far to trust a denoised image over its noisy input, judged against an independent
    estimate: `x` is one half's colour, `den` the denoiser's output on that half alone, `y` the
    other half (independent of both), `var_y` its variance per pixel (H x W x 3). In the
    harness's display space (Table 1's), with e = den - x over the (2r + 1)^2 window W,

        w = clip(sum_W e (y - x) / sum_W e^2, 0, 1)

    is the least-squares weight of x + w e against y; as y = mu + noise independent of e, it is
    an unbiased estimate of the weight against the true mean mu, whatever the denoiser does (a
    network on a scene unlike its training). w is then scaled down where the numerator is within
    GATE_FULL of its own standard error (y's noise: sqrt(sum_W e^2 var(y)), var(y) carried
    through the display transform), and to 0 below GATE_ZERO: a change the halves cannot tell
    from noise is not made. Where the window shows no difference in display (saturated or black)
    w is 1. Returns H x W x 1."""
    dyy, dy = _display_with_noise(y, var_y)
    return _weight_in_display(display(den), display(x), dyy, dy, radius)


def _display_with_noise(y, var_y):
    """`y` in display space, and its noise there: display's slope times y's standard deviation."""
    sd = np.sqrt(np.maximum(np.asarray(var_y, np.float64), 0.0))
    yy = np.asarray(y, np.float64)
    return display(yy), 0.5 * (display(yy + sd) - display(np.maximum(yy - sd, 0.0)))


def _weight_in_display(dd, dx, dyy, dy, radius):
    """cross_validated_weight on images already in display space: the output dd, the judged half
    dx, the other half dyy and its noise dy."""
    e = dd - dx
    e = np.where(np.isfinite(e), e, 0.0)  # a non-finite output pixel: no change, and no NaN spread by the sums
    n = (2 * radius + 1) ** 2
    num = box_mean((e * (dyy - dx)).sum(axis=2), radius)
    den2 = box_mean((e * e).sum(axis=2), radius)
    se = np.sqrt(np.maximum(box_mean((e * e * dy * dy).sum(axis=2), radius), 0.0) / n)
    gate = np.clip((num / np.maximum(se, 1e-30) - GATE_ZERO) / (GATE_FULL - GATE_ZERO), 0.0, 1.0)
    return _window_weight(num, den2, gate)


def _window_weight(num, den2, gate=1.0):
    """The least-squares weight num / den2 of a window's change, clipped to [0, 1] and scaled by
    `gate`; 1 where the window shows no change in display (den2 ~ 0). H x W x 1."""
    flat = den2 <= 1e-18
    w = np.clip(num / np.where(flat, 1.0, den2), 0.0, 1.0)
    return np.where(flat, 1.0, w * gate)[:, :, None]


def cross_validated(color, output, halves, half_outputs, variance, radius):
    """The learned plug-ins' guard against making a frame worse than its input: the denoiser is
    also run on each half of the samples (`halves`: the two half colours, `half_outputs`: its
    outputs on them); each half's output is judged against the other half by
    `cross_validated_weight`, and the frame's output moves from the input towards `output` by
    the mean of the two weights: color + w (output - color). Where the network helps the halves
    say so and w ~ 1; where it erases what the input holds (thin texture at high spp), w ~ 0 and
    the input stays. Arrays H x W x 3; radius <= 0 returns `output`."""
    if radius <= 0:
        return output
    return blend(color, output, halves_weight(halves, half_outputs, variance, radius))


def halves_weight(halves, half_outputs, variance, radius):
    """`cross_validated`'s weight, H x W x 1: the mean of each half's `cross_validated_weight`
    against the other; `variance` is the frame's."""
    var_half = 2.0 * np.asarray(variance, np.float64)
    # Each half is judged once and is the other's yardstick once: its display image serves both.
    (xa, sa), (xb, sb) = (_display_with_noise(h, var_half) for h in halves)
    da, db = (display(o) for o in half_outputs)
    return 0.5 * (_weight_in_display(da, xa, xb, sb, radius) + _weight_in_display(db, xb, xa, sa, radius))


def blend(color, output, w):
    """color + w (output - color), float32: how every guard applies its weight w (H x W x 1)."""
    x = np.asarray(color, np.float64)
    return (x + w * (np.asarray(output, np.float64) - x)).astype(np.float32)


# The SURE guard's perturbation: tau standard deviations of the pixel's noise, with signs from a
# fixed seed (the output is a function of the frame only). 0.5: large enough that a float32
# network's response is not rounding, small against the noise the network removes.
SURE_TAU = 0.5
SURE_SEED = 20261207


def sure_weight(color, variance, output, perturbed_output, signs, radius, slope_at_output=False):
    """How far to trust a denoiser's output over its noisy input, judged on the frame itself by
    Stein's unbiased risk estimate (SURE; Stein 1981, as Li, Wu and Chuang's SURE-based
    reconstruction of 2012 uses it for renderings), with the divergence estimated by one
    perturbed run (Monte-Carlo SURE, Ramani, Blu and Unser 2008).

    In the display space of Table 1 (clamp, sRGB), y = display(color) = mu + n with per-pixel
    noise s^2 (the variance of the pixel's mean through the display's slope), g(y) =
    display(output) and e = g(y) - y. For the output y + w e, the expected squared error over a
    (2r + 1)^2 window W is, by Stein's lemma (E[n_i g_i(y)] = s_i^2 E[dg_i/dy_i]),

        sum_W s^2 + 2 w sum_W s^2 (dg_i/dy_i - 1) + w^2 sum_W e^2,

    lowest at w = sum_W s^2 (1 - dg_i/dy_i) / sum_W e^2, clipped to [0, 1]: the weight the
    halves' cross-validation estimates at half the samples, here at the frame's own noise.
    s_i^2 dg_i/dy_i comes from `perturbed_output`, the denoiser run on color + SURE_TAU sd signs
    (sd the pixel's noise, signs +-1 per pixel, the same on its three channels, whose noise
    is one path's): s_i signs_i (g_i(perturbed) - g_i(y)) / SURE_TAU, whose mean over the signs
    is s_i^2 dg_i/dy_i (the other pixels' terms have mean zero and average out over the window).
    Assumes each pixel's noise independent of the other pixels' (the tracer's pixels are) and
    its variance known (the frame's estimate, averaged over the window).

    slope_at_output: the display's slope taken at the output (an estimate of the mean) instead of
    at the noisy colour, whose slope is 0 where a firefly is clamped at 1 (the window then shows
    SURE no noise to remove, only a large change, and the weight drops). Better together with the
    halves' weight, worse alone (docs/method-defaults.md, "The SURE guard"), so `guard_weight` takes it
    only with the halves. Returns H x W x 1."""
    var = np.maximum(np.asarray(variance, np.float64), 0.0)
    dx, s = _display_with_noise(color, var)
    if slope_at_output:
        g, s = _display_with_noise(output, var)
    else:
        g = display(output)
    e = g - dx
    e = np.where(np.isfinite(e), e, 0.0)
    t = s * signs * (display(perturbed_output) - g) / SURE_TAU
    t = np.where(np.isfinite(t), t, 0.0)
    return _window_weight(box_mean((s * s - t).sum(axis=2), radius), box_mean((e * e).sum(axis=2), radius))


def sure_perturbation(color, variance):
    """The frame the SURE guard runs the denoiser on a second time (`sure_weight`), and its signs:
    color + SURE_TAU sd signs, clamped at 0, float32; signs H x W x 1 of +-1 from SURE_SEED."""
    x = np.asarray(color, np.float64)
    sd = np.sqrt(np.maximum(np.asarray(variance, np.float64), 0.0))
    signs = np.random.default_rng(SURE_SEED).choice(np.array([-1.0, 1.0]), size=x.shape[:2] + (1,))
    return np.maximum(x + SURE_TAU * sd * signs, 0.0).astype(np.float32), signs


def guard_weight(color, variance, output, radius=0, halves=None, half_outputs=None, sure=0, perturbed_output=None,
                 signs=None):
    """The weight `guarded` blends by, from the network's runs already made: the halves' (radius >
    0 and `halves` given, with the network's `half_outputs` on them), SURE's (sure > 0, from its
    `perturbed_output` on `sure_perturbation`'s frame and `signs`; with the halves' weight there
    too, the display's slope at the output), the smaller of the two where both are. None where
    neither applies. H x W x 1."""
    weights = []
    if radius > 0 and halves is not None:
        weights.append(halves_weight(halves, half_outputs, variance, radius))
    if sure > 0:
        weights.append(sure_weight(color, variance, output, perturbed_output, signs, sure,
                                   slope_at_output=bool(weights)))
    if not weights:
        return None
    return weights[0] if len(weights) == 1 else np.minimum(weights[0], weights[1])


def guarded(frame, output, denoise, layers, radius, clamp, sure=0):
    """A learned plug-in's output made safe against its input. With radius > 0 and the frame's
    half buffers, the halves' weight (`cross_validated`: the network run again on each half
    through `denoise`, a function of a dict of `layers`); with sure > 0, SURE's weight over
    windows of that radius (`sure_weight`: the network run again on the frame with its colour
    perturbed; with the halves too, the display's slope at the output); with both, the smaller of
    the two at each pixel: the output moves from the input only as far as both judges say it
    helps (`guard_weight`). With neither (radius and sure 0, or no halves and sure 0),
    `noise_clamp` at `clamp` standard deviations."""
    x, var = frame["color"], frame["variance"]
    halves = half_colors = half_outputs = None
    if radius > 0:
        halves = [half_frame(frame, h, layers) for h in (0, 1)]
        if halves[0] is not None:
            half_colors, half_outputs = [h["color"] for h in halves], [denoise(h) for h in halves]
    perturbed_output = signs = None
    if sure > 0:
        perturbed, signs = sure_perturbation(x, var)
        perturbed_output = denoise({**{name: frame[name] for name in layers}, "color": perturbed})
    w = guard_weight(x, var, output, radius, half_colors, half_outputs, sure, perturbed_output, signs)
    return noise_clamp(x, var, output, clamp) if w is None else blend(x, output, w)


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
