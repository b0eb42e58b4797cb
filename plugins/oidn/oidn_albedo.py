"""The albedo the `oidn` plug-in gives OIDN with `albedo = "oidn"`: OIDN's documented
convention, made from the tracer's layers (the default, `albedo = "tracer"`, passes T as
stored: measured the stronger row, docs/method-defaults.md, "oidn"). Its own module so that
python/oidn_direct.py (the check that the plug-in's row is OIDN itself) feeds OIDN's own API the
same buffers."""
import numpy as np


def oidn_albedo(frame):
    """The albedo as OIDN's documentation describes it, from the tracer's layers (`frame` maps
    layer names to H x W x 3 arrays: "albedo", and "emission", "refl1.albedo" and "refl1.tint"
    where the frame has them). T, the reflectance of the first diffuse hit, is kept where it is
    non-zero. Where it is 0:
      - a smooth mirror or pane with a reflection level behind it: OIDN's albedo of what is seen
        in or through a perfect specular surface, the level's albedo times its bounce weight
        (refl1.tint * refl1.albedo, the Fresnel weight included);
      - an emitter (E > 0): 1, as OIDN's albedo of a surface that only emits;
      - elsewhere (rough metal and rough glass, with no level behind): 0, as the tracer writes it.
        OIDN's alternatives there were measured worse on hard.toml's still-life (8-bit mse
        against 0: 1 on rough glass +24%, 1 on rough glass and metal +49%, over three seeds;
        the lobe's colour gloss_color + trans_color +36%, seed 1; docs/method-defaults.md,
        "oidn")."""
    t = np.array(frame["albedo"], dtype=np.float32)
    missing = np.all(t <= 0.0, axis=2)
    if "refl1.albedo" in frame and "refl1.tint" in frame:
        behind = np.clip(np.asarray(frame["refl1.tint"], np.float32) * np.asarray(frame["refl1.albedo"], np.float32), 0, 1)
        seen = missing & np.any(behind > 0.0, axis=2)
        t[seen] = behind[seen]
        missing &= ~seen
    if "emission" in frame:
        t[missing & np.any(np.asarray(frame["emission"]) > 0.0, axis=2)] = 1.0
    return np.ascontiguousarray(t)
