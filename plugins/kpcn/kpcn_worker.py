"""Plug-in (protocol "worker"): kpcn, a kernel-predicting convolutional network trained here
(kpcn_model.py says what it is; scripts/train_kpcn trains it; docs/method-defaults.md, "kpcn",
says on what and how long).

The weights are the training script's output, never downloaded: `weights/kpcn.pt` beside this
file (hashed into every kpcn cell's key, like all of the plug-in's folder), or the file named by
$DENOISEBENCH_KPCN_WEIGHTS (or its older alias $DNB_KPCN_WEIGHTS; for trying other weights with `denoise`; not part of the cells' keys, so put
weights an experiment uses into weights/). Without weights, or without PyTorch, the worker
answers {"ready": false, "unavailable": ...} saying how to get them: the kpcn cells of an
experiment are then skipped with that reason, not failed. The weights are loaded once, at
start-up; the ready line carries their SHA-256 and what they were trained on (the manifest the
training script writes beside them), recorded in every kpcn cell of results.json.
"""
import hashlib
import json
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_WEIGHTS = os.path.join(HERE, "weights", "kpcn.pt")
TRAIN = "scripts/train_kpcn --out plugins/kpcn/weights (docs/method-defaults.md, \"kpcn\")"


def _unavailable(why):
    if len(sys.argv) > 1:  # frame protocol: an error
        sys.exit(f"kpcn: {why}")
    sys.__stdout__.write(json.dumps({"ready": False, "unavailable": why}) + "\n")
    sys.__stdout__.flush()
    sys.exit(0)


try:
    import torch  # noqa: F401
except ImportError as e:
    _unavailable(f"PyTorch is not importable ({e}): install Debian's python3-torch (scripts/setup does)")

import kpcn_model  # noqa: E402
from denoisebench_plugin import run  # noqa: E402


def setup():
    path = os.environ.get("DENOISEBENCH_KPCN_WEIGHTS") or os.environ.get("DNB_KPCN_WEIGHTS") or DEFAULT_WEIGHTS
    if not os.path.isfile(path):
        _unavailable(f"no trained weights at '{path}': train them with {TRAIN}")
    with open(path, "rb") as f:
        digest = hashlib.sha256(f.read()).hexdigest()
    model = kpcn_model.load(path)
    manifest = {}
    man_path = os.path.splitext(path)[0] + ".json"
    if os.path.isfile(man_path):
        with open(man_path) as f:
            manifest = json.load(f)
    print(f"kpcn: weights {path} (sha256 {digest[:16]}, {kpcn_model.parameter_count(model)} parameters, "
          f"{manifest.get('steps', '?')} training steps)")
    info = {"weights": os.path.relpath(path, HERE) if path.startswith(HERE) else path, "weights_sha256": digest}
    for key in ("steps", "train_seconds", "final_loss", "script_sha256", "torch_version"):
        if key in manifest:
            info[key] = manifest[key]
    if "scenes" in manifest:
        info["trained_on"] = ", ".join(s["name"] for s in manifest["scenes"])
    return {"model": model, "info": info}


def denoise(frame, params, state):
    kpcn_model.threads(int(params.get("threads", 0)))
    planes = kpcn_model.prepare(frame)
    return kpcn_model.denoise_planes(state["model"], planes)


run(denoise, setup=setup, info=lambda state: state["info"])
