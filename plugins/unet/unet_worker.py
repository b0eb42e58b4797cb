"""Plug-in (protocol "worker"): unet, an OIDN-style U-Net trained here (unet_model.py says what
it is; scripts/train_unet trains it; docs/method-defaults.md, "unet", says on what and how long).

The weights are the training script's output, never downloaded: `weights/unet.pt` beside this
file (hashed into every unet cell's key, like all of the plug-in's folder), or the file named by
$DENOISEBENCH_UNET_WEIGHTS (for trying other weights with `denoise`; not part of the cells' keys,
so put weights an experiment uses into weights/). Without weights, or without PyTorch, the worker
answers {"ready": false, "unavailable": ...} saying how to get them: the unet cells of an
experiment are then skipped with that reason, not failed. The weights are loaded once, at
start-up; the ready line carries their SHA-256, what they were trained on and their held-out
scores (from the manifest the training script writes beside them), recorded in every unet cell
of results.json.
"""
import hashlib
import json
import os
import sys

sys.dont_write_bytecode = True  # no __pycache__ in plugins/unet: its content is in cell keys

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_WEIGHTS = os.path.join(HERE, "weights", "unet.pt")
TRAIN = "scripts/train_unet --out plugins/unet/weights (docs/method-defaults.md, \"unet\")"

from denoisebench_plugin import run, torch_threads, unavailable  # noqa: E402

try:
    import torch  # noqa: F401
except ImportError as e:
    unavailable("unet", f"PyTorch is not importable ({e}): install Debian's python3-torch (scripts/setup does)")

import unet_model  # noqa: E402


def validation_summary(rows):
    """One line from the manifest's held-out rows: the mean 8-bit mse of the input and the net."""
    if not rows:
        return "no held-out frames"
    a = sum(r["input_mse"] for r in rows) / len(rows)
    b = sum(r["net_mse"] for r in rows) / len(rows)
    scenes = len({r["scene"] for r in rows})
    return f"8-bit mse {a:.2f} -> {b:.2f} (mean of {len(rows)} held-out frames, {scenes} scenes)"


def setup():
    path = os.environ.get("DENOISEBENCH_UNET_WEIGHTS") or DEFAULT_WEIGHTS
    if not os.path.isfile(path):
        unavailable("unet", f"no trained weights at '{path}': train them with {TRAIN}")
    with open(path, "rb") as f:
        digest = hashlib.sha256(f.read()).hexdigest()
    model = unet_model.load(path)
    manifest = {}
    man_path = os.path.splitext(path)[0] + ".json"
    if os.path.isfile(man_path):
        with open(man_path) as f:
            manifest = json.load(f)
    print(f"unet: weights {path} (sha256 {digest[:16]}, {unet_model.parameter_count(model)} parameters, "
          f"{manifest.get('steps', '?')} training steps)")
    info = {"weights": os.path.relpath(path, HERE) if path.startswith(HERE) else path, "weights_sha256": digest,
            "parameters": unet_model.parameter_count(model)}
    for key in ("steps", "train_seconds", "final_loss", "script_sha256", "model_sha256", "torch_version"):
        if key in manifest:
            info[key] = manifest[key]
    if "scenes" in manifest:
        info["trained_on"] = ", ".join(s["name"] for s in manifest["scenes"] if s.get("split") != "validation")
    if "validation" in manifest:
        info["validation"] = validation_summary(manifest["validation"])
    return {"model": model, "info": info}


def denoise(frame, params, state):
    torch_threads(int(params.get("threads", 0)))
    return unet_model.denoise_planes(state["model"], unet_model.prepare(frame))


run(denoise, setup=setup, info=lambda state: state["info"])
