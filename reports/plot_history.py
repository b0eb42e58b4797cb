#!/usr/bin/python3
"""Plots of the nightly history (reports/history.csv, one row per nightly run; written by
`denoisebench nightly check --history`): quality and speed over time.

  OUT_DIR/history_mse.png    MSE per scene (one panel each), one line per method
  OUT_DIR/history_speed.png  time ratio (method / reference workload) per benchmark case
                             (one panel per thread setting), one line per method

A value that failed its gate in that run (the history's failed_checks: quality or ahead for
an MSE, performance for a ratio) is marked with a red ring. Rows are ordered by date; the x
axis is the run's date.

Usage: /usr/bin/python3 reports/plot_history.py HISTORY.csv OUT_DIR
"""
import csv
import datetime
import os
import sys

import matplotlib

matplotlib.use("Agg")  # files only, no display
import matplotlib.dates as mdates  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import matplotlib.ticker  # noqa: E402


def parse_date(text):
    return datetime.datetime.strptime(text, "%Y-%m-%dT%H:%M:%SZ")


def number(text):
    try:
        return float(text)
    except ValueError:
        return None


def failed(row, column):
    """Whether `column`'s value failed its gate in this run (from the row's failed_checks:
    "quality SCENE METHOD", "ahead SCENE METHOD", "performance CASE (frame ...) METHOD")."""
    checks = [c.strip() for c in row.get("failed_checks", "").split(";") if c.strip()]
    parts = column.split("/")
    if parts[0] == "mse" and len(parts) == 3:
        scene, method = parts[1], parts[2]
        return any(c in (f"quality {scene} {method}", f"ahead {scene} {method}") for c in checks)
    if parts[0] == "ratio":
        case = column[len("ratio/"):]
        return any(c.startswith(f"performance {case} ") for c in checks)
    return False


def series(rows, column):
    """(dates, values, failed) of the rows that have a value in `column`."""
    xs, ys, bad = [], [], []
    for r in rows:
        v = number(r.get(column, ""))
        if v is None:
            continue
        xs.append(r["_date"])
        ys.append(v)
        bad.append(failed(r, column))
    return xs, ys, bad


def panel(ax, rows, columns, label_of, title, ylabel, log):
    ax.set_prop_cycle(color=plt.cm.tab20.colors)  # up to 20 methods without a repeated colour
    values = []
    for col in columns:
        xs, ys, bad = series(rows, col)
        if not xs:
            continue
        values += ys
        (line,) = ax.plot(xs, ys, marker="o", markersize=3, label=label_of(col))
        fx = [x for x, b in zip(xs, bad) if b]
        fy = [y for y, b in zip(ys, bad) if b]
        if fx:
            ax.scatter(fx, fy, s=60, facecolors="none", edgecolors="red", linewidths=1.2, zorder=3)
    ax.set_title(title, fontsize=10)
    ax.set_ylabel(ylabel)
    if log:
        ax.set_yscale("log")
        ax.yaxis.set_major_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
        # Label minor ticks only when the values span less than a decade (else they collide).
        narrow = values and min(values) > 0 and max(values) < 10 * min(values)
        minor = matplotlib.ticker.FormatStrFormatter("%g") if narrow else matplotlib.ticker.NullFormatter()
        ax.yaxis.set_minor_formatter(minor)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
    locator = mdates.AutoDateLocator()
    ax.xaxis.set_major_locator(locator)
    ax.xaxis.set_major_formatter(mdates.ConciseDateFormatter(locator))
    dates = [r["_date"] for r in rows]
    if dates and max(dates) - min(dates) < datetime.timedelta(days=1):
        # A few runs on one day: show that day, not years around it.
        ax.set_xlim(min(dates) - datetime.timedelta(hours=6), max(dates) + datetime.timedelta(hours=6))


def figure(groups, rows, label_of, ylabel, log, path, suptitle):
    n = len(groups)
    cols = 2 if n > 1 else 1
    nrows = (n + cols - 1) // cols
    fig, axes = plt.subplots(nrows, cols, figsize=(8.5 * cols, 3.6 * nrows), squeeze=False)
    for ax, (title, columns) in zip(axes.flat, groups):
        panel(ax, rows, columns, label_of, title, ylabel, log)
    for ax in list(axes.flat)[n:]:
        ax.axis("off")
    fig.suptitle(suptitle)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: plot_history.py HISTORY.csv OUT_DIR")
    path, out_dir = sys.argv[1], sys.argv[2]
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        header = reader.fieldnames or []
        rows = list(reader)
    for col in ("date", "verdict"):
        if col not in header:
            sys.exit(f"{path}: line 1: no column '{col}' (not a nightly history)")
    for i, r in enumerate(rows, start=2):
        try:
            r["_date"] = parse_date(r["date"])
        except ValueError:
            sys.exit(f"{path}: line {i}: date '{r['date']}' is not YYYY-MM-DDTHH:MM:SSZ")
    rows.sort(key=lambda r: r["_date"])
    os.makedirs(out_dir, exist_ok=True)
    written = []

    # mse/<scene>/<method>
    scenes = {}
    for col in header:
        parts = col.split("/")
        if parts[0] == "mse" and len(parts) == 3:
            scenes.setdefault(parts[1], []).append(col)
    if scenes:
        out = os.path.join(out_dir, "history_mse.png")
        figure(sorted(scenes.items()), rows, lambda c: c.split("/")[2], "MSE (8-bit)", True, out,
               "Nightly quality: MSE per scene and method (red ring: failed its gate)")
        written.append(out)

    # ratio/nightly/<method>/<size>/threads:<n>
    speed = {}
    for col in header:
        if col.startswith("ratio/"):
            parts = col.split("/")
            key = "/".join(parts[3:]) if len(parts) > 3 else col
            speed.setdefault(key, []).append(col)
    if speed:
        out = os.path.join(out_dir, "history_speed.png")
        figure(sorted(speed.items()), rows, lambda c: c.split("/")[2], "time / reference workload", True, out,
               "Nightly speed: method time over the reference workload (red ring: failed its gate)")
        written.append(out)

    if not written:
        sys.exit(f"{path}: no mse/ or ratio/ columns to plot")
    for w in written:
        print(w)


if __name__ == "__main__":
    main()
