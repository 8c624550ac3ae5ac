#!/usr/bin/env python3
"""Tables and plots of a tools/scaling.sh run.

Usage: tools/plot_scaling.py --dir out/scaling [--plots docs/images]

Reads DIR/manifest.tsv (run name, series, commands) and DIR/json/NAME.json
(prt-precompute --summary-json) + DIR/json/NAME.relight.json
(prt-bench-relight-file --json), and for the point lights DIR/pointlights.tsv with
DIR/json/NAME.tsis.json (prt-bench-tsis --json) and DIR/logs/NAME.cache.log
(prt-pointlight --method cache --compare-jb); writes DIR/scaling.csv (one row per run, every
field), DIR/tables.md (one table per series, fitted slopes) and, when matplotlib is
installed (tools/setup.sh --plots), PLOTS/scaling_*.png: log-log plots with the
least-squares slope of log y against log x in the legend (slope 1: linear growth;
slightly above 1 over a decade or so: n log n; 0: independent of x).
"""

import argparse
import csv
import json
import math
import os
import sys

from pointlight_log import parse_cache_log
from repeats import aggregate, number

# Each series: what is on the x axis and which metrics to plot and tabulate.
# A metric: (key, label, unit, panel, fit) with fit "loglog" (slope) or "doubling"
# (increase per doubling of x, for logarithmic growth).
SERIES = {
    "ms_mesh": {
        "title": "Multiple scattering vs mesh size (30 mm Marble, 6x32x32, 128 coefficients)",
        "x": "vertices", "xlabel": "vertices",
        "metrics": [
            ("pass1_seconds", "pass 1", "s", "precompute time [s]", "loglog"),
            ("pass2_seconds", "pass 2", "s", "precompute time [s]", "loglog"),
            ("total_seconds", "total", "s", "precompute time [s]", "loglog"),
            ("relight_ms_median", "relight kernel", "ms", "per frame [ms] / size [MB]", "loglog"),
            ("relight_cold_ms_median", "relight kernel, cold", "ms", "per frame [ms] / size [MB]", "loglog"),
            ("file_MB", "file", "MB", "per frame [ms] / size [MB]", "loglog"),
            ("peak_MB", "peak memory", "MB", "per frame [ms] / size [MB]", "loglog"),
        ],
    },
    "ms_samples": {
        "title": "Multiple scattering vs sample count",
        "x": "samples", "xlabel": "samples",
        "metrics": [
            ("pass1_seconds", "pass 1", "s", "precompute time [s]", "loglog"),
            ("pass2_seconds", "pass 2", "s", "precompute time [s]", "loglog"),
            ("mean_nodes_visited", "kd-tree nodes visited per vertex", "", "nodes visited per vertex", "doubling"),
        ],
    },
    "ms_cubemap": {
        "title": "Multiple scattering vs cubemap size N (6 x N x N)",
        "x": "cubemap_size", "xlabel": "cubemap face size N",
        "metrics": [
            ("pass1_seconds", "pass 1", "s", "precompute time [s]", "loglog"),
            ("pass2_seconds", "pass 2", "s", "precompute time [s]", "loglog"),
            ("relight_ms_median", "relight kernel", "ms", "per frame [ms]", "loglog"),
            ("relight_cold_ms_median", "relight kernel, cold", "ms", "per frame [ms]", "loglog"),
            ("light_ms_median", "light vector", "ms", "per frame [ms]", "loglog"),
        ],
    },
    "ms_coefficients": {
        "title": "Multiple scattering vs coefficients kept per vertex",
        "x": "coefficients", "xlabel": "coefficients per vertex",
        "metrics": [
            ("pass2_seconds", "pass 2", "s", "precompute time [s]", "loglog"),
            ("relight_ms_median", "relight kernel", "ms", "per frame [ms] / size [MB]", "loglog"),
            ("relight_cold_ms_median", "relight kernel, cold", "ms", "per frame [ms] / size [MB]", "loglog"),
            ("file_MB", "file", "MB", "per frame [ms] / size [MB]", "loglog"),
        ],
    },
    "ss_mesh": {
        "title": "Isotropic single scattering vs mesh size (--components ss, at sites)",
        "x": "vertices", "xlabel": "vertices",
        "metrics": [
            ("ss_seconds", "single scattering", "s", "precompute time [s]", "loglog"),
            ("ss_sites", "sites", "", "sites", "loglog"),
            ("relight_ms_median", "relight kernel", "ms", "per frame [ms] / size [MB]", "loglog"),
            ("relight_cold_ms_median", "relight kernel, cold", "ms", "per frame [ms] / size [MB]", "loglog"),
            ("file_MB", "file", "MB", "per frame [ms] / size [MB]", "loglog"),
        ],
    },
    "ss_path_samples": {
        "title": "Isotropic single scattering vs path samples",
        "x": "path_samples", "xlabel": "path samples along -n",
        "metrics": [
            ("ss_seconds", "single scattering", "s", "precompute time [s]", "loglog"),
            ("ss_rays_per_vertex", "rays per vertex", "", "rays per vertex", "loglog"),
        ],
    },
}
# Extra columns of every table.
TABLE_COLUMNS = [
    ("vertices", "vertices", "{:,.0f}"),
    ("samples", "samples", "{:,.0f}"),
    ("pass1_seconds", "pass 1 s", "{:.3g}"),
    ("pass2_seconds", "pass 2 s", "{:.3g}"),
    ("pass2_us_per_vertex", "pass 2 us/vertex", "{:.3g}"),
    ("mean_nodes_visited", "nodes/vertex", "{:,.0f}"),
    ("ss_seconds", "SS s", "{:.3g}"),
    ("ss_ms_per_vertex", "SS ms/vertex", "{:.3g}"),
    ("ss_sites", "SS sites", "{:,.0f}"),
    ("ss_ms_per_site", "SS ms/site", "{:.3g}"),
    ("total_seconds", "total s", "{:.3g}"),
    ("file_MB", "file MB", "{:.3g}"),
    ("file_bytes_per_vertex", "bytes/vertex", "{:,.0f}"),
    ("peak_MB", "peak MB", "{:,.0f}"),
    ("relight_ms_median", "relight ms", "{:.3g}"),
    ("relight_cold_ms_median", "relight cold ms", "{:.3g}"),
    ("light_ms_median", "light ms", "{:.3g}"),
    ("load_average_1min", "load avg", "{:.2g}"),
]


def flatten(run):
    """One flat dict per run: summary fields, settings, machine, relight (prefixed)."""
    row = {"name": run["name"], "series": " ".join(run["series"])}
    pre = run.get("precompute") or {}
    for k, v in (pre.get("summary") or {}).items():
        row[k] = v
    for k, v in (pre.get("settings") or {}).items():
        if k in ("sigma_s_prime", "sigma_a"):
            v = ",".join(f"{x:g}" for x in v)
        row.setdefault(k, v)
    machine = pre.get("machine") or {}
    row["threads"] = machine.get("threads")
    la = machine.get("load_average_start")
    row["load_average_1min"] = la[0] if la else None
    lae = machine.get("load_average_end")
    row["load_average_end_1min"] = lae[0] if lae else None
    for k, v in (run.get("relight") or {}).items():
        if k in ("tool", "file"):
            continue
        key = k if k.startswith(("relight_", "light_")) else "relight_" + k
        row[key] = v
    # Derived.
    def get(k):
        v = row.get(k)
        return v if isinstance(v, (int, float)) and not isinstance(v, bool) else None
    row["file_MB"] = get("file_bytes") / 1e6 if get("file_bytes") is not None else None
    row["peak_MB"] = get("peak_memory_bytes") / 1e6 if get("peak_memory_bytes") is not None else None
    row["pass2_us_per_vertex"] = 1e6 * get("pass2_seconds_per_vertex") if get("pass2_seconds_per_vertex") else None
    row["ss_ms_per_vertex"] = 1e3 * get("ss_seconds_per_vertex") if get("ss_seconds_per_vertex") else None
    row["ss_ms_per_site"] = 1e3 * get("ss_seconds") / get("ss_sites") if get("ss_seconds") and get("ss_sites") else None
    row["relight_stream_MB"] = get("relight_stream_bytes") / 1e6 if get("relight_stream_bytes") else None
    row["precompute_command"] = run["precompute_command"]
    row["relight_command"] = run["relight_command"]
    return row


def fit(xs, ys, kind):
    """(value, text) of the fit over the points with positive numbers, or (None, "")."""
    pts = [(x, y) for x, y in zip(xs, ys) if number(x) and number(y) is not None and x > 0]
    if kind == "loglog":
        pts = [(x, y) for x, y in pts if y > 0]
    if len({x for x, _ in pts}) < 2:
        return None, ""
    lx = [math.log(x) for x, _ in pts]
    ly = [math.log(y) if kind == "loglog" else y for _, y in pts]
    mx, my = sum(lx) / len(lx), sum(ly) / len(ly)
    sxx = sum((a - mx) ** 2 for a in lx)
    slope = sum((a - mx) * (b - my) for a, b in zip(lx, ly)) / sxx
    if kind == "loglog":
        return slope, f"slope {slope:.2f}"
    per_doubling = slope * math.log(2)
    return per_doubling, f"{per_doubling:+.3g} per doubling"


# Point-light runs (DIR/pointlights.tsv), plotted against their vertices; metrics as SERIES'.
POINT_LIGHT_METRICS = [
    ("tsis_frame_ms", "texture space: new light position", "ms", "texture-space sampling [ms]", "loglog"),
    ("tsis_irradiance_ms", "texture space: irradiance map", "ms", "texture-space sampling [ms]", "loglog"),
    ("tsis_sums_ms", "texture space: per-vertex sums", "ms", "texture-space sampling [ms]", "loglog"),
    ("cache_seconds", "irradiance cache (T_cache)", "s", "irradiance cache frame [s]", "loglog"),
    ("jb_seconds", "Jensen-Buhler (T_JB)", "s", "irradiance cache frame [s]", "loglog"),
]


def load_point_lights(d):
    """One row per point-light run: prt-bench-tsis's JSON and prt-pointlight's log."""
    path = os.path.join(d, "pointlights.tsv")
    if not os.path.exists(path):
        return []
    rows = []
    with open(path) as f:
        for m in csv.DictReader(f, delimiter="\t"):
            tsis_path = os.path.join(d, "json", m["name"] + ".tsis.json")
            log_path = os.path.join(d, "logs", m["name"] + ".cache.log")
            if not os.path.exists(tsis_path) or not os.path.exists(log_path):
                print(f"plot_scaling: {m['name']}: no point-light results (the run failed?), left out",
                      file=sys.stderr)
                continue
            t = json.load(open(tsis_path))
            frame = t["rows"][0]
            c = parse_cache_log(open(log_path).read()) or {}
            rows.append({
                "name": m["name"], "vertices": t["vertices"], "triangles": t["triangles"],
                "tsis_frame_ms": frame["frame_ms"], "tsis_irradiance_ms": frame["irradiance_ms"],
                "tsis_shadow_maps_ms": frame["shadow_maps_ms"], "tsis_draws_ms": frame["draws_ms"],
                "tsis_sums_ms": frame["sums_ms"], "tsis_samples": frame["samples"],
                "cache_seconds": c.get("cache_seconds"), "jb_seconds": c.get("jb_seconds"),
                "cache_speedup": c.get("speedup"), "cache_vs_jb": c.get("vs_jb"), "cache_share": c.get("cache_share"),
                "tsis_command": m["tsis"], "cache_command": m["cache"],
            })
    return sorted(rows, key=lambda r: r["vertices"])


def point_light_table(pl):
    """Markdown section and fitted slopes of the point-light runs."""
    samples = ", ".join(sorted({f"{r['tsis_samples']:,}" for r in pl})) or "?"
    out = ["## Point lights vs mesh size (dragon, 30 mm, Skin2, one point light)", "",
           f"Texture-space sampling: hybrid, N = {samples}, 512 x 512, per vertex, median of 5 new light "
           "positions (irradiance map + shadow maps + draws + per-vertex sums). Irradiance cache: "
           "defaults, 1024 x 1024, T_cache and Jensen-Buhler's T_JB on the same samples and octree "
           "in the same run.", "",
           "| run | vertices | triangles | TSIS ms per light (fps) | irradiance map ms | shadow maps ms | "
           "draws ms | sums ms | T_cache s | T_JB s | speedup | caches % of hit pixels | cache vs JB |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in pl:
        out.append(f"| {r['name']} | {r['vertices']:,} | {r['triangles']:,} | {r['tsis_frame_ms']:.3g} "
                   f"({1e3 / r['tsis_frame_ms']:.3g}) | {r['tsis_irradiance_ms']:.3g} | "
                   f"{r['tsis_shadow_maps_ms']:.3g} | {r['tsis_draws_ms']:.3g} | {r['tsis_sums_ms']:.3g} | "
                   f"{cell(r['cache_seconds'], '{:.3g}')} | {cell(r['jb_seconds'], '{:.3g}')} | "
                   f"{cell(r['cache_speedup'], '{:.3g}')}x | {cell(r['cache_share'], '{:.3g}')} | "
                   f"{'' if r['cache_vs_jb'] is None else format(100 * r['cache_vs_jb'], '.2f') + '%'} |")
    out += ["", "Commands:", ""]
    out += [f"- {r['name']}: `{r['tsis_command']}`; `{r['cache_command']}`" for r in pl]
    out.append("")
    slopes = []
    for key, label, _, _, _ in POINT_LIGHT_METRICS:
        value, text = fit([r["vertices"] for r in pl], [r.get(key) for r in pl], "loglog")
        if value is not None:
            slopes.append(("Point lights vs mesh size", label, text, len(pl)))
    return out, slopes


def load_runs(d):
    runs = []
    with open(os.path.join(d, "manifest.tsv")) as f:
        reader = csv.DictReader(f, delimiter="\t")
        for m in reader:
            repeats = int(m.get("repeats") or 1)
            flats = []
            for k in range(1, repeats + 1):
                tag = m["name"] if k == 1 else f"{m['name']}.r{k}"
                run = {"name": m["name"], "series": m["series"].split(","),
                       "precompute_command": m["precompute"], "relight_command": m["relight"]}
                for key, suffix in (("precompute", ".json"), ("relight", ".relight.json")):
                    p = os.path.join(d, "json", tag + suffix)
                    run[key] = json.load(open(p)) if os.path.exists(p) else None
                if run["precompute"] is None:
                    print(f"plot_scaling: {tag}: no summary (the run failed?), left out", file=sys.stderr)
                    continue
                flats.append(flatten(run))
            if flats:
                runs.append(aggregate(flats))
    return runs


def write_csv(rows, path):
    keys = []
    for r in rows:
        for k in r:
            if k not in keys and k != "_spread":
                keys.append(k)
    tmp = path + f".tmp.{os.getpid()}"
    with open(tmp, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=keys)
        w.writeheader()
        for r in rows:
            w.writerow({k: ("" if r.get(k) is None else r.get(k)) for k in keys})
    os.replace(tmp, path)


def cell(v, f):
    v = number(v)
    return "" if v is None else f.format(v)


def cell_spread(r, k, f):
    """The cell of r[k], with "(min..max)" when the repeats of the run differ."""
    s = (r.get("_spread") or {}).get(k)
    text = cell(r.get(k), f)
    return f"{text} ({f.format(s[0])}..{f.format(s[1])})" if s and text else text


def title(spec, rs):
    """The series title with the meshes of its runs."""
    meshes = sorted({os.path.basename(str(r.get("mesh", ""))).split(".")[0] for r in rs})
    return f"{spec['title']}: {', '.join(m for m in meshes if m)}"


def series_rows(rows, name):
    spec = SERIES[name]
    rs = [r for r in rows if name in r["series"].split() and number(r.get(spec["x"])) is not None]
    return sorted(rs, key=lambda r: r[spec["x"]])


def tables(rows, pl=()):
    out = ["# Scaling runs", "",
           "Generated by tools/scaling.sh + tools/plot_scaling.py. Times are wall-clock seconds "
           "on the machine the runs were made on; \"load avg\" is the 1-minute load average when "
           "the run started (above the core count: other work competed). With --repeat N a cell is "
           "the median of the N runs and (min..max), and the plots and fits use the medians. Slopes: least squares of "
           "log y on log x (1 = linear; a little above 1 = n log n; 0 = flat).", ""]
    slope_rows = []
    for name, spec in SERIES.items():
        rs = series_rows(rows, name)
        if not rs:
            continue
        out += [f"## {title(spec, rs)}", ""]
        cols = [c for c in TABLE_COLUMNS if any(number(r.get(c[0])) is not None for r in rs)]
        head = ["run", spec["xlabel"]] + [c[1] for c in cols if c[0] != spec["x"]]
        out.append("| " + " | ".join(head) + " |")
        out.append("|" + "---|" * len(head))
        for r in rs:
            vals = [r["name"], f"{r[spec['x']]:,}" if isinstance(r[spec["x"]], int) else f"{r[spec['x']]:g}"]
            vals += [cell_spread(r, k, f) for k, _, f in cols if k != spec["x"]]
            out.append("| " + " | ".join(vals) + " |")
        out.append("")
        out.append("Commands:")
        out.append("")
        for r in rs:
            out.append(f"- {r['name']}: `{r['precompute_command']}`; `{r['relight_command']}`")
        out.append("")
        xs = [r[spec["x"]] for r in rs]
        for key, label, unit, _, kind in spec["metrics"]:
            value, text = fit(xs, [r.get(key) for r in rs], kind)
            if value is not None:
                slope_rows.append((spec["title"].split(" (")[0], label, text, len(rs)))
    # Relight against the bytes it streams, over every run.
    rs = [r for r in rows if number(r.get("relight_stream_MB")) and number(r.get("relight_ms_median"))]
    if rs:
        out += ["## Relight time per frame against the bytes it streams (every file)", "",
                "Warm: back to back (a file smaller than the last-level cache is read from cache); "
                "cold: each run after reading a 1 GiB array (from memory).", "",
                "| run | vertices | components | stream MB | relight ms (warm) | GB/s | relight ms (cold) | GB/s | light ms |",
                "|---|---|---|---|---|---|---|---|---|"]
        for r in sorted(rs, key=lambda r: r["relight_stream_MB"]):
            cold = number(r.get("relight_cold_ms_median"))
            out.append(f"| {r['name']} | {r['vertices']:,} | {r.get('components', '')} | "
                       f"{r['relight_stream_MB']:.3g} | {r['relight_ms_median']:.3g} | "
                       f"{r['relight_stream_MB'] / r['relight_ms_median']:.3g} | "
                       f"{cell(cold, '{:.3g}')} | "
                       f"{'' if not cold else format(r['relight_stream_MB'] / cold, '.3g')} | "
                       f"{cell(r.get('light_ms_median'), '{:.3g}')} |")
        out.append("")
        for key, label in (("relight_ms_median", "kernel time (warm) vs stream bytes"),
                           ("relight_cold_ms_median", "kernel time (cold) vs stream bytes")):
            value, text = fit([r["relight_stream_MB"] for r in rs], [r.get(key) for r in rs], "loglog")
            if value is not None:
                slope_rows.append(("Relight", label, text, len(rs)))
    if pl:
        section, slopes = point_light_table(pl)
        out += section
        slope_rows += slopes
    if slope_rows:
        out += ["## Fitted growth", "", "| series | metric | fit | points |", "|---|---|---|---|"]
        out += [f"| {a} | {b} | {c} | {d} |" for a, b, c, d in slope_rows]
        out.append("")
    return "\n".join(out)


def plot(rows, plots_dir, pl=()):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        from matplotlib.ticker import FuncFormatter, NullFormatter
    except ImportError:
        print("plot_scaling: matplotlib not installed (tools/setup.sh --plots): no plots, tables only",
              file=sys.stderr)
        return []
    written = []
    plain = FuncFormatter(lambda v, _: f"{v:g}")

    def minor_label(v, _):
        if v <= 0:
            return ""
        m = v / 10 ** math.floor(math.log10(v) + 1e-9)
        return f"{v:g}" if abs(m - round(m)) < 1e-6 and round(m) in (2, 3, 5) else ""
    minor = FuncFormatter(minor_label)

    def label_axes(ax):
        """Plain numbers (2000, 0.5) instead of 2x10^3; minor ticks labelled only on short axes."""
        for axis, lim, scale in ((ax.xaxis, ax.get_xlim(), ax.get_xscale()),
                                 (ax.yaxis, ax.get_ylim(), ax.get_yscale())):
            if scale != "log":
                continue
            axis.set_major_formatter(plain)
            short = lim[0] > 0 and math.log10(lim[1] / lim[0]) < 1.3
            axis.set_minor_formatter(minor if short else NullFormatter())

    def draw(ax, xs, ys, label, kind, marker, scatter=False):
        pts = [(x, y) for x, y in zip(xs, ys) if number(y) is not None and (kind != "loglog" or y > 0)]
        if not pts:
            return
        px, py = [p[0] for p in pts], [p[1] for p in pts]
        slope, text = fit(px, py, kind)
        line = ax.plot(px, py, marker=marker, linestyle="none" if scatter else "-",
                       label=f"{label} ({text})" if text else label)[0]
        if scatter and slope is not None and kind == "loglog":
            # The fitted power law, dashed, over the points' range.
            lx = [math.log(x) for x in px]
            ly = [math.log(y) for y in py]
            c = sum(ly) / len(ly) - slope * sum(lx) / len(lx)
            ends = [min(px), max(px)]
            ax.plot(ends, [math.exp(c + slope * math.log(x)) for x in ends], linestyle="--",
                    color=line.get_color(), linewidth=1)

    def panels_figure(rs, xs, metrics, xlabel, suptitle, name):
        """One panel per metric group against xs (log x; log y unless fitted per doubling): scaling_NAME.png."""
        panels = []
        for m in metrics:
            if m[3] not in panels:
                panels.append(m[3])
        fig, axes = plt.subplots(1, len(panels), figsize=(5.2 * len(panels), 4.2), squeeze=False)
        markers = "osD^vx+*"
        for ax, panel in zip(axes[0], panels):
            doubling = False
            for i, (key, label, unit, p, kind) in enumerate(m for m in metrics if m[3] == panel):
                draw(ax, xs, [r.get(key) for r in rs], label, kind, markers[i % len(markers)])
                doubling = doubling or kind == "doubling"
            ax.set_xscale("log")
            if not doubling:
                ax.set_yscale("log")
            label_axes(ax)
            ax.set_xlabel(xlabel)
            ax.set_ylabel(panel)
            ax.grid(True, which="both", alpha=0.3)
            if ax.get_legend_handles_labels()[0]:
                ax.legend(fontsize=8)
        fig.suptitle(suptitle, fontsize=10)
        fig.tight_layout()
        path = os.path.join(plots_dir, f"scaling_{name}.png")
        fig.savefig(path, dpi=100)
        plt.close(fig)
        written.append(path)

    for name, spec in SERIES.items():
        rs = series_rows(rows, name)
        if rs:
            panels_figure(rs, [r[spec["x"]] for r in rs], spec["metrics"], spec["xlabel"], title(spec, rs), name)
    rs = [r for r in rows if number(r.get("relight_stream_MB")) and number(r.get("relight_ms_median"))]
    if rs:
        fig, ax = plt.subplots(figsize=(6, 4.5))
        rs = sorted(rs, key=lambda r: r["relight_stream_MB"])
        draw(ax, [r["relight_stream_MB"] for r in rs], [r["relight_ms_median"] for r in rs],
             "warm (back to back)", "loglog", "o", scatter=True)
        draw(ax, [r["relight_stream_MB"] for r in rs], [r.get("relight_cold_ms_median") for r in rs],
             "cold (after reading 1 GiB)", "loglog", "s", scatter=True)
        labelled = []
        for r in rs:  # one name per cluster of points with about the same size
            x = r["relight_stream_MB"]
            if any(abs(math.log(x / l)) < 0.1 for l in labelled):
                continue
            labelled.append(x)
            ax.annotate(r["name"], (x, r["relight_ms_median"]), fontsize=6,
                        xytext=(3, -9), textcoords="offset points")
        ax.set_xscale("log")
        ax.set_yscale("log")
        label_axes(ax)
        ax.set_xlabel("bytes streamed per relight [MB]")
        ax.set_ylabel("relight time per frame [ms] (median)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
        fig.suptitle("Relight kernel time against the transport bytes it streams", fontsize=10)
        fig.tight_layout()
        path = os.path.join(plots_dir, "scaling_relight.png")
        fig.savefig(path, dpi=100)
        plt.close(fig)
        written.append(path)
    if pl:
        panels_figure(pl, [r["vertices"] for r in pl], POINT_LIGHT_METRICS, "vertices",
                      "Point lights vs mesh size (dragon, 30 mm, Skin2)", "pointlights_mesh")
    return written


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dir", default="out/scaling", help="tools/scaling.sh output directory")
    ap.add_argument("--plots", default=None, help="directory of the PNG plots (default DIR/images)")
    a = ap.parse_args()
    rows = load_runs(a.dir)
    pl = load_point_lights(a.dir)
    if not rows and not pl:
        sys.exit("plot_scaling: no successful runs in " + a.dir)
    write_csv(rows, os.path.join(a.dir, "scaling.csv"))
    text = tables(rows, pl)
    path = os.path.join(a.dir, "tables.md")
    with open(path + ".tmp", "w") as f:
        f.write(text)
    os.replace(path + ".tmp", path)
    print(text)
    plots_dir = a.plots or os.path.join(a.dir, "images")
    os.makedirs(plots_dir, exist_ok=True)
    written = plot(rows, plots_dir, pl)
    print(f"wrote {os.path.join(a.dir, 'scaling.csv')}, {path}" +
          (", " + ", ".join(written) if written else ""))


if __name__ == "__main__":
    main()
