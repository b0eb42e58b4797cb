"""One colour and one marker per method, the same in every plot and page of every run.

Read by reports/plots.py (matplotlib) and reports/viewer.py (the page's labels). A method's
style depends on its name only, never on the order of a run's records, so a method looks the
same across runs, plots and pages.

The colours are the Okabe-Ito set and Paul Tol's "muted" set, both made to stay distinct under
the common colour-vision deficiencies; neither has 15 colours, so every method also has its own
marker, and series stay apart in grey print too. An ablation variant (or any config variant of
a method) takes its parent's colour, a dashed line and a hollow marker of its own.
"""
import hashlib

# The registry's methods and the harness's own columns, fixed.
KNOWN = {
    "path_tracing": ("#000000", "o"),
    "input": ("#888888", "x"),
    "reference": ("#000000", "*"),
    "proposed": ("#D55E00", "o"),        # Okabe-Ito vermillion
    "am": ("#0072B2", "s"),              # Okabe-Ito blue
    "am_opencv": ("#56B4E9", "D"),       # Okabe-Ito sky blue
    "bilateral": ("#009E73", "^"),       # Okabe-Ito bluish green
    "irradiance_cache": ("#E69F00", "v"),  # Okabe-Ito orange
    "atrous": ("#CC79A7", "<"),          # Okabe-Ito reddish purple
    "guided": ("#882255", ">"),          # Tol muted wine
    "nlmeans": ("#332288", "p"),         # Tol muted indigo
    "svgf": ("#DDCC77", "h"),            # Tol muted sand
    "nfor": ("#AA4499", "P"),            # Tol muted purple
    "oidn": ("#999933", "X"),            # Tol muted olive
    "kpcn": ("#CC6677", "d"),            # Tol muted rose
    "svgf_temporal": ("#8C6D1F", "H"),   # a darker sand than svgf's: its temporal sibling
    "temporal_accumulation": ("#117733", "8"),  # Tol muted green
}
# For methods the table does not know (plug-ins): by a hash of the name.
SPARE_COLOURS = ["#44AA99", "#117733", "#88CCEE", "#F0E442", "#661100", "#6699CC"]
MARKERS = ["o", "s", "D", "^", "v", "<", ">", "p", "h", "P", "X", "d", "*", "H", "8"]
DASHES = [(0, (5, 2)), (0, (2, 2)), (0, (6, 2, 1, 2)), (0, (8, 3)), (0, (3, 1, 1, 1, 1, 1))]


def _hash(name):
    return int(hashlib.sha256(name.encode()).hexdigest()[:8], 16)


def style(method, parent=None):
    """{"colour", "marker", "linestyle", "filled", "parent"} of a method column.

    `parent` is the record's base_method: a column whose name differs from it is a variant.
    """
    if method in KNOWN:
        c, m = KNOWN[method]
        return {"colour": c, "marker": m, "linestyle": "-", "filled": True, "parent": method}
    if parent and parent != method:
        base = style(parent)
        h = _hash(method)
        return {"colour": base["colour"], "marker": MARKERS[h % len(MARKERS)], "linestyle": DASHES[h % len(DASHES)],
                "filled": False, "parent": parent}
    h = _hash(method)
    return {"colour": SPARE_COLOURS[h % len(SPARE_COLOURS)], "marker": MARKERS[h % len(MARKERS)], "linestyle": "-",
            "filled": True, "parent": method}


def parents(records):
    """method column -> base_method, from a results document's records."""
    out = {}
    for r in records:
        out.setdefault(r["method"], r.get("base_method") or r["method"])
    return out
