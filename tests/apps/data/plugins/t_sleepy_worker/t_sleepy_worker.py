"""Test plug-in: a worker that takes 2 s to start (a model loading) and no time per frame."""
import time
from denoisebench_plugin import run
run(lambda frame, params, state: frame["color"], setup=lambda: time.sleep(2.0))
