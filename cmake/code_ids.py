#!/usr/bin/env python3
"""Per-method code identities for the reuse of finished cells (docs/results.md, "Reuse").

A finished method cell may be reused only when the code that computed it is the code that would
compute it again. The hash of the whole program says that, but it changes with any edit, so a
change to one method re-ran every cell of every method (hours at the paper's size). This script,
run by the build after linking the program, gives each built-in method an identity of its own:
the SHA-256 of every object file of the program except the other methods' own files and the
build-identity object (core/build_info.cpp: the revision strings only, which change with every
commit and compute nothing).

A method's own file is the object that defines its factory, `dnb::<name>_method()`
(denoisers/builtin_methods.h). It counts as the method's own only when nothing else can reach its
code except through that factory:
  - none of its strong external symbols other than the factory is referenced by another object;
  - it has no static initialiser (code that runs at start-up, whatever method a run uses).
Otherwise it is shared code, part of every identity (a change to it re-runs every cell: safe).
Inline functions and template instances are emitted as weak copies into every object that uses
them and the linker keeps one; the one-definition rule makes those copies the same code, so which
object supplied it does not matter.

Written here because no tool computes it: the link map says which objects a program uses, not
which of them a given code path can reach. The program records its own SHA-256 here, so a file
left from another build is ignored (the program then falls back to its whole hash).

Usage: code_ids.py --program BIN --objects LIST --nm NM --binary-dir DIR --out JSON
                   [--identity-object REL] [--replace OBJ=FILE ...]
--identity-object: the build-identity object, relative to DIR. --replace hashes FILE in place of
object OBJ (relative to DIR): the test's way to "change" one object.
"""
import argparse
import hashlib
import json
import os
import re
import subprocess
import sys

FACTORY = re.compile(r"^_ZN3dnb(\d+)(\w+_method)Ev$")  # dnb::<name>_method(), <length><identifier>
WEAK_OR_UNDEFINED = set("UVWuvw")


def sha256_file(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def nm_lines(nm, path, *flags):
    out = subprocess.run([nm, *flags, path], check=True, capture_output=True, text=True).stdout
    for line in out.splitlines():
        parts = line.split()
        if len(parts) >= 2:
            yield parts[-2], parts[-1]  # type, name (the address column is absent for U)


def factory_name(symbol):
    """<name> when `symbol` is dnb::<name>_method() mangled, else None."""
    m = FACTORY.match(symbol)
    return m.group(2)[: -len("_method")] if m and len(m.group(2)) == int(m.group(1)) else None


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--program", required=True)
    ap.add_argument("--objects", required=True, help="file listing the program's objects, one a line")
    ap.add_argument("--nm", default="nm")
    ap.add_argument("--binary-dir", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--identity-object", default="core/CMakeFiles/dnb_core.dir/build_info.cpp.o")
    ap.add_argument("--replace", action="append", default=[])
    a = ap.parse_args()

    with open(a.objects) as f:
        objects = sorted({line.strip() for line in f if line.strip()})
    replace = dict(r.split("=", 1) for r in a.replace)
    rel = {o: os.path.relpath(o, a.binary_dir) for o in objects}
    content = {o: sha256_file(replace.get(rel[o], o)) for o in objects}

    # Symbols: which object defines which factory, each object's strong definitions and its
    # references, and whether it has a static initialiser.
    factories, strong, undefined, has_init = {}, {}, {}, {}
    for o in objects:
        strong[o], undefined[o], has_init[o] = set(), set(), False
        for kind, name in nm_lines(a.nm, o):
            if kind == "U":
                undefined[o].add(name)
            elif kind not in WEAK_OR_UNDEFINED and kind.isupper():
                strong[o].add(name)
                method = factory_name(name)
                if method is not None:
                    factories.setdefault(method, []).append(o)
            if name.startswith("_GLOBAL__sub_I_"):
                has_init[o] = True

    own, shared_reasons = {}, {}
    for method, defs in sorted(factories.items()):
        if len(defs) != 1:
            shared_reasons[method] = "factory defined in several objects"
            continue
        o = defs[0]
        if rel[o] == a.identity_object:
            continue
        if has_init[o]:
            shared_reasons[method] = f"{rel[o]} has a static initialiser"
            continue
        if sum(o in d for d in factories.values()) > 1:
            shared_reasons[method] = f"{rel[o]} defines another method's factory too"
            continue
        exported = {s for s in strong[o] if factory_name(s) != method}
        users = sorted(rel[o2] for o2 in objects if o2 != o and undefined[o2] & exported)
        if users:
            shared_reasons[method] = f"{rel[o]}'s symbols are used by {', '.join(users)}"
            continue
        own[method] = o

    own_objects = set(own.values())
    shared = hashlib.sha256()
    for o in objects:
        if o in own_objects or rel[o] == a.identity_object:
            continue
        shared.update(f"{rel[o]}\t{content[o]}\n".encode())
    shared_id = shared.hexdigest()
    methods = {
        m: hashlib.sha256(f"shared\t{shared_id}\n{rel[o]}\t{content[o]}\n".encode()).hexdigest()
        for m, o in sorted(own.items())
    }
    doc = {
        "format": "denoisebench-code-ids",
        "version": 1,
        "program_sha256": sha256_file(a.program),
        "shared": shared_id,
        "methods": methods,
        "own_files": {m: rel[o] for m, o in sorted(own.items())},
        "shared_method_files": shared_reasons,
    }
    tmp = a.out + ".tmp"
    with open(tmp, "w") as f:
        json.dump(doc, f, indent=1, sort_keys=True)
        f.write("\n")
    os.replace(tmp, a.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
