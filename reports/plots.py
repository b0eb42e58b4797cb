#!/usr/bin/python3
"""Plots of a denoisebench results folder, from results.json only (run by `denoisebench report`).

  plots/mse_bars.png            MSE (8-bit sRGB, Table 1's metric) per scene and method
  plots/error_time_<scene>.png  error vs time, log-log: plain path tracing's renders and fitted
                                power law, and every method at its total time (input + filter)

Usage: /usr/bin/python3 reports/plots.py RESULTS_DIR [METRIC]
"""
import json
import math
import os
import re
import sys

import matplotlib

matplotlib.use("Agg")  # files only, no display
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def safe(name):
    return re.sub(r"[^A-Za-z0-9_.-]", "_", name)


def main():
    if len(sys.argv) < 2:
        sys.exit("usage: plots.py RESULTS_DIR [METRIC]")
    out_dir = sys.argv[1]
    metric = sys.argv[2] if len(sys.argv) > 2 else "mse"
    with open(os.path.join(out_dir, "results.json")) as f:
        res = json.load(f)
    records = res["records"]
    cfg = res.get("config", {})
    scenes = cfg.get("scenes") or sorted({r["scene"] for r in records})
    spp = (cfg.get("spp") or [r["spp"] for r in records if r.get("role") != "plain"])[0]
    methods = []
    for r in records:
        if r.get("role") in ("method", "ablation") and r["method"] not in methods:
            methods.append(r["method"])
    plots = os.path.join(out_dir, "plots")
    os.makedirs(plots, exist_ok=True)

    def value(scene, method):
        for r in records:
            if r["scene"] == scene and r["method"] == method and r["spp"] == spp:
                v = r["metrics"].get(metric)
                return v if v is not None else math.nan
        return math.nan

    # Bars: scenes on the x axis, one bar per method (input included for scale).
    cols = ["input"] + methods
    fig, ax = plt.subplots(figsize=(max(6, 1.2 * len(scenes) * len(cols) / 3), 4))
    width = 0.8 / len(cols)
    x = np.arange(len(scenes))
    for i, m in enumerate(cols):
        ax.bar(x + (i - (len(cols) - 1) / 2) * width, [value(s, m) for s in scenes], width, label=m)
    ax.set_xticks(x)
    ax.set_xticklabels(scenes)
    ax.set_ylabel(metric)
    ax.set_title(f"{metric} per scene and method, {spp} spp input")
    ax.legend(fontsize="small", ncol=2)
    fig.tight_layout()
    fig.savefig(os.path.join(plots, f"{metric}_bars.png"), dpi=100)
    plt.close(fig)

    for s in scenes:
        plain = sorted((r["times"]["total"], r["metrics"][metric], r["spp"]) for r in records
                       if r["scene"] == s and r.get("role") == "plain" and r["metrics"].get(metric) is not None)
        fig, ax = plt.subplots(figsize=(6.4, 4.6))
        if plain:
            t = np.array([p[0] for p in plain])
            e = np.array([p[1] for p in plain])
            ax.plot(t, e, "o-", color="black", label="plain path tracing")
            for ti, ei, si in plain:
                ax.annotate(f"{si}", (ti, ei), textcoords="offset points", xytext=(4, 4), fontsize=7)
            ok = (t > 0) & (e > 0)
            if ok.sum() >= 2:
                slope, icpt = np.polyfit(np.log(t[ok]), np.log(e[ok]), 1)
                tt = np.geomspace(t[ok].min() / 4, t[ok].max() * 16, 50)
                ax.plot(tt, np.exp(icpt) * tt ** slope, "--", color="gray",
                        label=f"fit: {metric} = {math.exp(icpt):.3g} t^{slope:.2f}")
        for r in records:
            if r["scene"] == s and r["spp"] == spp and r.get("role") in ("method", "ablation", "input"):
                v = r["metrics"].get(metric)
                if v is not None and r["times"]["total"] > 0:
                    ax.plot(r["times"]["total"], v, "s", label=f'{r["method"]} ({spp} spp)')
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("time, seconds (input render + filter)")
        ax.set_ylabel(metric)
        ax.set_title(f"{s}: error vs time")
        ax.legend(fontsize="x-small")
        ax.grid(True, which="both", alpha=0.3)
        fig.tight_layout()
        fig.savefig(os.path.join(plots, f"error_time_{safe(s)}.png"), dpi=100)
        plt.close(fig)


if __name__ == "__main__":
    main()
