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
import os

HERE = os.path.dirname(os.path.abspath(__file__))
TRAIN = "scripts/train_unet --out plugins/unet/weights (docs/method-defaults.md, \"unet\")"

from denoisebench_plugin import guarded, learned_weights, require_torch, run, torch_threads  # noqa: E402

require_torch("unet")

import unet_model  # noqa: E402


def setup():
    model, info = learned_weights("unet", HERE, ("DENOISEBENCH_UNET_WEIGHTS",), TRAIN, unet_model.load,
                                  unet_model.parameter_count)
    return {"model": model, "info": info}


def denoise(frame, params, state):
    torch_threads(int(params.get("threads", 0)))

    def net(layers):
        return unet_model.denoise_planes(state["model"], unet_model.prepare(layers))

    return guarded(frame, net(frame), net, unet_model.LAYERS, int(params.get("cross_validation", 2)),
                   float(params.get("noise_clamp", 1.5)), sure=int(params.get("sure", 2)))


run(denoise, setup=setup, info=lambda state: state["info"])
