"""Test plug-in: a worker whose trained weights are missing says so instead of being ready."""
import json
import sys
print(json.dumps({"ready": False, "unavailable": "no weights in t_unavailable/weights.pt: train them with train.py"}))
