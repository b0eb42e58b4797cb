"""Helper for denoisebench renderer back-ends written in Python (docs/renderers.md).

A back-end renders a scene file of its own renderer for `denoisebench run` (a config's
`[[scene]] renderer = "NAME", file = "scene.xml"`). This module speaks the protocol around one
function of yours:

    from denoisebench_renderer import run

    def render(request, state):
        # request: scene, width, height, spp, seed, max_depth, threads, output, layers
        ...  # render request["scene"], write the layers to request["output"] (write_layers)
        return {"render_seconds": seconds}   # the render alone, start-up left out

    run(render, version=lambda: "myrenderer 1.2", setup=load_library)

`run` picks the form from the command line: `--version` prints the version line (the harness
keys its render cache by it) and exits; no arguments is the worker: `setup()` runs once (its
time is start-up, not a render's), the ready line is printed, then one JSON request per line on
stdin, one JSON answer per line on stdout (`{"ok": true, "render_seconds": S}` or `{"ok":
false, "error": "..."}`), until stdin closes. `--request REQ.json` renders one request and
exits (for trying a back-end by hand). Anything else printed goes to the harness's log: in
worker mode stdout carries the protocol, so `print` is sent to stderr.

An exception raised by `render` fails that render only (its message is the cell's failure
reason: name the scene file in it); `Unavailable` raised by `setup` answers the start with
`{"ready": false, "unavailable": why}`, which fails every render of the back-end with `why`.

Needs NumPy and OpenImageIO's Python binding for write_layers (Debian: python3-numpy,
python3-openimageio). The harness puts this folder on PYTHONPATH.
"""

import json
import os
import sys
import traceback

# A frame's channel names by layer (docs/design.md, "AOV frame file"; core/aov_frame.h).
_SUFFIXES = {"normal": ("X", "Y", "Z"), "depth": ("Z",)}


class Unavailable(Exception):
    """Raised by setup() when the renderer cannot run on this machine (not installed, ...)."""


def channel_names(layer, channels):
    """The EXR channel names of a harness layer: 'color' is bare R,G,B; 'normal' .X/Y/Z;
    'depth' .Z; other 3-channel layers .R/G/B and 1-channel ones .Y."""
    if layer == "color":
        return ["R", "G", "B"]
    last = layer.rsplit(".", 1)[-1]
    if last in _SUFFIXES:
        return [f"{layer}.{s}" for s in _SUFFIXES[last]]
    return [f"{layer}.{s}" for s in (("R", "G", "B") if channels == 3 else ("Y",))]


def write_layers(path, layers, attributes=None):
    """Writes {layer: H x W x C float array} as one 32-bit float EXR with the harness's channel
    names, to a temporary name first (the harness never reads half a file)."""
    import numpy as np
    import OpenImageIO as oiio
    names, planes = [], []
    for layer, img in layers.items():
        a = np.asarray(img, dtype=np.float32)
        if a.ndim == 2:
            a = a[:, :, None]
        names += channel_names(layer, a.shape[2])
        planes.append(a)
    pixels = np.ascontiguousarray(np.concatenate(planes, axis=2))
    h, w, c = pixels.shape
    spec = oiio.ImageSpec(w, h, c, oiio.FLOAT)
    spec.channelnames = tuple(names)
    spec.attribute("compression", "zip")
    for k, v in (attributes or {}).items():
        spec.attribute(k, str(v))
    tmp = f"{path}.tmp-{os.getpid()}.exr"
    out = oiio.ImageOutput.create(tmp)
    if out is None or not out.open(tmp, spec) or not out.write_image(pixels) or not out.close():
        raise RuntimeError(f"cannot write '{path}': {oiio.geterror()}")
    os.replace(tmp, path)


_FIELDS = {"scene": str, "width": int, "height": int, "spp": int, "seed": int, "max_depth": int,
           "output": str, "layers": list}


def check_request(req):
    """The request's fields, typed; ValueError naming the one missing or mistyped."""
    if not isinstance(req, dict):
        raise ValueError(f"a request is a JSON object, got {type(req).__name__}")
    for k, t in _FIELDS.items():
        if k not in req or not isinstance(req[k], t) or isinstance(req[k], bool):
            raise ValueError(f"request field '{k}': expected a {t.__name__}, got {req.get(k)!r}")
    req.setdefault("threads", 0)
    return req


def _answer(stream, obj):
    stream.write(json.dumps(obj) + "\n")
    stream.flush()


def _render_one(render, state, req):
    req = check_request(req)
    out = render(req, state) or {}
    if not os.path.isfile(req["output"]):
        raise RuntimeError(f"{req['scene']}: the back-end wrote no output '{req['output']}'")
    return {"ok": True, **out}


def run(render, version, setup=None, info=None):
    """Runs the back-end under the form the harness started it with (see the module's text).
    `version()` returns one line: the renderer and its version (and anything else that changes
    its images, such as a variant); `info` (a dict, or a function of setup's result) goes into
    the ready line."""
    argv = sys.argv[1:]
    if argv == ["--version"]:
        print(version())
        return
    if len(argv) == 2 and argv[0] == "--request":
        with open(argv[1]) as f:
            req = json.load(f)
        print(json.dumps(_render_one(render, setup() if setup else None, req)))
        return
    if argv:
        sys.exit(f"unexpected arguments {argv} (expected none, --version, or --request REQ.json)")
    # The protocol gets stdout's file descriptor to itself; descriptor 1 becomes stderr, so that
    # neither the user's prints nor a native library's (Mitsuba's logger, Blender's) reach it.
    sys.stdout.flush()
    protocol = os.fdopen(os.dup(1), "w", buffering=1)
    os.dup2(2, 1)
    sys.stdout = sys.stderr
    try:
        state = setup() if setup else None
    except Unavailable as e:
        _answer(protocol, {"ready": False, "unavailable": str(e)})
        return
    ready = {"ready": True}
    if info is not None:
        ready["info"] = dict(info(state) if callable(info) else info)
    _answer(protocol, ready)
    for line in sys.stdin:
        if not line.strip():
            continue
        try:
            answer = _render_one(render, state, json.loads(line))
        except Exception as e:  # one bad scene fails that render, not the worker
            traceback.print_exc(file=sys.stderr)
            answer = {"ok": False, "error": str(e) or type(e).__name__}
        _answer(protocol, answer)
