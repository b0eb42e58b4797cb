"""Plug-in (protocol "worker"): Intel Open Image Denoise, the "RT" filter in HDR mode, guided by
the albedo and the normals (docs/plugins.md; the method's defaults: docs/method-defaults.md).

OIDN comes from PyPI, pinned in python/requirements-pypi.txt (pyoidn: its wheel ships
libOpenImageDenoise.so.2 with the built-in trained weights), installed by scripts/setup into the
project's virtual environment .venv/. The manifest starts this script with Debian's Python, which
is always there (a missing program would make every denoisebench command fail when it loads the
manifest); the script then replaces itself (same process) with .venv's Python. Without .venv or
without the pinned package it answers the harness's start with {"ready": false, "unavailable":
...} saying to run scripts/setup: the oidn cells of an experiment are then skipped with that
reason, not failed (docs/plugins.md).

The library is loaded with ctypes (pyoidn's own Python wrapper needs cffi, not installed), once
at start-up; one CPU device per `threads` value and one filter per kind of image are made once
and reused for every frame (a frame of the same size as the last one commits cheaply).
"""
import json
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
VENV = os.path.normpath(os.path.join(HERE, "..", "..", ".venv"))


def _unavailable(why):
    """Says the method cannot run here: in the worker protocol as its ready line (the harness
    skips its cells), in the frame protocol as an error. Written without the helper module,
    which may not be importable before the move into .venv."""
    if len(sys.argv) > 1:
        sys.exit(f"oidn: {why}")
    out = sys.__stdout__  # the protocol's stream: the helper points sys.stdout at stderr
    out.write(json.dumps({"ready": False, "unavailable": why}) + "\n")
    out.flush()
    sys.exit(0)


def _into_venv():
    """Re-executes this script with .venv's Python unless it already runs there."""
    if os.path.realpath(sys.prefix) == os.path.realpath(VENV):
        return
    python = os.path.join(VENV, "bin", "python3")
    if os.environ.get("DENOISEBENCH_OIDN_REEXEC") == "1":
        _unavailable(f"'{python}' did not start inside '{VENV}' (sys.prefix is '{sys.prefix}'); "
                     "re-create it with scripts/setup (rm -rf .venv first)")
    if not os.access(python, os.X_OK):
        _unavailable(f"the project's virtual environment '{VENV}' is missing (no '{python}'): "
                     "run scripts/setup, which installs python/requirements-pypi.txt (pyoidn, OIDN's "
                     "library) into it")
    os.environ["DENOISEBENCH_OIDN_REEXEC"] = "1"
    sys.stdout.flush()
    sys.stderr.flush()
    os.execv(python, [python, os.path.abspath(__file__)] + sys.argv[1:])


_into_venv()

import ctypes  # noqa: E402
import importlib.metadata  # noqa: E402
import importlib.util  # noqa: E402
import re  # noqa: E402

import numpy as np  # noqa: E402

import denoisebench_plugin  # noqa: E402
import oidn_albedo  # noqa: E402
from denoisebench_plugin import run  # noqa: E402

PACKAGE = "pyoidn"
DEVICE_TYPE_CPU = 1
FORMAT_FLOAT3 = 3
QUALITY = {"high": 6, "balanced": 5, "fast": 4}  # OIDNQuality (OIDN 2.x)


def _pinned_version():
    """pyoidn's version as pinned in python/requirements-pypi.txt beside the helper (that folder
    is in every plug-in cell's key, so bumping the pin reruns the cells), or None."""
    req = os.path.join(os.path.dirname(os.path.abspath(denoisebench_plugin.__file__)), "requirements-pypi.txt")
    try:
        with open(req) as f:
            for line in f:
                m = re.match(rf"\s*{PACKAGE}\s*==\s*([^\s#;]+)", line)
                if m:
                    return m.group(1)
    except OSError:
        pass
    return None


def _library_path():
    spec = importlib.util.find_spec(PACKAGE)  # the package's folder, without importing it
    if spec is None or not spec.submodule_search_locations:
        _unavailable(f"the package '{PACKAGE}' (OIDN's library) is not installed in '{sys.prefix}': run scripts/setup")
    have = importlib.metadata.version(PACKAGE)
    want = _pinned_version()
    if want is not None and have != want:
        _unavailable(f"'{sys.prefix}' has {PACKAGE} {have}, python/requirements-pypi.txt pins {want}: run scripts/setup")
    lib = os.path.join(list(spec.submodule_search_locations)[0], "oidn", "lib", "libOpenImageDenoise.so.2")
    if not os.path.exists(lib):
        _unavailable(f"{PACKAGE} {have} has no '{lib}'")
    return lib, have


class Oidn:
    """The few calls of OIDN's C API (OpenImageDenoise/oidn.h) that the filter needs."""

    def __init__(self, path):
        lib = self.lib = ctypes.CDLL(path)
        vp, cs, i, b, sz = ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int, ctypes.c_bool, ctypes.c_size_t
        for name, res, args in (
            ("oidnNewDevice", vp, [i]),
            ("oidnSetDeviceInt", None, [vp, cs, i]),
            ("oidnSetDeviceBool", None, [vp, cs, b]),
            ("oidnGetDeviceInt", i, [vp, cs]),
            ("oidnCommitDevice", None, [vp]),
            ("oidnGetDeviceError", i, [vp, ctypes.POINTER(cs)]),
            ("oidnNewFilter", vp, [vp, cs]),
            ("oidnSetSharedFilterImage", None, [vp, cs, vp, i, sz, sz, sz, sz, sz]),
            ("oidnSetFilterBool", None, [vp, cs, b]),
            ("oidnSetFilterInt", None, [vp, cs, i]),
            ("oidnCommitFilter", None, [vp]),
            ("oidnExecuteFilter", None, [vp]),
        ):
            fn = getattr(lib, name)
            fn.restype, fn.argtypes = res, args
        self.devices = {}  # threads -> device
        self.filters = {}  # (threads, kind, quality) -> filter

    def check(self, device, what):
        msg = ctypes.c_char_p()
        code = self.lib.oidnGetDeviceError(device, ctypes.byref(msg))
        if code != 0:
            text = msg.value.decode(errors="replace") if msg.value else "(no message)"
            raise RuntimeError(f"OIDN error {code} in {what}: {text}")

    def device(self, threads):
        if threads not in self.devices:
            d = self.lib.oidnNewDevice(DEVICE_TYPE_CPU)
            if not d:
                raise RuntimeError("OIDN could not create a CPU device")
            if threads > 0:
                self.lib.oidnSetDeviceInt(d, b"numThreads", threads)
            self.lib.oidnCommitDevice(d)
            self.check(d, "oidnCommitDevice")
            self.devices[threads] = d
        return self.devices[threads]

    def version(self, device):
        v = self.lib.oidnGetDeviceInt(device, b"version")  # major * 10000 + minor * 100 + patch
        return f"{v // 10000}.{v // 100 % 100}.{v % 100}"

    def filter(self, threads, kind, quality):
        """One "RT" filter per use: kind is "main", "main_clean_aux" (the colour with prefiltered
        auxiliary images), "albedo" or "normal" (the prefilters of OIDN's docs, in place)."""
        key = (threads, kind, quality)
        if key not in self.filters:
            d = self.device(threads)
            f = self.lib.oidnNewFilter(d, b"RT")
            self.check(d, "oidnNewFilter")
            if kind.startswith("main"):
                self.lib.oidnSetFilterBool(f, b"hdr", True)
                self.lib.oidnSetFilterBool(f, b"cleanAux", kind == "main_clean_aux")
            self.lib.oidnSetFilterInt(f, b"quality", QUALITY[quality])
            self.check(d, "setting the filter's parameters")
            self.filters[key] = f
        return self.filters[key]

    def execute(self, threads, kind, quality, images):
        """Runs a filter on host arrays (H x W x 3 float32, C-contiguous; kept alive by the
        caller until it returns): images maps OIDN's image names to arrays."""
        d = self.device(threads)
        f = self.filter(threads, kind, quality)
        for name, img in images.items():
            h, w = img.shape[:2]
            self.lib.oidnSetSharedFilterImage(f, name.encode(), img.ctypes.data, FORMAT_FLOAT3, w, h, 0, 0, 0)
        self.lib.oidnCommitFilter(f)
        self.check(d, f"oidnCommitFilter ({kind})")
        self.lib.oidnExecuteFilter(f)
        self.check(d, f"oidnExecuteFilter ({kind})")


def load():
    path, package_version = _library_path()
    oidn = Oidn(path)
    d = oidn.device(0)
    oidn.oidn_version = oidn.version(d)
    oidn.package_version = package_version
    print(f"Intel Open Image Denoise {oidn.oidn_version} ({PACKAGE} {package_version}, {path}), "
          f"CPU device, {oidn.lib.oidnGetDeviceInt(d, b'numThreads')} threads by default")
    return oidn


def _rgb(frame, layer):
    return np.ascontiguousarray(frame[layer], dtype=np.float32)


ALBEDO = ("oidn", "tracer")


def denoise(frame, params, oidn):
    threads = int(params.get("threads", 0))
    quality = str(params.get("quality", "high"))
    if quality not in QUALITY:
        raise ValueError(f"quality '{quality}': expected one of {', '.join(QUALITY)}")
    color = _rgb(frame, "color")
    mode = str(params.get("albedo", "tracer"))
    if mode not in ALBEDO:
        raise ValueError(f"albedo '{mode}': expected one of {', '.join(ALBEDO)}")
    # The frame's own arrays or copies: the prefilters may overwrite them.
    albedo = oidn_albedo.oidn_albedo(frame) if mode == "oidn" else _rgb(frame, "albedo")
    normal = _rgb(frame, "normal")
    out = np.empty_like(color)
    if params.get("clean_aux", False):
        oidn.execute(threads, "albedo", quality, {"albedo": albedo, "output": albedo})
        oidn.execute(threads, "normal", quality, {"normal": normal, "output": normal})
        kind = "main_clean_aux"
    else:
        kind = "main"
    oidn.execute(threads, kind, quality, {"color": color, "albedo": albedo, "normal": normal, "output": out})
    return out


run(denoise, setup=load,
    info=lambda oidn: {"oidn_version": oidn.oidn_version, "package": f"{PACKAGE}=={oidn.package_version}"})
