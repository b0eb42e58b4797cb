"""Test plug-in: a temporal worker (manifest `temporal = true`). Its output is a constant image:
R the frames of this request's sequence it has seen, this one included (its history), G the
request's index, B 1 where the frame has a motion layer, else 0. It refuses a frame out of turn
(an index that is not the next of its sequence, other than 0), as a real temporal method would
produce garbage there."""
import numpy as np
from denoisebench_plugin import run


def denoise(frame, params, state):
    seq = frame.sequence
    key = seq["id"] if seq else None
    index = seq["index"] if seq else 0
    if index == 0:
        state[key] = 0
    elif state.get(key) != index:
        raise RuntimeError(f"frame {index} of {key} out of turn (expected {state.get(key)})")
    state[key] = state.get(key, 0) + 1
    out = np.zeros((frame.height, frame.width, 3), dtype=np.float32)
    out[:, :, 0] = state[key]
    out[:, :, 1] = index
    out[:, :, 2] = 1.0 if "motion" in frame else 0.0
    return out


run(denoise, setup=dict)
