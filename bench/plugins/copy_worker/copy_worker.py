"""Benchmark worker: the protocol with no filter (no NumPy, no EXR decoding). It answers with a
copy of $BENCH_OUTPUT_EXR (an R, G, B image of the frame's size the benchmark prepared), so that
reading the output costs what a real plug-in's 3-channel output costs."""
import json
import os
import shutil
import sys

print(json.dumps({"ready": True}), flush=True)
for line in sys.stdin:
    req = json.loads(line)
    shutil.copyfile(os.environ["BENCH_OUTPUT_EXR"], req["output"])
    print(json.dumps({"ok": True}), flush=True)
