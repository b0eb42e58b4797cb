"""Test plug-in: returns the input colour unchanged."""
from denoisebench_plugin import run
run(lambda frame, params: frame["color"])
