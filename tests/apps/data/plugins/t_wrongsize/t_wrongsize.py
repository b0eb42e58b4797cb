"""Test plug-in: writes an image of half the size."""
from denoisebench_plugin import run
run(lambda frame, params: frame["color"][::2, ::2])
