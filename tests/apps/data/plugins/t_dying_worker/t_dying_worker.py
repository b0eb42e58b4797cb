"""Test plug-in: a worker that dies on every request."""
import os, sys
from denoisebench_plugin import run
def die(frame, params):
    print("dying on purpose", file=sys.stderr, flush=True)
    os._exit(3)
run(die)
