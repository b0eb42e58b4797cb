#!/usr/bin/python3
"""The report's sequences: one MP4 per animated sequence and input spp, and the page's section
that links the videos and the per-frame plots (run by `denoisebench report`).

For each sequence of results.json (`sequences`, experiment/results.h SequenceRecord) and each
input spp, at the first input seed: every frame of the input, of each method and variant and of
the reference, tone-mapped as the viewer's default (x 1, i.e. exposure 0 stops, clamped to
[0, 1], sRGB), tiled side by side (rows of at most 5) with each column's name above its tile
and the frame above the grid, encoded by ffmpeg at 4 frames a second:

  videos/<sequence>_<spp>spp.mp4   H.264 (libx264) when ffmpeg has it, else MPEG-4 part 2;
                                   yuv420p, even width and height; one video frame per frame
  web/sequences.html               the page's "Sequences" section (experiment/report.cpp puts
                                   it in index.html): per sequence and spp the video, and
                                   plots/sequence_<sequence>_<spp>spp_{mse,tmse}.png where
                                   reports/plots.py wrote them

Tiles narrower than 160 pixels are enlarged by a whole factor (nearest neighbour), so that the
labels fit and the pixels stay pixels. The images are the ones results.json names: the
sequence record's `images` for the input and the methods, and each frame row's record's
`reference.image` for the reference.

ffmpeg is $DENOISEBENCH_FFMPEG when set, else `ffmpeg` on PATH. Without it (or without an
encoder named above), or with --no-video (`report --no-images`), no video is written: the log
and the page say so and why, and the section is written all the same.

Exit 2 (bad input) naming results.json's key and the file when an image it names is missing or
unreadable, or a sequence record lacks a frame; exit 1 when ffmpeg fails, with its message.

Usage: /usr/bin/python3 reports/video.py RESULTS_DIR [--no-video]
"""
import html
import os
import re
import shutil
import subprocess
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import method_style  # noqa: E402
from viewer import BadInput, read_exr  # noqa: E402  (channels looked up by name)

FPS = 4
MAX_COLUMNS = 5   # tiles per row of the grid
MIN_TILE = 160    # tiles narrower than this are enlarged by a whole factor
LABEL_H = 18      # the strip above each tile
TITLE_H = 22      # the strip above the grid
GAP = 4
BG = (34, 34, 34)


def safe(name):  # as reports/plots.py names its files
    return re.sub(r"[^A-Za-z0-9_.-]", "_", name)


def anchor(name):  # as reports/viewer.js names a scene's section
    return "scene-" + re.sub(r"[^A-Za-z0-9_-]", "_", name)


def frame_row(name, t):  # experiment/config.cpp sequence_row
    return f"{name}.f{t:02d}"


def log(msg):
    print(msg, flush=True)


def to_srgb8(px):
    """Linear radiance -> 8-bit sRGB: x 1 (exposure 0), clamp to [0, 1], the sRGB curve (viewer.js srgb)."""
    v = np.clip(np.nan_to_num(px, nan=0.0, posinf=1.0, neginf=0.0), 0.0, 1.0)
    s = np.where(v <= 0.0031308, 12.92 * v, 1.055 * np.power(v, 1 / 2.4) - 0.055)
    return np.round(255 * s).astype(np.uint8)


def text_strip(text, width, height, fontsize, chip=None):
    """`text` in white on the background, left-aligned, clipped to width x height (matplotlib's
    Agg renderer and its bundled DejaVu Sans: no font of the system is needed); with `chip`, a
    small square of that colour before it."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=(width / 100, height / 100), dpi=100, facecolor=tuple(c / 255 for c in BG))
    canvas = FigureCanvasAgg(fig)
    x = 4 + (height - 6 + 4 if chip else 0)
    fig.text(x / width, 0.5, text, color="white", fontsize=fontsize, va="center", ha="left",
             family="DejaVu Sans", clip_on=True)
    canvas.draw()
    img = np.asarray(canvas.buffer_rgba())[:, :, :3].copy()
    if img.shape[0] != height or img.shape[1] != width:  # rounding of the figure size
        out = np.empty((height, width, 3), np.uint8)
        out[:] = BG
        h, w = min(height, img.shape[0]), min(width, img.shape[1])
        out[:h, :w] = img[:h, :w]
        img = out
    if chip:
        c = [int(chip[i:i + 2], 16) for i in (1, 3, 5)]
        img[3:height - 3, 4:4 + height - 6] = (160, 160, 160)  # an outline: black (the reference) shows
        img[4:height - 4, 5:3 + height - 6] = c
    return img


def find_ffmpeg():
    """(path, encoder, None) or (None, None, why not)."""
    env = os.environ.get("DENOISEBENCH_FFMPEG") or os.environ.get("DNB_FFMPEG")
    if env:
        if not (os.path.isfile(env) and os.access(env, os.X_OK)):
            return None, None, f"DENOISEBENCH_FFMPEG='{env}' is not an executable file"
        exe = env
    else:
        exe = shutil.which("ffmpeg")
        if not exe:
            return None, None, "ffmpeg is not installed (not on PATH; Debian's ffmpeg, which scripts/setup installs)"
    try:
        enc = subprocess.run([exe, "-hide_banner", "-encoders"], capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired) as e:
        return None, None, f"'{exe} -encoders' failed: {e}"
    names = {line.split()[1] for line in enc.stdout.splitlines() if len(line.split()) > 1 and line.startswith(" V")}
    for encoder in ("libx264", "mpeg4"):
        if encoder in names:
            return exe, encoder, None
    return None, None, f"'{exe}' has neither the libx264 nor the mpeg4 encoder"


class Layout:
    def __init__(self, n, w, h):
        self.scale = max(1, -(-MIN_TILE // w))
        self.tw, self.th = w * self.scale, h * self.scale
        self.cols = min(n, MAX_COLUMNS)
        self.rows = -(-n // self.cols)
        width = self.cols * self.tw + (self.cols + 1) * GAP
        height = TITLE_H + self.rows * (LABEL_H + self.th + GAP) + GAP
        self.width, self.height = width + width % 2, height + height % 2  # yuv420p: even sizes

    def origin(self, k):
        """Top-left corner of tile k's label strip."""
        r, c = divmod(k, self.cols)
        return TITLE_H + r * (LABEL_H + self.th + GAP), GAP + c * (self.tw + GAP)


def columns_of(dir_, res, name, spp, seed, frames):
    """[(label, colour, [image path per frame], [results.json key per frame])] at (spp, seed):
    the input, the methods, the ablations (in record order), then the reference."""
    order = {"input": 0, "method": 1, "ablation": 2}
    seqs = [(i, r) for i, r in enumerate(res.get("sequences") or [])
            if r["sequence"] == name and r["spp"] == spp and r.get("seed") == seed]
    seqs.sort(key=lambda ir: order.get(ir[1].get("role"), 3))
    parents = method_style.parents(res.get("records", []))
    cols = []
    for i, r in seqs:
        imgs = r.get("images") or []
        if len(imgs) != frames:
            raise BadInput(f"{os.path.join(dir_, 'results.json')}: sequences[{i}].images: {len(imgs)} images for "
                           f"{frames} frames ({name}, {r['method']}, {spp} spp)")
        m = r["method"]
        label = f"input ({spp} spp)" if r.get("role") == "input" else m
        cols.append((label, method_style.style(m, parents.get(m))["colour"], imgs,
                     [f"sequences[{i}].images[{t}]" for t in range(frames)]))
    refs, keys, ref_spp = [], [], None
    recs = res.get("records", [])
    for t in range(frames):
        row = frame_row(name, t)
        hit = next(((i, r) for i, r in enumerate(recs) if r["scene"] == row and r.get("reference", {}).get("image")
                    and r["spp"] == spp and r.get("seed") == seed), None) or \
            next(((i, r) for i, r in enumerate(recs) if r["scene"] == row and r.get("reference", {}).get("image")), None)
        if not hit:
            raise BadInput(f"{os.path.join(dir_, 'results.json')}: records: no record of row '{row}' names its "
                           f"reference image (sequence {name}, frame {t})")
        refs.append(hit[1]["reference"]["image"])
        keys.append(f"records[{hit[0]}].reference.image")
        ref_spp = hit[1]["reference"].get("spp", ref_spp)
    cols.append((f"reference ({ref_spp} spp)" if ref_spp else "reference", method_style.style("reference")["colour"],
                 refs, keys))
    return cols


def encode(dir_, res, name, spp, seed, frames, exe, encoder):
    """Writes videos/<name>_<spp>spp.mp4; returns (relative path, column labels)."""
    cols = columns_of(dir_, res, name, spp, seed, frames)
    first = read_exr(dir_, cols[0][2][0], cols[0][3][0])
    h, w = first.shape[:2]
    lay = Layout(len(cols), w, h)
    rel = f"videos/{safe(name)}_{spp}spp.mp4"
    out = os.path.join(dir_, rel)
    os.makedirs(os.path.dirname(out), exist_ok=True)
    tmp = out + ".tmp.mp4"
    quality = ["-crf", "18", "-preset", "medium"] if encoder == "libx264" else ["-q:v", "3"]
    cmd = [exe, "-hide_banner", "-loglevel", "error", "-y", "-f", "rawvideo", "-pix_fmt", "rgb24",
           "-s", f"{lay.width}x{lay.height}", "-framerate", str(FPS), "-i", "-", "-c:v", encoder, *quality,
           "-pix_fmt", "yuv420p", "-movflags", "+faststart", tmp]
    canvas = np.empty((lay.height, lay.width, 3), np.uint8)
    canvas[:] = BG
    for k, (label, colour, _, _) in enumerate(cols):  # the labels are the same on every frame
        y, x = lay.origin(k)
        canvas[y:y + LABEL_H, x:x + lay.tw] = text_strip(label, lay.tw, LABEL_H, 8.5, chip=colour)
    err = open(tmp + ".log", "w+")
    proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=err)
    try:
        for t in range(frames):
            title = f"{name}  |  {spp} spp input, seed {seed}  |  frame {t:02d} ({t + 1} of {frames})"
            canvas[:TITLE_H] = text_strip(title, lay.width, TITLE_H, 10)
            for k, (_, _, imgs, keys) in enumerate(cols):
                px = first if (k == 0 and t == 0) else read_exr(dir_, imgs[t], keys[t])
                if px.shape[:2] != (h, w):
                    raise BadInput(f"{os.path.join(dir_, 'results.json')}: {keys[t]}: '{imgs[t]}' is "
                                   f"{px.shape[1]}x{px.shape[0]}, the sequence's first image {w}x{h}")
                tile = to_srgb8(px)
                if lay.scale > 1:
                    tile = tile.repeat(lay.scale, 0).repeat(lay.scale, 1)
                y, x = lay.origin(k)
                canvas[y + LABEL_H:y + LABEL_H + lay.th, x:x + lay.tw] = tile
            proc.stdin.write(canvas.tobytes())
        proc.stdin.close()
        rc = proc.wait()
    except BrokenPipeError:
        rc = proc.wait()
    except BaseException:
        proc.kill()
        proc.wait()
        raise
    err.seek(0)
    msg = err.read().strip().splitlines()
    err.close()
    os.remove(tmp + ".log")
    if rc != 0 or not os.path.exists(tmp):
        if os.path.exists(tmp):
            os.remove(tmp)
        raise RuntimeError(f"ffmpeg failed (exit {rc}) on {rel}: `{' '.join(cmd)}`: "
                           f"{' / '.join(msg[-3:]) if msg else 'no message'}")
    os.replace(tmp, out)
    return rel, [c[0] for c in cols], lay


def plot_links(dir_, name, spp):
    out = []
    for metric in ("mse", "tmse"):
        stem = f"plots/sequence_{safe(name)}_{spp}spp_{metric}"
        if os.path.exists(os.path.join(dir_, stem + ".png")):
            pdf = f' (<a href="{stem}.pdf">PDF</a>)' if os.path.exists(os.path.join(dir_, stem + ".pdf")) else ""
            out.append(f'<figure><img src="{stem}.png" alt="per-frame {metric}: {html.escape(name)}, {spp} spp">'
                       f'<figcaption>{stem}.png{pdf}</figcaption></figure>')
    return out


def main():
    args = [a for a in sys.argv[1:] if a != "--no-video"]
    if len(args) != 1:
        sys.exit("usage: video.py RESULTS_DIR [--no-video]")
    dir_ = args[0]
    import json
    with open(os.path.join(dir_, "results.json")) as f:
        res = json.load(f)
    seqs = res.get("sequences") or []
    if not seqs:
        log("no sequences in results.json: nothing to do")
        return
    cfg = res.get("config", {})
    lengths = cfg.get("sequences") or {}
    names = list(dict.fromkeys(list(lengths) + [r["sequence"] for r in seqs]))
    seeds = cfg.get("seeds") or []
    if "--no-video" in sys.argv[1:]:
        exe, encoder, why = None, None, "written with report --no-images"
    else:
        exe, encoder, why = find_ffmpeg()
    if why:
        log(f"warning: sequence videos skipped: {why}")
    viewer = os.path.exists(os.path.join(dir_, "web/viewer/manifest.js"))
    parts = ['<h2 id="sequences">Sequences</h2>',
             "<p>Per animated sequence and input spp: each column's mse and tmse frame by frame "
             "(<code>plots/sequence_*</code>, from results.json's <code>sequences</code>; the mean over the seeds), "
             f"and a video of the input, every method and the reference side by side at the first seed ({FPS} frames "
             "a second, tone-mapped as the viewer's default: linear, exposure 0, clamped, sRGB).</p>"]
    try:
        for name in names:
            rs = [r for r in seqs if r["sequence"] == name]
            if not rs:
                continue
            frames = int(lengths.get(name) or max(r.get("frames") or 0 for r in rs))
            parts.append(f'<section class="sequence" id="sequence-{html.escape(safe(name))}">'
                         f"<h3>{html.escape(name)} ({frames} frames)</h3>")
            if viewer:
                parts.append(f'<p>Every frame\'s images, any two side by side with a frame slider: '
                             f'<a href="#{html.escape(anchor(name))}">{html.escape(name)} in the viewer</a>.</p>')
            for spp in sorted({r["spp"] for r in rs}):
                have = {r.get("seed") for r in rs if r["spp"] == spp}
                seed = next((s for s in seeds if s in have), None)
                if seed is None:
                    seed = min(have, key=lambda s: (s is None, s or 0))
                parts.append(f"<h4>{spp} spp input</h4>")
                if exe:
                    rel, labels, lay = encode(dir_, res, name, spp, seed, frames, exe, encoder)
                    log(f"{rel}: {frames} frames, {lay.width}x{lay.height}, {encoder}: {', '.join(labels)}")
                    parts.append(f'<figure class="video"><video src="{rel}" preload="metadata" controls loop muted playsinline '
                                 f'width="{lay.width}" height="{lay.height}"></video><figcaption>{html.escape(", ".join(labels))}'
                                 f' (seed {seed}; <a href="{rel}">{rel}</a>)</figcaption></figure>')
                else:
                    parts.append(f'<p class="note">No video: {html.escape(why)}.</p>')
                links = plot_links(dir_, name, spp)
                parts.append('<div class="plots">' + "\n".join(links) + "</div>" if links else
                             '<p class="note">No per-frame plots (written with <code>report --no-plots</code>).</p>')
            parts.append("</section>")
    except BadInput as e:
        print(f"error: {e}", file=sys.stderr)
        sys.exit(2)
    except RuntimeError as e:
        print(f"error: {e}", file=sys.stderr)
        sys.exit(1)
    path = os.path.join(dir_, "web/sequences.html")
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path + ".tmp", "w") as f:
        f.write("\n".join(parts) + "\n")
    os.replace(path + ".tmp", path)


if __name__ == "__main__":
    main()
