#!/usr/bin/env python3
"""Error against the number of light coefficients, from Python (docs/python.md).

Precomputes the bunny (or any mesh), relights it under two environments keeping only
the largest K Haar coefficients of each light (prt-relight's -L K), and plots the
image's relative RMSE against the frame with every coefficient, with matplotlib.

    PYTHONPATH=build/python python3 python/examples/coefficient_sweep.py

writes out/python-example/: the transport file, one PNG per environment and K, and
coefficients.png, the plot. The run's tests call it on a small torus (--mesh ...).
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np

import prt

ROOT = Path(__file__).resolve().parents[2]


def arguments():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--mesh", default=str(ROOT / "data/meshes/bunny.off"), help="mesh file (default: the bunny)")
    p.add_argument("--environments", nargs=2, metavar="EXR",
                   default=[str(ROOT / "data/envmaps/forest.exr"), str(ROOT / "data/envmaps/sunset.exr")],
                   help="two lat-long environments (default: forest and sunset)")
    p.add_argument("--material", default="Marble")
    p.add_argument("--size-mm", type=float, default=30.0)
    p.add_argument("--cubemap-size", type=int, default=32)
    p.add_argument("--samples", type=int, default=None, help="irradiance samples (default: the tool's rule)")
    p.add_argument("--size", type=int, default=256, help="image side in pixels")
    p.add_argument("--out", default=str(ROOT / "out/python-example"), help="output folder")
    return p.parse_args()


def progress_printer():
    """A progress callable printing one line per stage when it ends."""
    start = {}

    def report(stage, done, total, unit):
        start.setdefault(stage, time.monotonic())
        if done == total:
            print(f"  {stage}: {total} {unit} in {time.monotonic() - start[stage]:.1f} s", flush=True)

    return report


def main():
    a = arguments()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    transport_path = out / (Path(a.mesh).name.split(".")[0] + ".prt")

    print(f"precompute {a.mesh} ({a.material}, {a.size_mm} mm, cubemap 6x{a.cubemap_size}^2)")
    options = dict(material=a.material, size_mm=a.size_mm, cubemap_size=a.cubemap_size)
    if a.samples:
        options["samples"] = a.samples
    transport = prt.precompute(a.mesh, str(transport_path), progress=progress_printer(), **options)
    print("  " + ("up to date: " if transport.summary["skipped"] else "wrote ") + str(transport_path))

    obj = prt.load_object(a.mesh, str(transport_path))
    n_all = 6 * a.cubemap_size**2
    counts = [k for k in (4, 8, 16, 32, 64, 128, 256, 512, 1024, 2048, 4096) if k < n_all] + [n_all]
    curves = {}
    for path in a.environments:
        env = prt.load_environment(path)
        name = Path(path).stem
        full = prt.render(obj, env, width=a.size, height=a.size)
        prt.write_png(str(out / f"{name}_all.png"), full)
        errors = []
        for k in counts:
            image = prt.render(obj, env, width=a.size, height=a.size, light_terms=k)
            errors.append(prt.compare(image, full)["relative_rmse"])
            prt.write_png(str(out / f"{name}_{k:05d}.png"), image)
        curves[name] = errors
        print(f"{name}: " + ", ".join(f"K={k} {100 * e:.2f}%" for k, e in zip(counts, errors)))

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4), dpi=120)
    for name, errors in curves.items():
        # Every coefficient is the reference itself (error 0): leave it off the log axis.
        ax.loglog(counts[:-1], np.array(errors[:-1]) * 100, marker="o", label=name)
    ax.set_xlabel("light coefficients kept (K, of %d)" % n_all)
    ax.set_ylabel("relative RMSE of the image, %")
    ax.set_title(f"{Path(a.mesh).name}, {a.material}: error against coefficients")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "coefficients.png")
    print(f"plot: {out / 'coefficients.png'}")
    return curves


if __name__ == "__main__":
    sys.exit(0 if main() else 1)
