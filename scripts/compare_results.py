#!/usr/bin/python3
"""Compares two results folders of `denoisebench run` on everything but provenance and timing.

    scripts/compare_results.py OLD_DIR NEW_DIR [--images]

Records are matched by (scene, method, spp, seed) (a config of several seeds has a record per seed); each must have the same role, metrics (exactly),
parameters, reference settings and file names. Left out, because they differ between any two
runs or builds: the header's format/schema_version/machine/build/git_revision/written, and each
record's cell_key (it hashes the build), times, phases, counters, cache hits and the reference's
seconds. With --images, every image both records name is compared pixel by pixel with OIIO's
idiff (exact). Exit 0 when equal, 1 with the differences listed.
"""
import json
import subprocess
import sys

IGNORED_RECORD_KEYS = {"cell_key", "times", "phases", "counters", "input_cache_hit"}
IGNORED_REFERENCE_KEYS = {"seconds", "cache_hit"}
# Counters that are measurements of time, not of the work done.
TIMING_COUNTERS = ("seconds", "_ms")


def comparable(record):
    r = {k: v for k, v in record.items() if k not in IGNORED_RECORD_KEYS}
    r["reference"] = {k: v for k, v in record.get("reference", {}).items() if k not in IGNORED_REFERENCE_KEYS}
    counters = record.get("counters") or {}
    r["work_counters"] = {k: v for k, v in counters.items() if not k.endswith(TIMING_COUNTERS)}
    return r


def load(folder):
    with open(folder + "/results.json") as f:
        doc = json.load(f)
    return doc, {(r["scene"], r["method"], r["spp"], r.get("seed")): r for r in doc["records"]}


def main(argv):
    args = [a for a in argv[1:] if not a.startswith("--")]
    if len(args) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    (old_doc, old), (new_doc, new) = load(args[0]), load(args[1])
    diffs = []
    cfg_old = {k: v for k, v in old_doc.get("config", {}).items() if k != "path"}
    cfg_new = {k: v for k, v in new_doc.get("config", {}).items() if k != "path"}
    if cfg_old != cfg_new:
        diffs.append(f"config differs: {cfg_old} vs {cfg_new}")
    for key in sorted(set(old) | set(new)):
        if key not in old or key not in new:
            diffs.append(f"{key}: only in {'new' if key in new else 'old'}")
            continue
        a, b = comparable(old[key]), comparable(new[key])
        for k in sorted(set(a) | set(b)):
            if a.get(k) != b.get(k):
                diffs.append(f"{key} {k}: {a.get(k)} vs {b.get(k)}")
        if "--images" in argv:
            for name, rel in sorted(old[key].get("files", {}).items()):
                other = new[key].get("files", {}).get(name)
                if other is None:
                    continue
                p = subprocess.run(["idiff", "-q", "-fail", "0", "-failpercent", "0", "-warn", "0",
                                    f"{args[0]}/{rel}", f"{args[1]}/{other}"], capture_output=True, text=True)
                if p.returncode != 0:
                    diffs.append(f"{key} {name}: pixels differ ({rel})")
    order_old = [(r["scene"], r["method"], r["spp"], r.get("seed")) for r in old_doc["records"]]
    order_new = [(r["scene"], r["method"], r["spp"], r.get("seed")) for r in new_doc["records"]]
    if order_old != order_new:
        diffs.append("records are in another order")
    for d in diffs:
        print(d)
    print(f"{len(old)} records compared: {'equal' if not diffs else f'{len(diffs)} differences'}")
    return 1 if diffs else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
