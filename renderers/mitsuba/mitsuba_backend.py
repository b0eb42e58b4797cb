"""Renderer back-end (protocol "worker", docs/renderers.md): Mitsuba 3 renders a Mitsuba 3 XML
scene file with the harness's split integrator (split_integrator.py) and writes a harness frame:
R,G,B and the layers direct, indirect, albedo, reflection, emission, normal and depth under
their channel names (docs/design.md, "AOV frame file").

Mitsuba comes from PyPI, pinned in python/requirements-pypi.txt and installed by scripts/setup
into the project's .venv/. The manifest starts this script with Debian's Python, which is always
there; the script then replaces itself (same process) with .venv's Python. Without .venv or
without Mitsuba it answers the start with {"ready": false, "unavailable": ...} saying to run
scripts/setup, and the scene's cells fail with that reason.

Per request the scene file is read with its own camera, shapes, materials and lights; the
harness sets the film's size (a box pixel filter: each pixel the mean of its own samples, as
the harness's frames; Mitsuba's default Gaussian spreads a sample over neighbours), replaces the
integrator with `dnb_split` (the request's max_depth), and renders with the request's spp and
seed (Mitsuba's own sampler of the scene, seeded). The same request gives the same image.

The variant is `scalar_rgb` (needs nothing else), or $DENOISEBENCH_MITSUBA_VARIANT; it is part
of the version line, so the render cache keeps renders of different variants apart. The
integrator is written per sample: the scalar variants only.
"""
import json
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
VENV = os.path.normpath(os.path.join(HERE, "..", "..", ".venv"))
VARIANT = os.environ.get("DENOISEBENCH_MITSUBA_VARIANT", "scalar_rgb")


def _unavailable(why):
    """The back-end cannot run here: the worker's ready line says why (every render of it fails
    with that reason); --version and --request exit with it."""
    if len(sys.argv) > 1:
        sys.exit(f"mitsuba back-end: {why}")
    sys.__stdout__.write(json.dumps({"ready": False, "unavailable": why}) + "\n")
    sys.__stdout__.flush()
    sys.exit(0)


def _into_venv():
    """Re-executes this script with .venv's Python unless it already runs there."""
    if os.path.realpath(sys.prefix) == os.path.realpath(VENV):
        return
    python = os.path.join(VENV, "bin", "python3")
    if os.environ.get("DENOISEBENCH_MITSUBA_REEXEC") == "1":
        _unavailable(f"'{python}' did not start inside '{VENV}' (sys.prefix is '{sys.prefix}'); "
                     "re-create it with scripts/setup (rm -rf .venv first)")
    if not os.access(python, os.X_OK):
        _unavailable(f"the project's virtual environment '{VENV}' is missing (no '{python}'): run scripts/setup, "
                     "which installs python/requirements-pypi.txt (Mitsuba 3) into it")
    os.environ["DENOISEBENCH_MITSUBA_REEXEC"] = "1"
    sys.stdout.flush()
    sys.stderr.flush()
    os.execv(python, [python, os.path.abspath(__file__)] + sys.argv[1:])


_into_venv()

import xml.etree.ElementTree as ET  # noqa: E402

sys.path.insert(0, os.path.dirname(HERE))  # denoisebench_renderer.py, beside the back-ends
from denoisebench_renderer import Unavailable, run, write_layers  # noqa: E402


def load_mitsuba():
    try:
        import drjit as dr
        import mitsuba as mi
    except ImportError as e:
        raise Unavailable(f"Mitsuba 3 is not importable from '{VENV}' ({e}): run scripts/setup, which installs "
                          "python/requirements-pypi.txt into .venv")
    if VARIANT not in mi.variants():
        raise Unavailable(f"Mitsuba variant '{VARIANT}' ($DENOISEBENCH_MITSUBA_VARIANT) is not one of "
                          f"{', '.join(mi.variants())}")
    if not VARIANT.startswith("scalar_") or "rgb" not in VARIANT:
        raise Unavailable(f"Mitsuba variant '{VARIANT}': the split integrator is written per sample, for a scalar "
                          "RGB variant (scalar_rgb)")
    try:
        mi.set_variant(VARIANT)
    except Exception as e:  # an llvm/cuda variant without its library, for instance
        raise Unavailable(f"Mitsuba variant '{VARIANT}' does not start: {e}")
    mi.set_log_level(mi.LogLevel.Warn)
    sys.path.insert(0, HERE)
    import split_integrator
    split_integrator.register(VARIANT)
    return {"mi": mi, "dr": dr}


def version():
    try:
        import drjit as dr
        import mitsuba as mi
    except ImportError as e:
        sys.exit(f"mitsuba back-end: Mitsuba 3 is not importable from '{VENV}' ({e}): run scripts/setup")
    from importlib.metadata import version as package_version
    return f"mitsuba {package_version('mitsuba')} drjit {package_version('drjit')} {VARIANT}"


def _child(parent, tag, name):
    for e in parent.findall(tag):
        if e.get("name") == name:
            return e
    return None


def harness_scene(path, req):
    """The scene file's XML with the harness's film size, box filter and integrator."""
    try:
        tree = ET.parse(path)
    except ET.ParseError as e:
        raise ValueError(f"{path}: not well-formed XML ({e})")
    except OSError as e:
        raise ValueError(f"{path}: cannot read the scene file ({e.strerror})")
    root = tree.getroot()
    if root.tag != "scene":
        raise ValueError(f"{path}: the root element is <{root.tag}>, expected a Mitsuba 3 <scene>")
    for e in root.findall("integrator"):
        root.remove(e)
    integ = ET.Element("integrator", {"type": "dnb_split"})
    ET.SubElement(integ, "integer", {"name": "max_depth", "value": str(req["max_depth"])})
    root.insert(0, integ)
    sensor = root.find("sensor")
    if sensor is None:
        raise ValueError(f"{path}: the scene has no <sensor> (a camera to render from)")
    film = sensor.find("film")
    if film is None:
        film = ET.SubElement(sensor, "film", {"type": "hdrfilm"})
    for name in ("width", "height", "crop_offset_x", "crop_offset_y", "crop_width", "crop_height"):
        e = _child(film, "integer", name)
        if e is not None:
            film.remove(e)
    for e in film.findall("rfilter"):
        film.remove(e)
    ET.SubElement(film, "integer", {"name": "width", "value": str(req["width"])})
    ET.SubElement(film, "integer", {"name": "height", "value": str(req["height"])})
    ET.SubElement(film, "rfilter", {"type": "box"})
    return ET.tostring(root, encoding="unicode")


def render(req, state):
    import numpy as np
    mi, dr = state["mi"], state["dr"]
    path = req["scene"]
    xml = harness_scene(path, req)
    # Relative file names in the scene (meshes, textures) are the scene file's folder's.
    resolver = mi.Thread.thread().file_resolver()
    saved = mi.FileResolver(resolver)
    resolver.prepend(os.path.dirname(os.path.abspath(path)))
    try:
        scene = mi.load_string(xml)
    except Exception as e:  # Mitsuba's parser raises RuntimeError/ValueError with its message
        raise ValueError(f"{path}: Mitsuba could not load the scene: {e}")
    finally:
        mi.Thread.thread().set_file_resolver(saved)
    dr.set_thread_count(req["threads"] if req["threads"] > 0 else os.cpu_count())
    # Mitsuba warns at every render that a Python integrator is slow in scalar variants: known.
    mi.set_log_level(mi.LogLevel.Error)
    try:
        start = time.perf_counter()
        mi.render(scene, spp=req["spp"], seed=req["seed"] & 0xFFFFFFFF)
        seconds = time.perf_counter() - start
    finally:
        mi.set_log_level(mi.LogLevel.Warn)
    film = scene.sensors()[0].film()
    layers = {k: np.array(v, dtype=np.float64) for k, v in film.bitmap().split()}
    color = layers["<root>"][:, :, :3] if "<root>" in layers else None
    if color is None:
        raise RuntimeError(f"{path}: Mitsuba's film has no colour channels (layers: {', '.join(layers)})")
    dt, itx, t = layers["direct_t"], layers["indirect_t"], layers["albedo"]
    refl = layers["reflection"].copy()
    # D and I untextured: the albedo-weighted means (harness frames: sum of D T over sum of T).
    # Where a channel's T is 0 any light counted through the diffuse lobe goes to R instead, so
    # the split still adds up to the colour.
    has_t = t > 0
    safe = np.where(has_t, t, 1.0)
    direct = np.where(has_t, dt / safe, 0.0)
    indirect = np.where(has_t, itx / safe, 0.0)
    refl += np.where(has_t, 0.0, dt + itx)
    out = {"color": color, "direct": direct, "indirect": indirect, "albedo": t, "reflection": refl,
           "emission": layers["emission"], "normal": layers["normal"], "depth": layers["depth"]}
    wanted = {k: v for k, v in out.items() if k in req["layers"] or k == "color"}
    missing = [k for k in req["layers"] if k not in out]
    if missing:
        raise ValueError(f"{path}: the mitsuba back-end does not make the layers {', '.join(missing)} "
                         f"(it makes {', '.join(out)})")
    write_layers(req["output"], wanted)
    return {"render_seconds": seconds}


if __name__ == "__main__":
    run(render, version=version, setup=load_mitsuba, info=lambda s: {"version": version()})
