#!/usr/bin/env python3
"""Plots of tools/fidelity-budget.sh runs: relative RMSE against the independent
reference as a function of coefficients per vertex and of sample spacing.

Usage: /usr/bin/python3 tools/plot_fidelity.py OUT/MATERIAL_MESH.tsv [...] --plots docs/images
       /usr/bin/python3 tools/plot_fidelity.py OUT/*.tsv --table   (the budget table, markdown)

Reads the TSV files (material, kind, name, value, environment, rel_rmse,
precompute_s); rows of kind "coefficients" go to fidelity_coefficients.png, rows of
kind "density" (and "density, point rule", if a run added them) to
fidelity_density.png, one line per material, environment and kind. Needs matplotlib
(tools/setup.sh --plots installs Debian's python3-matplotlib).
"""

import argparse
import csv
import os
import sys
from collections import defaultdict


def print_budget_table(paths):
    values, variants, materials, environments = {}, [], [], []
    for path in paths:
        with open(path, newline="") as f:
            for row in csv.DictReader(f, delimiter="\t"):
                if row["kind"] not in ("budget", "sun"):
                    continue
                if row["name"] not in variants:
                    variants.append(row["name"])
                if row["material"] not in materials:
                    materials.append(row["material"])
                if row["environment"] not in environments:
                    environments.append(row["environment"])
                values[(row["name"], row["material"], row["environment"])] = 100.0 * float(row["rel_rmse"])
    print("| variant | " + " | ".join(f"{m} {e}" for m in materials for e in environments) + " |")
    print("|---|" + "---|" * (len(materials) * len(environments)))
    for v in variants:
        cells = []
        for m in materials:
            for env in environments:
                x = values.get((v, m, env))
                cells.append("" if x is None else f"{x:.2f}%")
        print(f"| {v} | " + " | ".join(cells) + " |")


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("tsv", nargs="+")
    parser.add_argument("--plots", default="docs/images")
    parser.add_argument("--table", action="store_true", help="print the budget rows as a markdown table, no plots")
    args = parser.parse_args()
    if args.table:
        print_budget_table(args.tsv)
        return
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        sys.exit("plot_fidelity: matplotlib is missing (tools/setup.sh --plots)")

    series = defaultdict(list)  # (kind, material, environment) -> [(x, y)]
    for path in args.tsv:
        with open(path, newline="") as f:
            for row in csv.DictReader(f, delimiter="\t"):
                try:
                    x, y = float(row["value"]), float(row["rel_rmse"])
                except (KeyError, ValueError):
                    sys.exit(f"plot_fidelity: {path}: malformed row {row}")
                series[(row["kind"], row["material"], row["environment"])].append((x, 100.0 * y))

    os.makedirs(args.plots, exist_ok=True)
    plots = [
        ("coefficients", "coefficients per vertex (k)", "fidelity_coefficients.png", True),
        ("density", "sample spacing (mm)", "fidelity_density.png", False),
    ]
    for kind, xlabel, name, log2 in plots:
        fig, ax = plt.subplots(figsize=(6, 4))
        drawn = 0
        for (k, material, env), points in sorted(series.items()):
            if not k.startswith(kind):
                continue
            points.sort()
            style = "--" if "point" in k else "-"
            label = f"{material}, {env}" + (" (point rule)" if "point" in k else "")
            ax.plot([p[0] for p in points], [p[1] for p in points], style, marker="o", label=label)
            drawn += 1
        if not drawn:
            plt.close(fig)
            continue
        if log2:
            ax.set_xscale("log", base=2)
        ax.set_xlabel(xlabel)
        ax.set_ylabel("relative RMSE vs independent reference (%)")
        ax.set_ylim(bottom=0)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
        fig.tight_layout()
        out = os.path.join(args.plots, name)
        fig.savefig(out, dpi=110)
        plt.close(fig)
        print(f"wrote {out}")


if __name__ == "__main__":
    main()
