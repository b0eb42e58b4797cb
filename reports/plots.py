#!/usr/bin/python3
"""Plots of a denoisebench results folder, from results.json only (run by `denoisebench report`).

Every plot is written as PNG (300 dpi) and PDF (vector), every method in one colour and marker
in every plot and page (reports/method_style.py: ablation variants in their parent's colour,
dashed, hollow markers), legends outside the data:

  plots/<metric>_bars.*               the metric per scene and method (Table 1), with the 95%
                                      t-interval over the input seeds where there are several
  plots/error_spp_<scene>.*           the metric against spp: plain path tracing's renders, the
                                      input and every method at each input spp, with intervals
  plots/error_filter_time_<scene>.*   the metric against each method's filter time alone (the
                                      input's render time marked apart, as a line)
  plots/error_time_<scene>.*          the metric against total time (input render + filter),
                                      with plain path tracing's renders and fitted power law
  plots/sequence_<seq>_<spp>spp_mse.*  per animated sequence (results.json's `sequences`) and
  plots/sequence_<seq>_<spp>spp_tmse.* input spp: each column's per-frame mse / tmse (the mean over
                                      the seeds) against the frame index
  plots/colours.json                  each plot's series and the colour matplotlib drew them in
                                      (for the test that a method keeps its colour)

Log scales where the values span more than a decade.

Usage: /usr/bin/python3 reports/plots.py RESULTS_DIR [METRIC]
"""
import json
import math
import os
import re
import sys

import matplotlib

matplotlib.use("Agg")  # files only, no display
import matplotlib.colors as mcolors  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.ticker  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import method_style  # noqa: E402

DPI = 300
T975 = [12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160, 2.145, 2.131,
        2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056, 2.052, 2.048, 2.045, 2.042]


def safe(name):
    return re.sub(r"[^A-Za-z0-9_.-]", "_", name)


def mean_ci(values):
    """Mean and the half width of its 95% Student t-interval (0 with one value), as Table 1."""
    v = [x for x in values if x is not None and math.isfinite(x)]
    if not v:
        return math.nan, 0.0
    m = sum(v) / len(v)
    if len(v) < 2:
        return m, 0.0
    sd = math.sqrt(sum((x - m) ** 2 for x in v) / (len(v) - 1))
    t = T975[len(v) - 2] if len(v) - 2 < len(T975) else 1.96
    return m, t * sd / math.sqrt(len(v))


def spans_decades(values):
    v = [x for x in values if x is not None and math.isfinite(x) and x > 0]
    return len(v) >= 2 and max(v) / min(v) > 10


class Plots:
    def __init__(self, out_dir):
        self.dir = os.path.join(out_dir, "plots")
        os.makedirs(self.dir, exist_ok=True)
        self.colours = {}

    def save(self, fig, ax, stem, series):
        """Legend outside the axes on the right; PNG and PDF; the series' drawn colours kept."""
        if ax.get_legend_handles_labels()[0]:
            ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small", frameon=False, borderaxespad=0)
        fig.tight_layout()
        for ext in ("png", "pdf"):
            fig.savefig(os.path.join(self.dir, f"{stem}.{ext}"), dpi=DPI, bbox_inches="tight")
        plt.close(fig)
        self.colours[stem] = {label: mcolors.to_hex(c) for label, c in series.items()}

    def finish(self):
        with open(os.path.join(self.dir, "colours.json"), "w") as f:
            json.dump(self.colours, f, indent=1, sort_keys=True)


def sequence_plots(res, plots, style):
    """Per (sequence, spp): each column's per-frame mse and tmse, the mean over its seeds.

    From results.json's `sequences` only (experiment/results.h SequenceRecord: `per_frame` holds
    one value per frame, null where a frame has none, as frame 0's tmse); a frame where no seed
    has a value is left out of the line rather than drawn as 0.
    """
    seqs = res.get("sequences") or []
    order = {"input": 0, "method": 1, "ablation": 2}
    for name in dict.fromkeys(r["sequence"] for r in seqs):
        for spp in sorted({r["spp"] for r in seqs if r["sequence"] == name}):
            rs = [r for r in seqs if r["sequence"] == name and r["spp"] == spp]
            columns = sorted(dict.fromkeys(r["method"] for r in rs),
                             key=lambda m: min(order.get(r.get("role"), 3) for r in rs if r["method"] == m))
            frames = max(r.get("frames") or 0 for r in rs)
            nseeds = len({r.get("seed") for r in rs})
            for metric, what in (("mse", "mse per frame"),
                                 ("tmse", "tmse per frame (flicker beyond the reference's change)")):
                fig, ax = plt.subplots(figsize=(7.0, 4.4))
                series, ys = {}, []
                for m in columns:
                    per_seed = [r.get("per_frame", {}).get(metric) or [] for r in rs if r["method"] == m]
                    xs, vs = [], []
                    for t in range(frames):
                        v = [p[t] for p in per_seed if t < len(p) and p[t] is not None and math.isfinite(p[t])]
                        if v:
                            xs.append(t)
                            vs.append(sum(v) / len(v))
                    if not xs:
                        continue
                    st = style.get(m) or method_style.style(m)
                    line = ax.plot(xs, vs, color=st["colour"], marker=st["marker"], linestyle=st["linestyle"],
                                   markersize=5, markerfacecolor=st["colour"] if st["filled"] else "white",
                                   markeredgecolor=st["colour"], label=m if m != "input" else f"input ({spp} spp)")
                    series[m] = line[0].get_color()
                    ys += vs
                if spans_decades(ys):
                    ax.set_yscale("log")
                ax.set_xlabel("frame")
                ax.set_ylabel(metric)
                ax.set_xlim(-0.5, frames - 0.5)
                ax.xaxis.set_major_locator(matplotlib.ticker.MaxNLocator(integer=True))
                ax.set_title(f"{name}: {what}, {spp} spp input" + (f" (mean over {nseeds} seeds)" if nseeds > 1 else ""))
                ax.grid(True, alpha=0.3)
                plots.save(fig, ax, f"sequence_{safe(name)}_{spp}spp_{metric}", series)


def main():
    if len(sys.argv) < 2:
        sys.exit("usage: plots.py RESULTS_DIR [METRIC]")
    out_dir = sys.argv[1]
    metric = sys.argv[2] if len(sys.argv) > 2 else "mse"
    with open(os.path.join(out_dir, "results.json")) as f:
        res = json.load(f)
    records = res["records"]
    cfg = res.get("config", {})
    scenes = cfg.get("scenes") or list(dict.fromkeys(r["scene"] for r in records))
    # A sequence's frames are plotted per frame by sequence_plots, not as stills (16 frames would
    # be 16 still plots each).
    frame_rows = {f"{name}.f{t:02d}" for name, n in (cfg.get("sequences") or {}).items() for t in range(n)}
    scenes = [s for s in scenes if s not in frame_rows]
    spp = (cfg.get("spp") or [r["spp"] for r in records if r.get("role") != "plain"])[0]
    methods = []
    for r in records:
        if r.get("role") in ("method", "ablation") and r["method"] not in methods:
            methods.append(r["method"])
    parents = method_style.parents(records)
    style = {m: method_style.style(m, parents.get(m)) for m in ["input", "path_tracing"] + methods}
    plots = Plots(out_dir)

    def seeds_of(scene, method, at_spp):
        return [r for r in records if r["scene"] == scene and r["method"] == method and r["spp"] == at_spp]

    def metric_of(r):
        v = r["metrics"].get(metric)
        return v if v is not None else math.nan

    def errorbar(ax, x, y, yerr, m, label, line=True, **kw):
        st = style[m]
        c = ax.errorbar(x, y, yerr=yerr if any(e > 0 for e in yerr) else None, color=st["colour"], marker=st["marker"],
                        linestyle=st["linestyle"] if line else "none", markersize=6,
                        markerfacecolor=st["colour"] if st["filled"] else "white", markeredgecolor=st["colour"],
                        capsize=3, label=label, **kw)
        return c[0].get_color()

    if scenes:  # a config of sequences only has no still scene
        # Bars: scenes on the x axis, one bar per method (input included for scale).
        cols = ["input"] + methods
        fig, ax = plt.subplots(figsize=(max(7.0, 1.2 + 0.25 * len(cols) * len(scenes)), 4.2))
        width = 0.8 / len(cols)
        x = np.arange(len(scenes))
        series, allv = {}, []
        for i, m in enumerate(cols):
            mc = [mean_ci([metric_of(r) for r in seeds_of(s, m, spp)]) for s in scenes]
            st = style[m]
            bars = ax.bar(x + (i - (len(cols) - 1) / 2) * width, [v for v, _ in mc], width,
                          yerr=[e for _, e in mc] if any(e > 0 for _, e in mc) else None, capsize=2,
                          color=st["colour"] if st["filled"] else "white", edgecolor=st["colour"],
                          hatch=None if st["filled"] else "////", linewidth=1.0, label=m)
            series[m] = bars.patches[0].get_edgecolor()
            allv += [v for v, _ in mc]
        ax.set_xticks(x)
        ax.set_xticklabels(scenes)
        ax.set_ylabel(metric)
        if spans_decades(allv):
            ax.set_yscale("log")
        ax.set_title(f"{metric} per scene and method, {spp} spp input")
        plots.save(fig, ax, f"{metric}_bars", series)

    for s in scenes:
        # Error against spp: every method at every input spp it has, with intervals over the seeds.
        fig, ax = plt.subplots(figsize=(7.0, 4.4))
        series, xs, ys = {}, [], []
        plain = {}
        for r in records:
            if r["scene"] == s and r.get("role") == "plain":
                plain.setdefault(r["spp"], []).append(metric_of(r))
        if plain:
            px = sorted(plain)
            mc = [mean_ci(plain[p]) for p in px]
            series["path_tracing"] = errorbar(ax, px, [v for v, _ in mc], [e for _, e in mc], "path_tracing",
                                              "plain path tracing")
            xs += px
            ys += [v for v, _ in mc]
        shown = ["input"] + methods
        for k, m in enumerate(shown):
            at = sorted({r["spp"] for r in records if r["scene"] == s and r["method"] == m})
            if not at:
                continue
            mc = [mean_ci([metric_of(r) for r in seeds_of(s, m, p)]) for p in at]
            # Methods at one spp side by side (a few percent apart on the log axis), so that their
            # intervals do not hide one another; the tick is the spp.
            dodge = 2 ** (0.04 * (k - (len(shown) - 1) / 2))
            series[m] = errorbar(ax, [p * dodge for p in at], [v for v, _ in mc], [e for _, e in mc], m, m)
            xs += at
            ys += [v for v, _ in mc]
        ax.set_xscale("log", base=2)
        if spans_decades(ys):
            ax.set_yscale("log")
        ax.set_xlabel("samples per pixel")
        ax.set_ylabel(metric)
        nseeds = len(cfg.get("seeds") or [1])
        ax.set_title(f"{s}: {metric} against spp" + (f" (mean, 95% interval over {nseeds} seeds)" if nseeds > 1 else ""))
        ax.grid(True, which="both", alpha=0.3)
        plots.save(fig, ax, f"error_spp_{safe(s)}", series)

        # Error against filter time alone; the input's render time as a line of its own.
        fig, ax = plt.subplots(figsize=(7.0, 4.4))
        series, ts = {}, []
        for m in methods:
            rs = seeds_of(s, m, spp)
            if not rs:
                continue
            t = float(np.median([r["times"]["filter"] for r in rs]))
            v, e = mean_ci([metric_of(r) for r in rs])
            if t <= 0 or not math.isfinite(v):
                continue
            series[m] = errorbar(ax, [t], [v], [e], m, m, line=False)
            ts.append(t)
        inp = seeds_of(s, "input", spp)
        if inp:
            tr = float(np.median([r["times"]["input_render"] for r in inp]))
            if tr > 0:
                ax.axvline(tr, color=style["input"]["colour"], linestyle=":", linewidth=1.2,
                           label=f"input render time ({spp} spp): {tr:.3g} s")
                ts.append(tr)
        if spans_decades(ts):
            ax.set_xscale("log")
        if spans_decades(list(ax.get_ylim())) or spans_decades([l.get_ydata()[0] for l in ax.get_lines() if len(l.get_ydata())]):
            ax.set_yscale("log")
        ax.set_xlabel("filter time, s (median over the seeds; render not included)")
        ax.set_ylabel(metric)
        ax.set_title(f"{s}: {metric} against filter time, {spp} spp input")
        ax.grid(True, which="both", alpha=0.3)
        plots.save(fig, ax, f"error_filter_time_{safe(s)}", series)

        # Error against total time, with plain path tracing's renders and their fitted power law.
        plain = sorted((r["times"]["total"], metric_of(r), r["spp"]) for r in records
                       if r["scene"] == s and r.get("role") == "plain" and r["metrics"].get(metric) is not None)
        fig, ax = plt.subplots(figsize=(7.0, 4.4))
        series = {}
        if plain:
            t = np.array([p[0] for p in plain])
            e = np.array([p[1] for p in plain])
            series["path_tracing"] = errorbar(ax, t, e, [0] * len(t), "path_tracing", "plain path tracing")
            for ti, ei, si in plain:
                ax.annotate(f"{si}", (ti, ei), textcoords="offset points", xytext=(4, 4), fontsize=7)
            ok = (t > 0) & (e > 0)
            if ok.sum() >= 2:
                slope, icpt = np.polyfit(np.log(t[ok]), np.log(e[ok]), 1)
                tt = np.geomspace(t[ok].min() / 4, t[ok].max() * 16, 50)
                ax.plot(tt, np.exp(icpt) * tt ** slope, "--", color="gray", linewidth=1,
                        label=f"fit: {metric} = {math.exp(icpt):.3g} t^{slope:.2f}")
        for m in ["input"] + methods:
            rs = seeds_of(s, m, spp)
            if not rs:
                continue
            t = float(np.median([r["times"]["total"] for r in rs]))
            v, e = mean_ci([metric_of(r) for r in rs])
            if t > 0 and math.isfinite(v):
                series[m] = errorbar(ax, [t], [v], [e], m, f"{m} ({spp} spp)", line=False)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("time, seconds (input render + filter)")
        ax.set_ylabel(metric)
        ax.set_title(f"{s}: {metric} against total time")
        ax.grid(True, which="both", alpha=0.3)
        plots.save(fig, ax, f"error_time_{safe(s)}", series)
    for r in res.get("sequences") or []:
        m = r["method"]
        if m not in style:
            style[m] = method_style.style(m, parents.get(m))
    sequence_plots(res, plots, style)
    plots.finish()


if __name__ == "__main__":
    main()
