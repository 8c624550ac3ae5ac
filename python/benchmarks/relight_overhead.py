#!/usr/bin/env python3
"""The overhead of prt.relight from Python against the C++ kernel (docs/performance.md).

    PYTHONPATH=build/python python3 python/benchmarks/relight_overhead.py [TRANSPORT] [ENVIRONMENT]

Default: out/bunny_marble.prt (tools/demo.sh) under data/envmaps/forest.exr. Each run
times, interleaved (so both see the same machine state), R calls of
prt.time_relight (the kernel timed in C++, no Python, no copy) and R calls of
prt.relight(..., out=array) timed in Python (the call, the argument checks, releasing
the GIL and the copy into the numpy array). It prints the median of each per run, the
ratio, and the median and spread of the ratio over the runs.
"""

import argparse
import statistics
import time
from pathlib import Path

import numpy as np

import prt

ROOT = Path(__file__).resolve().parents[2]

p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
p.add_argument("transport", nargs="?", default=str(ROOT / "out/bunny_marble.prt"))
p.add_argument("environment", nargs="?", default=str(ROOT / "data/envmaps/forest.exr"))
p.add_argument("--runs", type=int, default=5)
p.add_argument("--repeats", type=int, default=200, help="calls per run and path")
a = p.parse_args()

t = prt.load_transport(a.transport)
light = prt.load_environment(a.environment).light_vector(t.cubemap_size)
out = np.empty((t.vertex_count, 3), np.float32)
print(f"{a.transport}: {t.vertex_count} vertices, components {','.join(t.components)}; {a.repeats} calls per run")
ratios = []
for run in range(a.runs):
    kernel, python = [], []
    for _ in range(a.repeats // 10):
        kernel += prt.time_relight(t, light, repeats=10)
        for _ in range(10):
            start = time.perf_counter()
            prt.relight(t, light, out=out)
            python.append(time.perf_counter() - start)
    k, py = statistics.median(kernel), statistics.median(python)
    ratios.append(py / k)
    print(f"run {run + 1}: kernel {1e3 * k:.3f} ms, prt.relight {1e3 * py:.3f} ms, ratio {py / k:.4f}")
print(f"ratio prt.relight / kernel: median {statistics.median(ratios):.4f} (min {min(ratios):.4f}, max {max(ratios):.4f}) "
      f"over {a.runs} runs")
