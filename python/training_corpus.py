"""The training corpus of the learned baselines (kpcn, unet): procedural scenes made here,
rendered by the harness's own tracer, never an evaluation or generalisation scene.

Each scene is a random room or open court (docs/training-corpus.md has the whole list):
  - layout: a room of random proportions (walls, floor, often a ceiling) or, one in three, an
    open court under sun and sky; boxes, spheres, cylinders, arches and panelled walls with thin
    grooves; OBJ meshes from the scenes folder that no evaluation scene uses (the GLSL-PathTracer
    Hyperion parts: chrome, glass and marble spheres, rings, plate), when that folder is found;
  - materials: every type the tracer has (diffuse, mirror, coated, conductor smooth and rough,
    dielectric solid and thin, plastic), with random colours, roughness and indices;
  - textures: the tracer's procedural ones (checker, brick, wood, noise, leaf) and images made
    here with thin high-contrast detail (lines of 1-3 texels, text-like glyph rows, fine noise,
    grids), as sRGB PNG files whose names are their content's hash;
  - lights: ceiling panels, small bright lamps, emissive geometry, sun and sky, with the whole
    scene's light scaled by a random exposure (dim to bright: 1/4 to 4).

Scenes are functions of (seed, index) only: the same seed gives the same files. Every frame is
rendered by `denoisebench render` at each input spp and `denoisebench reference` (another
seed) and kept under WORK/frames/ by a name that holds the scene's file hash, the size, the spp
and the seed, so a second build renders nothing it has, and a killed build resumes where it
stopped (the harness writes each EXR whole or not at all). A kept frame counts only when the
tracer version it names (denoisebench:tracer_version) is the binary's (a 1x1 probe render
tells): after a tracer change every frame is rendered again, never mixed with the old ones.

The manifest (build()'s return value, written by the trainers) records per scene its file's
SHA-256, the tracer's content hash of the loaded scene (the frame's
denoisebench:extra:scene_hash), the mesh files it reads, and the seeds and spp; a test
(CorpusTest in tests/apps) checks that no content hash is an evaluation scene's and that no
mesh file is one an evaluation scene reads.
"""
import hashlib
import os
import subprocess
import sys
import tempfile
import time
import tomllib

import numpy as np
import OpenImageIO as oiio

from denoisebench_plugin import display

ROOT = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
EVALUATION_DIR = os.path.join(ROOT, "configs", "scenes")
REFERENCE_SEED = 1000003
# Meshes a corpus scene may read, relative to the scenes folder: none is read by an evaluation
# scene (the test checks it against configs/scenes/ too).
MESH_POOL = ["glsl-pathtracer/hyperion/" + n for n in
             ("chrome.obj", "glass.obj", "marb1.obj", "marb2.obj", "orange.obj", "pingpong.obj",
              "ring1.obj", "ring2.obj", "ring3.obj")]


def sha256_file(path):
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def write_atomic(path, data):
    tmp = f"{path}.tmp-{os.getpid()}"
    with open(tmp, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


def scenes_dir():
    """The folder of the shared OBJ scenes, as the harness finds it (DENOISEBENCH_SCENES, then
    ../shared/scenes beside the checkout), or None."""
    for d in (os.environ.get("DENOISEBENCH_SCENES", ""), os.path.join(ROOT, "..", "shared", "scenes")):
        if d and os.path.isdir(os.path.join(d, "glsl-pathtracer", "hyperion")):
            return os.path.realpath(d)
    return None


# --------------------------------------------------------------------------------------------
# Texture images with thin, high-contrast detail (what filters erase)


def _image_lines(rng, n):
    img = np.full((n, n), rng.uniform(0.6, 0.95), np.float32)
    period = int(rng.integers(5, 17))
    width = int(rng.integers(1, 4))
    ink = rng.uniform(0.0, 0.12)
    if rng.uniform() < 0.5:  # stripes, one direction
        for k in range(0, n, period):
            img[:, k:k + width] = ink
    else:  # a grid
        for k in range(0, n, period):
            img[:, k:k + width] = ink
            img[k:k + width, :] = ink
    return img


def _image_glyphs(rng, n):
    """Rows of text-like glyphs: random strokes on a 5x7 cell, one texel wide, on paper."""
    img = np.full((n, n), rng.uniform(0.75, 0.95), np.float32)
    ink = rng.uniform(0.0, 0.15)
    cw, ch = 6, 10  # glyph cell with its spacing
    for y0 in range(2, n - ch, ch):
        if rng.uniform() < 0.15:
            continue  # a blank line
        for x0 in range(2, n - cw, cw):
            if rng.uniform() < 0.18:
                continue  # a space
            for _ in range(int(rng.integers(2, 5))):
                if rng.uniform() < 0.5:
                    y = y0 + int(rng.integers(0, 7))
                    xa, xb = sorted(rng.integers(0, 5, 2))
                    img[y, x0 + xa:x0 + xb + 1] = ink
                else:
                    x = x0 + int(rng.integers(0, 5))
                    ya, yb = sorted(rng.integers(0, 7, 2))
                    img[y0 + ya:y0 + yb + 1, x] = ink
    return img


def _image_fine_noise(rng, n):
    lo, hi = sorted(rng.uniform(0.05, 0.9, 2))
    return (lo + (hi - lo) * rng.uniform(size=(n, n))).astype(np.float32)


def texture_image(rng, folder):
    """A random detail image (lines, grid, glyphs or fine noise), tinted, written as an sRGB PNG
    named by its content's hash. Returns the path."""
    n = 256
    kind = int(rng.integers(3))
    grey = [_image_lines, _image_glyphs, _image_fine_noise][kind](rng, n)
    tint = rng.uniform(0.6, 1.0, 3).astype(np.float32)
    rgb = np.clip(grey[:, :, None] * tint[None, None, :], 0, 1)
    srgb = np.where(rgb <= 0.0031308, 12.92 * rgb, 1.055 * np.power(rgb, 1 / 2.4) - 0.055)
    data = np.round(srgb * 255).astype(np.uint8)
    name = hashlib.sha256(data.tobytes()).hexdigest()[:16] + ".png"
    path = os.path.join(folder, name)
    if not os.path.exists(path):
        tmp = f"{path}.tmp-{os.getpid()}.png"
        out = oiio.ImageOutput.create(tmp)
        if not out or not out.open(tmp, oiio.ImageSpec(n, n, 3, "uint8")) or not out.write_image(data):
            sys.exit(f"training_corpus: could not write {tmp}: {oiio.geterror()}")
        out.close()
        os.replace(tmp, path)
    return path


# --------------------------------------------------------------------------------------------
# Scenes


def _v(*xs):
    return "[" + ", ".join(f"{float(x):.4g}" for x in xs) + "]"


def random_material(rng, name, texture=None, allow_delta=True):
    """TOML lines of one material of a random type (every type the tracer has)."""
    out = [f"[materials.{name}]"]
    col = rng.uniform(0.05, 0.85, 3)
    r = rng.uniform()
    if texture is not None:
        kind = "plastic" if r < 0.2 else "coated" if r < 0.35 and allow_delta else "diffuse"
        out += [f'type = "{kind}"', f'texture = "{texture}"']
        if kind == "plastic":
            out += [f"ior = {rng.uniform(1.3, 1.7):.3g}", f"roughness = {rng.uniform(0.05, 0.5):.3g}"]
        elif kind == "coated":
            out.append(f"ior = {rng.uniform(1.3, 1.7):.3g}")
        return out + [""]
    if r < 0.4 or not allow_delta and r < 0.55:
        out.append(f"albedo = {_v(*col)}")
    elif r < 0.5:
        out += ['type = "mirror"', f"tint = {_v(*rng.uniform(0.6, 0.95, 3))}"]
    elif r < 0.6:
        out += ['type = "coated"', f"albedo = {_v(*col)}", f"ior = {rng.uniform(1.3, 1.8):.3g}"]
    elif r < 0.75:
        out += ['type = "conductor"', f'metal = "{["Au", "Ag", "Cu", "Al"][int(rng.integers(4))]}"']
        if rng.uniform() < 0.7:
            out.append(f"roughness = {rng.uniform(0.05, 0.6):.3g}")
    elif r < 0.87:
        out += ['type = "plastic"', f"albedo = {_v(*col)}", f"ior = {rng.uniform(1.3, 1.7):.3g}",
                f"roughness = {rng.uniform(0.02, 0.5):.3g}"]
    else:
        out += ['type = "dielectric"', f"ior = {rng.uniform(1.3, 1.7):.3g}"]
        if rng.uniform() < 0.4:
            out.append(f"roughness = {rng.uniform(0.05, 0.3):.3g}")
        if rng.uniform() < 0.5:
            out.append(f"transmittance = {_v(*rng.uniform(0.6, 1.0, 3))}")
    return out + [""]


def procedural_scene(rng, index, texture_dir, scenes_folder):
    """A random scene as TOML text and the mesh files it reads (relative to the scenes folder)."""
    W, D, H = rng.uniform(3.0, 7.0), rng.uniform(3.0, 7.0), rng.uniform(2.4, 3.6)
    court = index % 3 == 2  # open court under sun and sky, no ceiling
    exposure = float(np.exp(rng.uniform(np.log(0.25), np.log(4.0))))
    out = [f'description = "training corpus scene {index} (python/training_corpus.py)"', ""]
    ex, ez = rng.uniform(0.3, 0.8) * W, rng.uniform(0.1, 0.3) * D
    lx, lz = rng.uniform(0.2, 0.8) * W, rng.uniform(0.55, 0.9) * D
    out += ["[camera]", f"eye = {_v(ex, rng.uniform(0.6, 2.0), ez)}", f"look_at = {_v(lx, rng.uniform(0.3, 1.3), lz)}",
            "up = [0.0, 1.0, 0.0]", f"vfov = {rng.uniform(35, 75):.3g}", ""]
    if court:
        sun = np.array([rng.uniform(-0.7, 0.7), rng.uniform(0.35, 0.95), rng.uniform(-0.7, 0.7)])
        out += ["[sun]", f"direction = {_v(*sun)}",
                f"irradiance = {_v(*(exposure * rng.uniform(3, 8) * np.array([1.0, 0.92, 0.8])))}", "angular_radius = 0.27", "",
                "[sky]", 'type = "gradient"', f"zenith = {_v(*(exposure * np.array([0.25, 0.38, 0.7])))}",
                f"horizon = {_v(*(exposure * np.array([0.75, 0.78, 0.82])))}", "ground = [0.1, 0.09, 0.08]", ""]
    # Textures: four of the tracer's procedural kinds, three detail images.
    textures = []
    for t in range(4):
        kind = ["checker", "brick", "wood", "noise", "leaf"][int(rng.integers(5))]
        out += [f"[textures.p{t}]", f'type = "{kind}"', f"scale = {rng.uniform(1, 10):.3g}"]
        if kind in ("checker", "noise", "leaf"):
            out += [f"color_a = {_v(*rng.uniform(0.03, 0.9, 3))}", f"color_b = {_v(*rng.uniform(0.03, 0.9, 3))}"]
        out.append("")
        textures.append(f"p{t}")
    for t in range(3):
        path = texture_image(rng, texture_dir)
        out += [f"[textures.i{t}]", 'type = "image"', f'file = "../textures/{os.path.basename(path)}"', ""]
        textures.append(f"i{t}")
    # Materials: seven textured (walls, floor, panels), eight of random types, two emitters.
    mats = []
    for m, tex in enumerate(textures):
        out += random_material(rng, f"t{m}", tex, allow_delta=not court)
        mats.append(f"t{m}")
    for m in range(8):
        # Under the sun, smooth delta materials make caustics a 2048-spp reference leaves noisy.
        out += random_material(rng, f"m{m}", None, allow_delta=not court)
        mats.append(f"m{m}")
    for m in range(2):
        out += [f"[materials.e{m}]", f"albedo = {_v(*rng.uniform(0.1, 0.5, 3))}",
                f"emission = {_v(*(exposure * rng.uniform(0.5, 6) * rng.uniform(0.5, 1.0, 3)))}", ""]
    textured = mats[:len(textures)]

    def pick(pool=None):
        pool = pool or mats
        return pool[int(rng.integers(len(pool)))]

    def quad(name, mat, verts, uv=None):
        out.extend(["[[objects]]", 'type = "quad"', f'name = "{name}"', f'material = "{mat}"',
                    f"vertices = {_v(*verts)}"] + ([f"uv_scale = {_v(*uv)}"] if uv else []) + [""])

    quad("floor", pick(textured), [0, 0, 0, 0, 0, D, W, 0, D, W, 0, 0], (W * rng.uniform(0.3, 1.5), D * rng.uniform(0.3, 1.5)))
    if not court:
        out += ["[materials.ceiling]", f"albedo = {_v(*rng.uniform(0.6, 0.85, 3))}", ""]
        quad("ceiling", "ceiling", [0, H, 0, W, H, 0, W, H, D, 0, H, D])
    walls = [("back", [0, 0, D, 0, H, D, W, H, D, W, 0, D], (W, H)), ("right", [W, 0, D, W, H, D, W, H, 0, W, 0, 0], (D, H)),
             ("left", [0, 0, 0, 0, H, 0, 0, H, D, 0, 0, D], (D, H)), ("front", [W, 0, 0, W, H, 0, 0, H, 0, 0, 0, 0], (W, H))]
    for name, verts, uv in walls:
        if court and rng.uniform() < 0.4:
            continue  # a court is open on some sides
        mat = pick(textured) if rng.uniform() < 0.7 else pick(mats)
        quad(name, mat, verts, (uv[0] * rng.uniform(0.3, 2), uv[1] * rng.uniform(0.3, 2)))
    # Panelled stretches: slats with thin dark gaps of 0.5-3 cm.
    for k in range(int(rng.integers(0, 3))):
        slat, gap = rng.uniform(0.04, 0.25), rng.uniform(0.005, 0.03)
        n = max(2, int(min(W * 0.6, 2.5) / (slat + gap)))
        out += ["[[objects]]", 'type = "box"', f'name = "panels{k}"', f'material = "{pick()}"',
                f"size = {_v(slat, rng.uniform(0.5, 1.8), 0.03)}",
                f"translate = {_v(rng.uniform(0.05, 0.35) * W, rng.uniform(0.5, 1.4), D - 0.02 - 0.04 * k)}",
                f"repeat = {n}", f"repeat_offset = {_v(slat + gap, 0, 0)}", ""]
    # Objects: primitives, arches, meshes of the pool, some of them emitting.
    emitters = 0
    for k in range(int(rng.integers(4, 10))):
        kind = ["box", "sphere", "cylinder", "arch", "mesh"][int(rng.integers(5))]
        if kind == "mesh" and not scenes_folder:
            kind = "sphere"
        x, z = rng.uniform(0.3, W - 0.3), rng.uniform(0.35 * D, D - 0.3)
        mat = pick()
        if emitters < 2 and rng.uniform() < 0.12:
            mat, emitters = f"e{emitters}", emitters + 1
        out += ["[[objects]]", f'name = "o{k}"']
        if kind == "box":
            s = rng.uniform(0.1, 1.0, 3)
            out += ['type = "box"', f'material = "{mat}"', f"size = {_v(*s)}", f"translate = {_v(x, s[1] / 2, z)}",
                    f"rotate = {_v(0, rng.uniform(0, 90), 0)}"]
        elif kind == "sphere":
            r = rng.uniform(0.08, 0.5)
            out += ['type = "sphere"', f'material = "{mat}"', f"radius = {r:.4g}", f"center = {_v(x, r + rng.uniform(0, 0.8), z)}"]
        elif kind == "cylinder":
            out += ['type = "cylinder"', f'material = "{mat}"', f"radius = {rng.uniform(0.03, 0.35):.4g}",
                    f"height = {rng.uniform(0.3, 2.0):.4g}", f"center = {_v(x, 0, z)}"]
        elif kind == "arch":
            r = rng.uniform(0.3, 0.9)
            out += ['type = "arch"', f'material = "{mat}"', f"radius = {r:.4g}", f"height = {r + rng.uniform(0.3, 1.2):.4g}",
                    f"depth = {rng.uniform(0.1, 0.4):.4g}", f"translate = {_v(x, 0, z)}",
                    f"rotate = {_v(0, rng.uniform(-40, 40), 0)}"]
        else:
            mesh = MESH_POOL[int(rng.integers(len(MESH_POOL)))]
            s = rng.uniform(1.0, 3.0)  # the Hyperion parts are some 0.4 units across
            out += ['type = "obj"', f'file = "@scenes/{mesh}"', f'material = "{mat}"', f"scale = {s:.4g}",
                    f"rotate = {_v(rng.uniform(-20, 20), rng.uniform(0, 360), 0)}", f"translate = {_v(x, 0.25 * s, z)}"]
        out.append("")
    if not court:
        for k in range(int(rng.integers(1, 3))):
            px, pz = rng.uniform(0.2, 0.7) * W, rng.uniform(0.2, 0.7) * D
            sx, sz = rng.uniform(0.2, 1.2), rng.uniform(0.2, 1.2)
            y = H - 0.001
            out += ["[[lights]]", 'type = "quad"', f'name = "panel{k}"',
                    f"vertices = {_v(px, y, pz, px + sx, y, pz, px + sx, y, pz + sz, px, y, pz + sz)}",
                    f"emission = {_v(*(exposure * rng.uniform(3, 14) / max(1, k * 2) * np.array([1.0, 0.95, 0.85])))}", ""]
    for k in range(int(rng.integers(0, 3))):
        out += ["[[lights]]", 'type = "sphere"', f'name = "lamp{k}"',
                f"center = {_v(rng.uniform(0.3, W - 0.3), rng.uniform(0.3, H - 0.4), rng.uniform(0.4 * D, D - 0.3))}",
                f"radius = {rng.uniform(0.02, 0.08):.3g}",
                f"emission = {_v(*(exposure * rng.uniform(10, 60) * np.array([1.0, 0.75, 0.45])))}", ""]
    text = "\n".join(out) + "\n"
    meshes = sorted({line.split('"@scenes/')[1].rstrip('"') for line in out if line.startswith('file = "@scenes/')})
    return text, meshes


# --------------------------------------------------------------------------------------------
# Rendering


def _run(cmd, env=None):
    r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    if r.returncode != 0:
        sys.exit(f"training_corpus: '{' '.join(cmd)}' failed ({r.returncode}):\n{r.stdout[-2000:]}")


def frame_attribute(path, name):
    inp = oiio.ImageInput.open(path)
    if not inp:
        sys.exit(f"training_corpus: cannot read {path}: {oiio.geterror()}")
    value = inp.spec().getattribute(name)
    inp.close()
    return value


def scene_content_hash(frame_path):
    """The tracer's content hash of the loaded scene a frame was rendered from."""
    return str(frame_attribute(frame_path, "denoisebench:extra:scene_hash"))


def tracer_version(binary, scene_path, env):
    """The tracer version `binary` renders with: the attribute of a 1x1, 1-spp probe frame."""
    fd, probe = tempfile.mkstemp(suffix=".exr", prefix="dnb-corpus-probe-")
    os.close(fd)
    try:
        _run([binary, "render", scene_path, "--spp", "1", "--size", "1x1", "-o", probe], env)
        return str(frame_attribute(probe, "denoisebench:tracer_version"))
    finally:
        for p in (probe, probe[:-4] + ".edges.exr"):
            if os.path.exists(p):
                os.remove(p)


def build(binary, work, seed, count, size, input_spp, ref_spp, log=print):
    """Generates `count` scenes from `seed` under WORK/scenes, renders what is missing under
    WORK/frames, and returns the manifest: {"scenes": [...], "samples": [...]} where each sample
    is {"scene", "spp", "frame", "reference"} (paths) and each scene records its hashes."""
    scenes_folder = scenes_dir()
    scene_dir, tex_dir, frames = (os.path.join(work, d) for d in ("scenes", "textures", "frames"))
    for d in (scene_dir, tex_dir, frames):
        os.makedirs(d, exist_ok=True)
    env = dict(os.environ)
    if scenes_folder:
        env["DENOISEBENCH_SCENES"] = scenes_folder
    manifest = {"seed": seed, "size": size, "input_spp": list(input_spp), "ref_spp": ref_spp,
                "reference_seed": REFERENCE_SEED, "scenes_folder_found": bool(scenes_folder), "scenes": [], "samples": []}
    rng = np.random.default_rng(seed)
    render_seconds = 0.0
    tracer = None  # the binary's tracer version, from a probe of the first scene

    def kept(frame):
        return os.path.exists(frame) and str(frame_attribute(frame, "denoisebench:tracer_version")) == tracer

    for i in range(count):
        text, meshes = procedural_scene(rng, i, tex_dir, scenes_folder)
        name = f"corpus-{seed}-{i}"
        path = os.path.join(scene_dir, name + ".toml")
        if not os.path.exists(path) or open(path).read() != text:
            write_atomic(path, text.encode())
        if tracer is None:
            tracer = tracer_version(binary, path, env)
            manifest["tracer_version"] = tracer
        file_hash = sha256_file(path)
        tag = file_hash[:12]
        ref = os.path.join(frames, f"{name}-{tag}-ref{ref_spp}-{size}.exr")
        t0 = time.time()
        if not kept(ref):
            log(f"training_corpus: {name}: reference ({ref_spp} spp, {size})")
            _run([binary, "reference", path, "--spp", str(ref_spp), "--size", size, "--seed", str(REFERENCE_SEED),
                  "--block-spp", str(min(256, ref_spp)), "--no-checkpoint", "-o", ref], env)
        for spp in input_spp:
            frame = os.path.join(frames, f"{name}-{tag}-s{spp}-{size}-seed{seed}.exr")
            if not kept(frame):
                log(f"training_corpus: {name}: input ({spp} spp)")
                _run([binary, "render", path, "--spp", str(spp), "--size", size, "--seed", str(seed), "-o", frame], env)
            manifest["samples"].append({"scene": name, "spp": spp, "frame": frame, "reference": ref})
        render_seconds += time.time() - t0
        manifest["scenes"].append({"name": name, "file": path, "sha256": file_hash,
                                   "content_hash": scene_content_hash(ref), "meshes": meshes})
    manifest["render_seconds"] = round(render_seconds, 1)
    return manifest


def evaluation_scene_files():
    """The evaluation and generalisation scenes' files (configs/scenes/*.toml) and the mesh files
    they read (relative to the scenes folder)."""
    files, meshes = [], set()
    for n in sorted(os.listdir(EVALUATION_DIR)):
        if n.endswith(".toml"):
            p = os.path.join(EVALUATION_DIR, n)
            files.append(p)
            with open(p, "rb") as f:
                doc = tomllib.load(f)
            for o in doc.get("objects", []):
                if isinstance(o.get("file"), str) and o["file"].startswith("@scenes/"):
                    meshes.add(o["file"][len("@scenes/"):])
    return files, meshes


# --------------------------------------------------------------------------------------------
# What both trainers share: the split, the crops, the loss


def split(manifest, every=5):
    """(training samples, validation samples): every `every`-th scene (index every-1, 2*every-1,
    ...) is held out for validation, all its spp with it, so validation sees scenes, not only
    pixels, the network never trained on."""
    held = {s["name"] for k, s in enumerate(manifest["scenes"]) if k % every == every - 1}
    train = [s for s in manifest["samples"] if s["scene"] not in held]
    val = [s for s in manifest["samples"] if s["scene"] in held]
    return train, val


def srgb8(image):
    """An image as Table 1 compares it (metrics/metrics.cpp): the display transform (clamp to
    [0, 1], sRGB), times 255, rounded half away from zero as std::round; float64 levels."""
    return np.floor(display(np.asarray(image, np.float64)) * 255.0 + 0.5)


def mse8(image, reference):
    """Table 1's mse: the mean squared difference of srgb8 levels."""
    return float(np.mean((srgb8(image) - srgb8(reference)) ** 2))


def weights_record(manifest, held):
    """What a weights manifest says of its corpus: the build's parameters and every scene (name,
    file relative to the checkout, file SHA-256, content hash, meshes, split; `held`: the names
    of the validation scenes)."""
    def rel(path):
        return os.path.relpath(path, ROOT) if path.startswith(ROOT) else path

    return {
        "corpus": {k: manifest[k] for k in ("seed", "size", "input_spp", "ref_spp", "reference_seed", "scenes_folder_found",
                                            "render_seconds")},
        "scenes": [{"name": s["name"], "file": rel(s["file"]), "sha256": s["sha256"], "content_hash": s["content_hash"],
                    "meshes": s["meshes"], "split": "validation" if s["name"] in held else "training"}
                   for s in manifest["scenes"]],
    }


class CropSampler:
    """Random crops of `patch` x `patch` pixels, half of them uniform over the samples and
    positions, half weighted by the input's error against the reference in display space (the
    metric's space) on a grid of half-patch steps: the hard regions (noise, edges, thin detail
    the filter must keep) are seen more often, as KPCN's importance-sampled patches were."""

    def __init__(self, inputs, references, patch, uniform=0.5):
        self.patch = patch
        self.uniform = uniform
        self.cells = []  # (sample, y, x)
        weights = []
        for i, (x, r) in enumerate(zip(inputs, references)):
            h, w = r.shape[:2]
            ph, pw = min(patch, h), min(patch, w)
            err = np.abs(display(x) - display(r)).mean(axis=2)
            step = max(1, patch // 2)
            for y in range(0, h - ph + 1, step):
                for xx in range(0, w - pw + 1, step):
                    self.cells.append((i, y, xx))
                    weights.append(float(err[y:y + ph, xx:xx + pw].mean()))
        wts = np.asarray(weights, np.float64)
        self.hard = wts / wts.sum() if wts.sum() > 0 else np.full(len(wts), 1.0 / len(wts))
        self.shapes = [r.shape[:2] for r in references]

    def draw(self, rng):
        """One crop: (sample index, y0, x0, height, width)."""
        if rng.uniform() < self.uniform:
            i = int(rng.integers(len(self.shapes)))
            h, w = self.shapes[i]
            ph, pw = min(self.patch, h), min(self.patch, w)
            return i, int(rng.integers(h - ph + 1)), int(rng.integers(w - pw + 1)), ph, pw
        i, y, x = self.cells[int(rng.choice(len(self.cells), p=self.hard))]
        h, w = self.shapes[i]
        return i, y, x, min(self.patch, h), min(self.patch, w)


def display_loss(out, target):
    """The training loss of both learned baselines (torch tensors, N x 3 x H x W, linear HDR):
    L1 in the metric's display space (clamp, sRGB: what Table 1's 8-bit mse sees), plus a tenth
    of L1 between log(1 + x) (KPCN's HDR transform) so that values above 1, which the clamp
    hides, are still pulled towards the reference. The sRGB curve's slope near 0 is capped by
    its linear segment (12.92), so dark pixels get finite gradients."""
    return _display_l1(out, target).mean()


def _display_l1(out, target):
    """Per image of the batch: the display-space L1 plus a tenth of the log L1 (display_loss)."""
    import torch

    def srgb(x):
        c = x.clamp(0.0, 1.0)
        return torch.where(c <= 0.0031308, 12.92 * c, 1.055 * c.clamp_min(0.0031308).pow(1 / 2.4) - 0.055)

    d = (srgb(out) - srgb(target)).abs().mean(dim=(1, 2, 3))
    return d + 0.1 * (torch.log1p(out.clamp_min(0)) - torch.log1p(target)).abs().mean(dim=(1, 2, 3))


RELATIVE_EPS = 2e-3  # display units (half an 8-bit step): a converged crop's ratio stays bounded


def relative_display_loss(out, target, noisy):
    """The mean over the crops of display_loss(out) / (display_loss(noisy input) + 2e-3): each
    crop's error relative to its input's. Why: with the absolute loss, a nearly converged crop
    (256 spp, error ~1/255) weighs a hundredth of a 4-spp crop, so a network can double its
    error there at no cost, and did (kpcn on held-out corpus scene 14 at 256 spp: 8-bit mse 6.7
    -> 21.7). Relative, every crop counts alike and a crop made worse than its input costs more
    than one left as it is: the loss aims at what the learned rows must do, never be worse than
    their input."""
    return (_display_l1(out, target) / (_display_l1(noisy.clamp_min(0), target) + RELATIVE_EPS)).mean()


GUARD_WEIGHT = 4.0


def guarded_display_loss(out, target, noisy, weight=GUARD_WEIGHT):
    """display_loss plus `weight` (4) times, per crop, how far display_loss(out) rises above the noisy input's
    own (zero where the output is no worse than its input): the absolute loss drives the
    denoising, the hinge penalises only a crop made worse than it came in. Why not the relative
    loss alone: a U-Net trained on it stayed the identity (held-out 8-bit mse 190.0 -> 190.7
    over 8000 steps; docs/method-defaults.md, "unet"), its gradient dominated by converged crops
    where any change costs."""
    net = _display_l1(out, target)
    base = _display_l1(noisy.clamp_min(0), target)
    return net.mean() + weight * (net - base).clamp_min(0).mean()
