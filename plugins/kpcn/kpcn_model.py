"""KPCN-style kernel-predicting network for denoisebench frames (Bako et al. 2017, "Kernel-Predicting
Convolutional Networks for Denoising Monte Carlo Renderings"), in PyTorch (Debian python3-torch,
CPU). Shared by the worker (kpcn_worker.py) and the training script (scripts/train_kpcn), so that
what is trained is exactly what runs.

As in KPCN, the frame is split into a diffuse and a specular part, each filtered by kernels of
its own:

  diffuse   Ld = (F - R - E) / (T + eps)   the textured diffuse part demodulated by the albedo T
                                           (exact on pixel means: T * Ld + R + E = F where T > 0)
  specular  R                              radiance through a specular first bounce (paper's R)
  emission  E                              passed through untouched

The network sees both parts log-transformed (log(1 + x), KPCN's transform for HDR inputs) with
the frame's variance (relative, log-transformed), the albedo, the normal and the depth, and
predicts a k x k kernel per pixel and part; the kernel's weights are a softmax, so they are
positive and sum to one, and the output is the weighted mean of the *linear* noisy part over
the window:

  out = T_eps * (K_d * Ld) + K_s * R + E

where Ld and R have had their fireflies cut first (split_fireflies, the harness's own rule), and
the cut light is dropped, as `proposed` and the illumination baselines drop it by default,
rather than spread back over a 33 x 33 box (energy kept): spread, the sun's fireflies on McGuire's
Sponza at 16 spp (the generalisation run) came out as bright squares, mse 9349 against the
input's 941; dropped, 710 (the quick run's cornell-box 28.1 -> 27.6 at seed 1, sponza unchanged).

A constant input stays constant whatever the weights (a normalised kernel of a constant), no
output is negative, and the output is a convex combination of the input's own values: a learned
method that cannot invent energy, the property that made KPCN stable to train. (Unlike KPCN the
specular kernel filters R linearly, not its logarithm, which would darken it: the mean of
log(1 + R) is below log(1 + mean R).)

The network: one trunk of 3x3 convolutions, 32 channels, ReLU, dilations 1, 1, 2, 4, 8, 1, 1 (a
receptive field of 37 x 37), then one 1x1 convolution per part to its k^2 kernel logits: 0.06 M
parameters, small enough to train on 2 CPU cores in well under an hour (KPCN's two nets of
nine 5x5 layers of 100 channels would take days there). Full frames are denoised in tiles with a
halo of the receptive field, so memory stays bounded whatever the frame's size, and the output
does not depend on the tile size beyond float rounding (the halo covers every pixel a tile's
output depends on; measured 4e-6 between tile sizes on values around 1).
"""
import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F

ALBEDO_EPS = 0.00316  # KPCN's demodulation epsilon
# 3 log diffuse, 3 log specular, 1 log relative variance, 3 albedo, 3 normal, 1 log relative depth
FEATURES = 14
DILATIONS = (1, 1, 2, 4, 8, 1, 1)
FIREFLY_RATIO = 3.0   # as the harness's baselines' firefly_ratio default
LAYERS = ["color", "albedo", "reflection", "emission", "normal", "depth", "variance"]


def receptive_radius(dilations=DILATIONS):
    return sum(dilations)


class Kpcn(nn.Module):
    """One convolutional trunk over both parts' features, two heads: the diffuse and the specular
    part each get their own k x k kernels (softmax weights). Sharing the trunk halves the cost
    of KPCN's two separate networks on a CPU; the parts stay separate where it matters, in the
    kernels that filter them."""

    def __init__(self, channels=32, kernel=11, dilations=DILATIONS):
        super().__init__()
        self.config = {"channels": channels, "kernel": kernel, "dilations": list(dilations)}
        layers = []
        cin = FEATURES
        for d in dilations:
            layers += [nn.Conv2d(cin, channels, 3, padding=d, dilation=d), nn.ReLU(inplace=True)]
            cin = channels
        self.trunk = nn.Sequential(*layers)
        self.diffuse_head = nn.Conv2d(channels, kernel * kernel, 1)
        self.specular_head = nn.Conv2d(channels, kernel * kernel, 1)
        # The untrained kernels keep half of each pixel's own value (the centre's logit is
        # log(k^2 - 1) above the others'): an untrained or barely trained net is the input half
        # blurred, not an 11 x 11 box blur, which erased thin lines over whole regions (20x the
        # input's mse on a held-out scene of thin texture lines). Training moves the weight off
        # the centre only where that lowers the loss.
        with torch.no_grad():
            for head in (self.diffuse_head, self.specular_head):
                head.weight.mul_(0.1)
                head.bias.zero_()
                head.bias[(kernel * kernel) // 2] = float(np.log(kernel * kernel - 1))
        self.kernel = kernel
        self.radius = receptive_radius(dilations)

    def kernels(self, features):
        t = self.trunk(features)
        return torch.softmax(self.diffuse_head(t), dim=1), torch.softmax(self.specular_head(t), dim=1)

    def forward(self, batch):
        """batch: a dict of N x C x H x W tensors from `window` (the sources with the kernel's
        margin of kernel // 2 on every side). Returns the N x 3 x H x W denoised colour."""
        kd, ks = self.kernels(batch["features"])
        d = apply_kernel(batch["diffuse_src"], kd, self.kernel)
        s = apply_kernel(batch["specular_src"], ks, self.kernel)
        return batch["albedo_eps"] * d + s + batch["emission"]


def apply_kernel(src, weights, kernel):
    """src: N x 3 x (H + k - 1) x (W + k - 1), weights: N x k^2 x H x W. Per pixel, the weighted
    sum of its k x k window of src (unfold: one matrix product per image)."""
    n, c = src.shape[0], src.shape[1]
    h, w = weights.shape[2], weights.shape[3]
    cols = F.unfold(src, kernel)  # N x (c * k^2) x (H * W)
    cols = cols.view(n, c, kernel * kernel, h * w)
    out = (cols * weights.reshape(n, 1, kernel * kernel, h * w)).sum(dim=2)
    return out.view(n, c, h, w)


def split_fireflies(layer, ratio=FIREFLY_RATIO):
    """The firefly split of the harness's filters (denoisers/illumination.h, split_fireflies):
    a pixel whose Rec. 709 luminance exceeds `ratio` times the largest of its 8 neighbours' is
    scaled down to that bound. Returns (kept, excess = layer - kept). Why here too: a kernel's
    weights are a softmax, never exactly 0, so a firefly a hundred thousand times brighter than
    its surroundings (the sun reached by a diffuse bounce) would print the kernel's shape around
    itself whatever the network learns. `prepare` drops the excess (module docstring)."""
    h, w = layer.shape[:2]
    lum = layer @ np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)
    if h * w <= 1:
        return layer, np.zeros_like(layer)
    p = np.pad(lum, 1, constant_values=0.0)  # luminance >= 0: outside pixels never raise a max
    m = np.zeros_like(lum)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            if dy or dx:
                m = np.maximum(m, p[1 + dy:1 + dy + h, 1 + dx:1 + dx + w])
    bound = ratio * m
    scale = np.where(lum > bound, bound / np.maximum(lum, 1e-30), 1.0).astype(np.float32)
    kept = layer * scale[:, :, None]
    return kept, layer - kept


def _hwc(frame, name):
    a = np.asarray(frame[name], dtype=np.float32)
    return a if a.ndim == 3 else a[:, :, None]


def prepare(frame):
    """The frame's layers as full-size float32 planes (3 x H x W or 1 x H x W numpy arrays):
    the linear sources and the features of both parts. `frame` maps layer names to H x W x C."""
    color, albedo = _hwc(frame, "color"), _hwc(frame, "albedo")
    refl, emis = _hwc(frame, "reflection"), _hwc(frame, "emission")
    normal, depth, var = _hwc(frame, "normal"), _hwc(frame, "depth"), _hwc(frame, "variance")
    t_eps = albedo + ALBEDO_EPS
    diffuse, _ = split_fireflies(np.maximum(color - refl - emis, 0.0) / t_eps)
    specular, _ = split_fireflies(np.maximum(refl, 0.0))
    # The noise as a relative quantity, one channel: the variance of the pixel's mean over its
    # (mean colour^2 + 1e-2), log-transformed (scale-free features generalise across exposures).
    rel_var = np.log1p(var.mean(axis=2, keepdims=True) / (color.mean(axis=2, keepdims=True) ** 2 + 1e-2))
    # Depth relative to the frame's median (scenes differ in scale), log-transformed.
    finite = depth[np.isfinite(depth) & (depth > 0)]
    med = float(np.median(finite)) if finite.size else 1.0
    rel_depth = np.log1p(np.clip(depth, 0.0, 1e6) / max(med, 1e-6))
    common = [rel_var, albedo, normal, rel_depth]

    def chw(a):
        return np.ascontiguousarray(np.transpose(a, (2, 0, 1)), dtype=np.float32)

    return {
        "diffuse_src": chw(diffuse),
        "specular_src": chw(specular),
        "albedo_eps": chw(t_eps),
        "emission": chw(emis),
        "features": chw(np.concatenate([np.log1p(diffuse), np.log1p(specular)] + common, axis=2)),
    }


def window(planes, y0, y1, x0, x1, margin):
    """Crops the planes of `prepare` to rows [y0, y1) and columns [x0, x1) as a batch of one;
    the two linear sources get `margin` more pixels on every side, replicated at the frame's
    border (so a constant frame's border stays constant)."""
    h, w = planes["diffuse_src"].shape[1:]
    out = {}
    for name, a in planes.items():
        if name.endswith("_src"):
            ys = np.clip(np.arange(y0 - margin, y1 + margin), 0, h - 1)
            xs = np.clip(np.arange(x0 - margin, x1 + margin), 0, w - 1)
            crop = a[:, ys][:, :, xs]
        else:
            crop = a[:, y0:y1, x0:x1]
        out[name] = torch.from_numpy(np.ascontiguousarray(crop))[None]
    return out


@torch.no_grad()
def denoise_planes(model, planes, tile=384):
    """Denoises a whole frame in tiles of `tile` x `tile` pixels. Each tile's networks see the
    tile plus a halo of the receptive field (clipped at the frame's border, where the
    convolutions' zero padding applies as on the whole frame), so the output is that of the
    whole frame at once, in bounded memory."""
    model.eval()
    h, w = planes["diffuse_src"].shape[1:]
    r, m = model.radius, model.kernel // 2
    out = np.empty((3, h, w), dtype=np.float32)
    for ty in range(0, h, tile):
        for tx in range(0, w, tile):
            y1, x1 = min(ty + tile, h), min(tx + tile, w)
            hy0, hx0 = max(ty - r, 0), max(tx - r, 0)
            hy1, hx1 = min(y1 + r, h), min(x1 + r, w)
            win = window(planes, hy0, hy1, hx0, hx1, m)
            kd, ks = model.kernels(win["features"])
            kd = kd[:, :, ty - hy0:y1 - hy0, tx - hx0:x1 - hx0]
            ks = ks[:, :, ty - hy0:y1 - hy0, tx - hx0:x1 - hx0]
            src = window(planes, ty, y1, tx, x1, m)
            d = apply_kernel(src["diffuse_src"], kd, model.kernel)
            s = apply_kernel(src["specular_src"], ks, model.kernel)
            res = src["albedo_eps"] * d + s + src["emission"]
            out[:, ty:y1, tx:x1] = res[0].numpy()
    return np.ascontiguousarray(np.transpose(out, (1, 2, 0)))


def load(path):
    """Loads weights written by scripts/train_kpcn: {"config": ..., "state": state_dict}."""
    blob = torch.load(path, map_location="cpu")
    cfg = blob["config"]
    model = Kpcn(cfg["channels"], cfg["kernel"], tuple(cfg["dilations"]))
    model.load_state_dict(blob["state"])
    model.eval()
    return model


def parameter_count(model):
    return int(sum(p.numel() for p in model.parameters()))
