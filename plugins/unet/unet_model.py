"""A U-Net denoiser in the manner of Intel Open Image Denoise (OIDN's "RT" network: an
encoder-decoder of 3x3 convolutions and ReLUs, max-pooling down, nearest upsampling up, skips by
concatenation, the input itself concatenated before the last convolutions), in PyTorch (Debian
python3-torch, CPU), trained here by scripts/train_unet on the training corpus
(python/training_corpus.py). Shared by the worker (unet_worker.py) and the training script, so
what is trained is exactly what runs.

Inputs, per pixel (10 channels), as OIDN's colour + albedo + normal, plus one of our own:

  colour    log(1 + s * F)          F the frame's colour (non-finite and negative samples -> 0),
                                    s the frame's auto-exposure (OIDN's: 0.18 over the geometric
                                    mean of the luminance of 16 x 16-pixel bins, the bins above
                                    1e-8; computed on the noisy input, once per whole frame).
                                    log(1 + x) is the HDR transfer function, where OIDN uses its
                                    PU curve: both compress highlights and are near linear at 0
  albedo    T clamped to [0, 1]     the harness's T (docs/method-defaults.md, "oidn", says how
                                    it differs from OIDN's albedo on glass and metal)
  normal    N clamped to [-1, 1]    world-space shading normal
  noise     log(1 + var / (m^2 + 1e-2))   the variance of the pixel's mean over its squared mean
                                    colour (means over the channels), both at exposure s, as
                                    kpcn_model.prepare computes it. NOT in OIDN, which has no
                                    noise-level input: it is what lets one network keep a nearly
                                    converged frame (256 spp) and smooth a 4-spp one

The network predicts a residual r in the transfer space, and the output is the inverse
transfer of (input + r), written so that r = 0 gives back F exactly:

  out = expm1(log1p(s F) + r) / s = F + (F + 1 / s) * expm1(r),   clamped at 0

The last convolution is zero-initialised (weights and bias), so the untrained network is the
identity bit for bit: a learned method that starts from its input, not from a blur, and moves
away from it only where training lowered the loss. Non-finite output values (r overflowing
exp) fall back to the input.

Frames of any size: the features are padded to a multiple of 2^levels by replicating the last
row and column, and the output cropped back. The whole frame runs at once (no tiles; the
U-Net's receptive field is wider than any halo worth paying): at the default size a 1024x768
frame peaks at about 0.5 GB above the interpreter (measured 470 MB, 0.6 KB per pixel) and takes
about 1.1 s on one busy core (2026-12-06). Every layer is deterministic on the
CPU (convolutions, max-pooling, nearest upsampling, concatenation), and the same weights give the
same output bit for bit on one and two torch threads (tested).
"""
import os

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F

LAYERS = ["color", "albedo", "normal", "variance"]
FEATURES = 10  # 3 log colour, 3 albedo, 3 normal, 1 log relative variance
EXPOSURE_KEY = 0.18  # OIDN's auto-exposure: the key value
EXPOSURE_BIN = 16  # OIDN's auto-exposure: bins of 16 x 16 pixels
EXPOSURE_EPS = 1e-8


def widths(base, levels):
    """Encoder widths in OIDN's proportions (32, 48, 64, 80, 96 for base 32): base * (1 + k / 2)
    at level k = 0..levels (level `levels` is the bottleneck)."""
    return [int(round(base * (1 + 0.5 * k))) for k in range(levels + 1)]


def _conv(cin, cout):
    c = nn.Conv2d(cin, cout, 3, padding=1)
    nn.init.kaiming_uniform_(c.weight, nonlinearity="relu")  # He initialisation, as OIDN's
    nn.init.zeros_(c.bias)
    return c


class Unet(nn.Module):
    """OIDN's U-Net shape with `levels` poolings and encoder widths `widths(base, levels)`:

      enc0, enc1 (full resolution, e0) -> pool -> skip 1 (1/2)
      enc_k (e_k, at 1/2^k) -> pool -> skip k + 1          for k = 1 .. levels - 1
      bottleneck: two convolutions of e_levels at 1/2^levels
      up, concat skip k, two convolutions of e_{k+1}       for k = levels - 1 .. 1
      up, concat the input, convolutions of 2 * base and base, the last one to 3 (zero-init)

    (OIDN: levels 4, base 32, decoder widths 112, 96, 64 instead of e_{k+1}; about 0.9 M
    parameters. Ours: levels 4, base 16, 0.2 M.)"""

    def __init__(self, base=16, levels=4):
        super().__init__()
        if levels < 1 or base < 1:
            raise ValueError(f"levels {levels} and base {base} must be at least 1")
        self.config = {"base": base, "levels": levels}
        self.levels = levels
        e = widths(base, levels)
        self.enc0 = _conv(FEATURES, e[0])
        self.enc1 = _conv(e[0], e[0])
        self.enc = nn.ModuleList([_conv(e[k - 1], e[k]) for k in range(1, levels)])
        self.bottleneck = nn.ModuleList([_conv(e[levels - 1], e[levels]), _conv(e[levels], e[levels])])
        # Decoder at level k (1/2^k) for k = levels - 1 .. 1: input = upsampled previous (width
        # e_{k+2} at k + 1 = levels: e_levels) + skip k (width e_{k-1}).
        self.dec = nn.ModuleList()
        prev = e[levels]
        for k in range(levels - 1, 0, -1):
            self.dec.append(nn.ModuleList([_conv(prev + e[k - 1], e[k + 1]), _conv(e[k + 1], e[k + 1])]))
            prev = e[k + 1]
        self.dec0a = _conv(prev + FEATURES, 2 * base)
        self.dec0b = _conv(2 * base, base)
        self.out = nn.Conv2d(base, 3, 3, padding=1)
        nn.init.zeros_(self.out.weight)  # the untrained net is the identity (module docstring)
        nn.init.zeros_(self.out.bias)

    def multiple(self):
        return 1 << self.levels

    def forward(self, features):
        """features: N x FEATURES x H x W (any H, W). Returns the residual r, N x 3 x H x W."""
        h, w = features.shape[2], features.shape[3]
        m = self.multiple()
        ph, pw = (-h) % m, (-w) % m
        x0 = F.pad(features, (0, pw, 0, ph), mode="replicate") if ph or pw else features
        relu = F.relu
        x = relu(self.enc1(relu(self.enc0(x0))))
        skips = [F.max_pool2d(x, 2)]  # skip 1, at 1/2
        x = skips[0]
        for conv in self.enc:
            x = F.max_pool2d(relu(conv(x)), 2)
            skips.append(x)
        x = skips.pop()  # the deepest pooled map feeds the bottleneck (it is not a skip)
        for conv in self.bottleneck:
            x = relu(conv(x))
        for (ca, cb), skip in zip(self.dec, reversed(skips)):
            x = torch.cat([F.interpolate(x, scale_factor=2.0, mode="nearest"), skip], dim=1)
            x = relu(cb(relu(ca(x))))
        x = torch.cat([F.interpolate(x, scale_factor=2.0, mode="nearest"), x0], dim=1)
        x = relu(self.dec0b(relu(self.dec0a(x))))
        r = self.out(x)
        return r[:, :, :h, :w] if ph or pw else r


def compose(color, residual, exposure):
    """The output from the linear colour F (N x 3 x H x W, finite, >= 0), the residual r and the
    exposure s (N x 1 x 1 x 1): F + (F + 1/s) expm1(r) = expm1(log1p(sF) + r) / s, clamped at
    0; exactly F where r = 0."""
    return (color + (color + 1.0 / exposure) * torch.expm1(residual)).clamp_min(0.0)


# --------------------------------------------------------------------------------------------
# Frames to features


def _hwc(frame, name):
    a = np.asarray(frame[name], dtype=np.float32)
    return a if a.ndim == 3 else a[:, :, None]


def _finite(a, lo, hi):
    return np.clip(np.where(np.isfinite(a), a, 0.0), lo, hi).astype(np.float32)


def auto_exposure(color):
    """OIDN's auto-exposure (core/autoexposure.h): the luminance averaged over bins of 16 x 16
    pixels (the last bins smaller), the geometric mean of the bins above 1e-8, and the scale
    that maps it to 0.18 (1 where no bin is lit). In float64: one number per frame."""
    h, w = color.shape[:2]
    lum = color.astype(np.float64) @ np.array([0.2126, 0.7152, 0.0722])
    b = EXPOSURE_BIN
    logs = []
    for y in range(0, h, b):
        row = lum[y:y + b]
        for x in range(0, w, b):
            v = float(row[:, x:x + b].mean())
            if v > EXPOSURE_EPS:
                logs.append(np.log2(v))
    if not logs:
        return 1.0
    return float(EXPOSURE_KEY / np.exp2(np.mean(logs)))


def prepare(frame):
    """The frame's planes: "features" (FEATURES x H x W float32), "color" (3 x H x W, the linear
    colour made finite and >= 0) and "exposure" (a float). `frame` maps layer names to
    H x W x C arrays."""
    color = _hwc(frame, "color")
    color = np.where(np.isfinite(color), np.maximum(color, 0.0), 0.0).astype(np.float32)
    albedo = _finite(_hwc(frame, "albedo"), 0.0, 1.0)
    normal = _finite(_hwc(frame, "normal"), -1.0, 1.0)
    var = _finite(_hwc(frame, "variance"), 0.0, 3.0e38)
    s = auto_exposure(color)
    mean = color.mean(axis=2, keepdims=True, dtype=np.float64) * s
    rel_var = np.log1p(var.mean(axis=2, keepdims=True, dtype=np.float64) * (s * s) / (mean * mean + 1e-2))
    log_color = np.log1p(color.astype(np.float64) * s)
    feats = np.concatenate([log_color, albedo, normal, rel_var], axis=2)

    def chw(a):
        return np.ascontiguousarray(np.transpose(a, (2, 0, 1)), dtype=np.float32)

    return {"features": chw(feats), "color": chw(color), "exposure": float(s)}


@torch.no_grad()
def denoise_planes(model, planes):
    """Denoises a whole frame (planes from `prepare`); returns H x W x 3 float32."""
    model.eval()
    f = torch.from_numpy(planes["features"])[None]
    c = torch.from_numpy(planes["color"])[None]
    s = torch.full((1, 1, 1, 1), planes["exposure"], dtype=torch.float32)
    out = compose(c, model(f), s)
    out = torch.where(torch.isfinite(out), out, c)
    return np.ascontiguousarray(np.transpose(out[0].numpy(), (1, 2, 0)))


def save(model, path, extra=None):
    """Writes {"config", "state"} (and `extra`) to `path` through a temporary file."""
    blob = {"config": model.config, "state": model.state_dict()}
    blob.update(extra or {})
    tmp = f"{path}.tmp-{os.getpid()}"
    torch.save(blob, tmp)
    os.replace(tmp, path)


def load(path):
    """Loads weights written by scripts/train_unet: {"config": ..., "state": state_dict}."""
    blob = torch.load(path, map_location="cpu")
    cfg = blob["config"]
    model = Unet(cfg["base"], cfg["levels"])
    model.load_state_dict(blob["state"])
    model.eval()
    return model


def parameter_count(model):
    return int(sum(p.numel() for p in model.parameters()))
