"""Renderer back-end (protocol "worker", docs/renderers.md): Blender Cycles renders a .blend,
.gltf/.glb or .obj scene file and this script writes a harness frame: R,G,B and the layers
direct, indirect, albedo, reflection, emission, normal and depth under their channel names
(docs/design.md, "AOV frame file"), made from Cycles' light passes as configs/import/cycles.toml
maps them:

    color      = Combined
    direct     = DiffDir,  indirect = DiffInd,  albedo = DiffCol          (D, I, T)
    reflection = (GlossDir + GlossInd) * GlossCol + (TransDir + TransInd) * TransCol
                 + VolumeDir + VolumeInd                                   (R)
    emission   = Emit + Env                                                (E)
    normal     = Normal (world space, averaged; in the glTF file's Y-up frame for a glTF scene)
    depth      = Denoising Depth (camera-to-hit distance averaged over the samples, 0 on a miss)

so that Combined = (D + I) * T + R + E per pixel to float rounding (Cycles composes Combined of
exactly these passes).

Blender (Debian's `blender`, scripts/setup with DNB_SETUP_BLENDER=1; $DENOISEBENCH_BLENDER names
another) is not a Python module: the manifest starts this script with Debian's Python, which
replaces itself (same process) with `blender --background --factory-startup -noaudio --python
cycles_backend.py -- ARGS`; inside Blender the script runs the worker loop of
denoisebench_renderer.py itself, so one Blender process serves every render of a run, and its
start-up is not a render's time. Without Blender it answers the start with {"ready": false,
"unavailable": ...} and the scene's cells fail with that reason.

Per request (Cycles on the CPU, every setting that changes the estimate pinned):
  size, cycles.samples = spp (adaptive sampling, denoising, clamping, light threshold, glossy
  filter off), cycles.seed = seed (31 bits: Cycles' seed is a signed int), a box pixel filter
  one pixel wide (each pixel the mean of its own samples), the Standard view transform (the EXR
  is linear in any case), threads (0: every core), and the bounces from max_depth: the tracer's
  max_depth is the path length in segments, the camera ray included (tracer/integrator.cpp: at
  most max_depth surface vertices); Cycles' bounces count from 0 = direct light only (2
  segments), so max_bounces = diffuse = glossy = transmission = volume = transparent bounces =
  max_depth - 2 (max_depth 1, emitters alone, has no Cycles form: refused).

Scene files:
  .blend        opened as it is (its materials, world, lights, camera; the active view layer).
  .gltf / .glb  Blender's glTF importer; a material with extras.denoisebench (denoisebench
                export-gltf) is rebuilt as the tracer's material (cycles_materials.py), the
                scene's extras.denoisebench sky becomes the world, the KHR_lights_punctual sun a
                Sun lamp of its irradiance and angular radius.
  .obj          Blender's OBJ importer (its MTL materials as Blender reads them); an OBJ has no
                camera or lights: a camera frames the bounding box from the front (+Z of the
                file), under a uniform white sky of radiance 1.
A scene is loaded once and kept while the requests name the same file (same size, same mtime).
A file that does not exist, does not load or has no camera is an error naming it.

$DENOISEBENCH_CYCLES_LOG (a file): one line per request, "pid scene seconds", to check that one
process serves a run (tests/apps/run_cycles_test.cpp).
"""
import json
import os
import shutil
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
BLENDER_ARGS = ["--background", "--factory-startup", "-noaudio", "--python"]


def _blender():
    """The Blender program: $DENOISEBENCH_BLENDER or `blender` on PATH, or None."""
    b = os.environ.get("DENOISEBENCH_BLENDER") or shutil.which("blender")
    return b if b and os.access(b, os.X_OK) else None


def _outside_blender():
    """Started by Debian's Python: --version answers here; otherwise become Blender running this
    script (the same process, so the harness's pipes and process group carry over)."""
    try:
        import bpy  # noqa: F401
        return
    except ImportError:
        pass
    blender = _blender()
    missing = ("Blender is not installed (no 'blender' on PATH, $DENOISEBENCH_BLENDER unset): "
               "run DNB_SETUP_BLENDER=1 scripts/setup, which installs Debian's blender")
    if sys.argv[1:] == ["--version"]:
        if not blender:
            sys.exit(f"cycles back-end: {missing}")
        import subprocess
        out = subprocess.run([blender, "--version"], capture_output=True, text=True, timeout=120)
        first = next((l.strip() for l in out.stdout.splitlines() if l.strip()), "")
        if out.returncode != 0 or not first.startswith("Blender"):
            sys.exit(f"cycles back-end: '{blender} --version' failed: {out.stdout}{out.stderr}")
        # Blender's version and the pinned settings' version (bumped when this back-end's images change).
        print(f"{first} cycles CPU settings-1")
        return sys.exit(0)
    if not blender:
        if len(sys.argv) > 1:
            sys.exit(f"cycles back-end: {missing}")
        sys.stdout.write(json.dumps({"ready": False, "unavailable": missing}) + "\n")
        sys.stdout.flush()
        sys.exit(0)
    # Blender prints its banner to stdout before the script runs: keep the protocol's descriptor
    # aside (inherited through exec) and give Blender stderr as its stdout until then.
    sys.stdout.flush()
    sys.stderr.flush()
    protocol = os.dup(1)
    os.set_inheritable(protocol, True)
    os.dup2(2, 1)
    os.environ["DENOISEBENCH_CYCLES_PROTOCOL_FD"] = str(protocol)
    # The harness puts renderers/ on PYTHONPATH; there this folder, named "cycles", would shadow
    # Blender's own cycles add-on. The script adds what it needs to sys.path itself.
    parent = os.path.dirname(HERE)
    keep = [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep)
            if p and os.path.realpath(p) != os.path.realpath(parent)]
    if keep:
        os.environ["PYTHONPATH"] = os.pathsep.join(keep)
    else:
        os.environ.pop("PYTHONPATH", None)
    os.execv(blender, [blender] + BLENDER_ARGS + [os.path.abspath(__file__), "--"] + sys.argv[1:])


_outside_blender()

# ---- inside Blender ----
import bpy  # noqa: E402
import numpy as np  # noqa: E402

# Debian's Blender 3.4.1 glTF importer uses np.bool, which NumPy 1.24 removed.
if "bool" not in np.__dict__:
    np.bool = bool

sys.path.append(os.path.dirname(HERE))  # denoisebench_renderer.py, beside the back-ends
sys.path.append(HERE)
from denoisebench_renderer import run, write_layers  # noqa: E402
import cycles_materials  # noqa: E402

# The passes read from Blender's multilayer EXR (without the view layer's prefix).
PASSES = ["Combined", "DiffDir", "DiffInd", "DiffCol", "GlossDir", "GlossInd", "GlossCol", "TransDir",
          "TransInd", "TransCol", "VolumeDir", "VolumeInd", "Emit", "Env", "Normal", "Denoising Depth"]
LAYERS = ["color", "direct", "indirect", "albedo", "reflection", "emission", "normal", "depth"]


def version():
    return f"Blender {bpy.app.version_string} cycles CPU settings-1"


def setup():
    return {"loaded": None, "tmp": None}


def _fail(path, what):
    raise ValueError(f"{path}: {what}")


def load_scene(path):
    """Opens or imports the scene file into a fresh Blender session; returns what kind it was."""
    if not os.path.isfile(path):
        _fail(path, "the scene file does not exist")
    ext = os.path.splitext(path)[1].lower()
    try:
        if ext == ".blend":
            bpy.ops.wm.open_mainfile(filepath=path, load_ui=False)
            return "blend"
        bpy.ops.wm.read_factory_settings(use_empty=True)
        if ext in (".gltf", ".glb"):
            res = bpy.ops.import_scene.gltf(filepath=path, convert_lighting_mode="RAW")
        elif ext == ".obj":
            res = bpy.ops.wm.obj_import(filepath=path)
        else:
            _fail(path, f"the cycles back-end reads .blend, .gltf, .glb and .obj scene files, not '{ext}'")
    except ValueError:
        raise
    except Exception as e:  # Blender's operators raise RuntimeError with the importer's message
        msg = str(e).strip().splitlines()
        _fail(path, f"Blender could not read the scene file: {msg[-1] if msg else type(e).__name__}")
    if "FINISHED" not in res:
        _fail(path, f"Blender could not read the scene file ({', '.join(res)})")
    return ext[1:]


def prepare_gltf(path):
    scene = bpy.context.scene
    for m in bpy.data.materials:
        exact = m.get("denoisebench")
        if exact is not None and hasattr(exact, "to_dict"):
            try:
                cycles_materials.build_material(m, exact.to_dict())
            except ValueError as e:
                _fail(path, f"material '{m.name}': {e}")
    extras = scene.get("denoisebench")
    cycles_materials.build_world(scene, extras.to_dict() if hasattr(extras, "to_dict") else {})
    for o in scene.objects:
        if o.type == "LIGHT" and o.data.type == "SUN":
            sun = o.data.get("denoisebench")
            radius = sun.to_dict().get("angular_radius_degrees") if hasattr(sun, "to_dict") else None
            if radius is not None:
                o.data.angle = 2 * radius * np.pi / 180  # Cycles' angle is the disc's diameter
    if scene.camera is None:
        cams = [o for o in scene.objects if o.type == "CAMERA"]
        if not cams:
            _fail(path, "the glTF file has no camera")
        scene.camera = cams[0]


def prepare_obj(path):
    scene = bpy.context.scene
    objs = [o for o in scene.objects if o.type == "MESH"]
    if not objs:
        _fail(path, "the OBJ file has no geometry")
    pts = np.array([o.matrix_world @ v.co for o in objs for v in o.data.vertices])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    centre, radius = (lo + hi) / 2, max(np.linalg.norm(hi - lo) / 2, 1e-6)
    cam_data = bpy.data.cameras.new("camera")
    cam_data.angle = np.radians(40)
    cam = bpy.data.objects.new("camera", cam_data)
    # The file's +Z (OBJ's forward-facing side) is Blender's -Y after the importer's axis change.
    cam.location = (centre[0], centre[1] - radius / np.tan(np.radians(20)) * 1.1, centre[2])
    cam.rotation_euler = (np.pi / 2, 0.0, 0.0)
    cam_data.clip_start = radius * 1e-3
    cam_data.clip_end = radius * 100
    scene.collection.objects.link(cam)
    scene.camera = cam
    cycles_materials.build_world(scene, {"sky": [1.0, 1.0, 1.0]})


def settings(scene, req, path):
    if req["max_depth"] < 2:
        _fail(path, f"max_depth {req['max_depth']}: Cycles always lights the first hit (its bounces count "
                    "from 0 = a path of 2 segments), so the cycles back-end needs max_depth >= 2")
    if scene.camera is None:
        _fail(path, "the scene has no active camera")
    r, c = scene.render, scene.cycles
    r.engine = "CYCLES"
    c.device = "CPU"
    r.resolution_x, r.resolution_y, r.resolution_percentage = req["width"], req["height"], 100
    r.pixel_aspect_x = r.pixel_aspect_y = 1
    r.use_border = False
    r.use_motion_blur = False
    r.film_transparent = False
    r.threads_mode = "FIXED" if req["threads"] > 0 else "AUTO"
    if req["threads"] > 0:
        r.threads = req["threads"]
    c.samples = req["spp"]
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.seed = req["seed"] & 0x7FFFFFFF
    c.use_animated_seed = False
    c.pixel_filter_type = "BOX"
    c.filter_width = 1.0
    bounces = req["max_depth"] - 2
    c.max_bounces = c.diffuse_bounces = c.glossy_bounces = c.transmission_bounces = bounces
    c.volume_bounces = c.transparent_max_bounces = bounces
    c.sample_clamp_direct = c.sample_clamp_indirect = 0.0
    c.light_sampling_threshold = 0.0
    c.blur_glossy = 0.0
    c.caustics_reflective = c.caustics_refractive = True
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    im = r.image_settings
    im.file_format = "OPEN_EXR_MULTILAYER"
    im.color_depth = "32"
    im.exr_codec = "ZIP"
    r.use_compositing = False
    r.use_sequencer = False
    layer = bpy.context.view_layer
    for vl in scene.view_layers:
        vl.use = vl == layer
    for p in ("use_pass_combined", "use_pass_diffuse_direct", "use_pass_diffuse_indirect", "use_pass_diffuse_color",
              "use_pass_glossy_direct", "use_pass_glossy_indirect", "use_pass_glossy_color",
              "use_pass_transmission_direct", "use_pass_transmission_indirect", "use_pass_transmission_color",
              "use_pass_emit", "use_pass_environment", "use_pass_normal"):
        setattr(layer, p, True)
    layer.cycles.use_pass_volume_direct = True
    layer.cycles.use_pass_volume_indirect = True
    layer.cycles.denoising_store_passes = True
    layer.cycles.use_denoising = False
    return layer


def read_passes(path):
    """{pass name: H x W x C float64} of Blender's multilayer EXR (the view layer's prefix off)."""
    import OpenImageIO as oiio
    inp = oiio.ImageInput.open(path)
    if inp is None:
        raise RuntimeError(f"cannot read Blender's output '{path}': {oiio.geterror()}")
    try:
        spec = inp.spec()
        pix = inp.read_image(0, 0, 0, spec.nchannels, oiio.FLOAT)
    finally:
        inp.close()
    pix = np.asarray(pix, dtype=np.float64).reshape(spec.height, spec.width, spec.nchannels)
    by_pass = {}
    for i, name in enumerate(spec.channelnames):
        parts = name.split(".")
        if len(parts) < 2:
            continue
        by_pass.setdefault(parts[-2], []).append((parts[-1], i))
    order = {"R": 0, "G": 1, "B": 2, "A": 3, "X": 0, "Y": 1, "Z": 2, "V": 0}
    out = {}
    for p, chans in by_pass.items():
        chans.sort(key=lambda c: order.get(c[0], 9))
        out[p] = pix[:, :, [i for _, i in chans]]
    return out


def harness_layers(passes, kind):
    h, w = passes["Combined"].shape[:2]
    zero = np.zeros((h, w, 3))

    def get(name):
        return passes[name][:, :, :3] if name in passes else zero

    refl = ((get("GlossDir") + get("GlossInd")) * get("GlossCol") + (get("TransDir") + get("TransInd")) * get("TransCol")
            + get("VolumeDir") + get("VolumeInd"))
    normal = get("Normal")
    if kind in ("gltf", "glb"):  # Blender's Z-up back to the file's Y-up: (x, y, z) -> (x, z, -y)
        normal = np.dstack([normal[:, :, 0], normal[:, :, 2], -normal[:, :, 1]])
    if "Denoising Depth" not in passes:
        raise RuntimeError("Blender wrote no 'Denoising Depth' pass")
    return {"color": get("Combined"), "direct": get("DiffDir"), "indirect": get("DiffInd"), "albedo": get("DiffCol"),
            "reflection": refl, "emission": get("Emit") + get("Env"), "normal": normal,
            "depth": passes["Denoising Depth"][:, :, :1]}


def render(req, state):
    import tempfile
    path = os.path.abspath(req["scene"])
    try:
        st = os.stat(path)
    except OSError as e:
        _fail(path, f"cannot read the scene file ({e.strerror})")
    key = (path, st.st_mtime_ns, st.st_size)
    if state["loaded"] is None or state["loaded"][0] != key:
        state["loaded"] = None
        kind = load_scene(path)
        if kind in ("gltf", "glb"):
            prepare_gltf(path)
        elif kind == "obj":
            prepare_obj(path)
        state["loaded"] = (key, kind)
    kind = state["loaded"][1]
    scene = bpy.context.scene
    settings(scene, req, path)
    missing = [k for k in req["layers"] if k not in LAYERS]
    if missing:
        _fail(path, f"the cycles back-end does not make the layers {', '.join(missing)} (it makes {', '.join(LAYERS)})")
    if state["tmp"] is None:
        state["tmp"] = tempfile.mkdtemp(prefix="denoisebench-cycles-")
    tmp = os.path.join(state["tmp"], "passes.exr")
    # Blender prints a progress line per stage and sample on stdout (descriptor 1, which the
    # helper pointed at stderr): quiet during the render; its errors still reach stderr.
    sys.stdout.flush()
    saved = os.dup(1)
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    try:
        start = time.perf_counter()
        bpy.ops.render.render(write_still=False)
        seconds = time.perf_counter() - start
    finally:
        os.dup2(saved, 1)
        os.close(saved)
        os.close(devnull)
    result = bpy.data.images.get("Render Result")
    if result is None:
        raise RuntimeError(f"{path}: Blender rendered no image")
    result.save_render(filepath=tmp, scene=scene)
    layers = harness_layers(read_passes(tmp), kind)
    write_layers(req["output"], {k: v for k, v in layers.items() if k in req["layers"] or k == "color"},
                 {"denoisebench:renderer": version()})
    os.remove(tmp)
    log = os.environ.get("DENOISEBENCH_CYCLES_LOG")
    if log:
        with open(log, "a") as f:
            f.write(f"{os.getpid()} {path} {seconds:.3f}\n")
    return {"render_seconds": seconds}


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    fd = os.environ.pop("DENOISEBENCH_CYCLES_PROTOCOL_FD", None)
    if fd is not None:  # the protocol's descriptor back on 1, now that Blender's banner is out
        sys.stdout.flush()
        os.dup2(int(fd), 1)
        os.close(int(fd))
    sys.argv = [os.path.abspath(__file__)] + argv
    try:
        run(render, version=version, setup=setup, info=lambda s: {"version": version()})
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
    # Blender would print "Blender quit" on exit; the protocol is done, so that goes nowhere harmful.


main()
