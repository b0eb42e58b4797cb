"""Test plug-in: a worker that takes 2 s to start (a model loading) and no time per frame, and
says what it loaded in its ready line (recorded as the cells' method_info)."""
import time
from denoisebench_plugin import run
run(lambda frame, params, state: frame["color"], setup=lambda: time.sleep(2.0),
    info={"model": "sleepy-1", "layers": 3})
