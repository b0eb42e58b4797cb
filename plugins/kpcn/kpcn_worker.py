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
import os

HERE = os.path.dirname(os.path.abspath(__file__))
TRAIN = "scripts/train_kpcn --out plugins/kpcn/weights (docs/method-defaults.md, \"kpcn\")"

from denoisebench_plugin import guarded, learned_weights, require_torch, run, torch_threads  # noqa: E402

require_torch("kpcn")

import kpcn_model  # noqa: E402


def setup():
    model, info = learned_weights("kpcn", HERE, ("DENOISEBENCH_KPCN_WEIGHTS", "DNB_KPCN_WEIGHTS"), TRAIN, kpcn_model.load,
                                  kpcn_model.parameter_count)
    return {"model": model, "info": info}


def denoise(frame, params, state):
    torch_threads(int(params.get("threads", 0)))

    def net(layers):
        return kpcn_model.denoise_planes(state["model"], kpcn_model.prepare(layers))

    return guarded(frame, net(frame), net, kpcn_model.LAYERS, int(params.get("cross_validation", 3)),
                   float(params.get("noise_clamp", 2.0)))


run(denoise, setup=setup, info=lambda state: state["info"])
