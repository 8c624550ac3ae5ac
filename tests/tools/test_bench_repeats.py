"""tools/repeats.py and tools/bench_report.py over repeated runs (standard library only).

Run: python3 -m unittest tests/tools/test_bench_repeats.py (CTest: tools_bench_repeats).
The report is checked on a synthetic tools/bench.sh directory whose three runs differ in
known ways, so every median and (min..max) it prints is known in advance.
"""

import json
import os
import subprocess
import sys
import tempfile
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
TOOLS = os.path.join(HERE, "..", "..", "tools")
sys.path.insert(0, TOOLS)

from repeats import aggregate, median_tree, number, spread_of  # noqa: E402


class MedianHelpers(unittest.TestCase):
    def test_number(self):
        self.assertEqual(number(3), 3)
        self.assertIsNone(number(True))
        self.assertIsNone(number(float("nan")))
        self.assertIsNone(number("3"))

    def test_aggregate_takes_medians_of_what_differs(self):
        row = aggregate([{"t": 3.0, "n": 7, "s": "a"}, {"t": 1.0, "n": 7, "s": "b"}, {"t": 2.0, "n": 7, "s": "c"}])
        self.assertEqual(row["t"], 2.0)
        self.assertEqual(row["n"], 7)
        self.assertEqual(row["s"], "a")
        self.assertEqual(row["_spread"], {"t": (1.0, 3.0, 3)})
        self.assertEqual(row["repeats"], 3)

    def test_median_tree_is_elementwise(self):
        trees = [{"a": {"b": [1, 10]}, "c": "x"}, {"a": {"b": [5, 30]}, "c": "y"}, {"a": {"b": [3, 20]}, "c": "z"}]
        self.assertEqual(median_tree(trees), {"a": {"b": [3, 20]}, "c": "x"})
        # An even count: the mean of the middle two, as statistics.median.
        self.assertEqual(median_tree([{"v": 1.0}, {"v": 4.0}]), {"v": 2.5})
        # Shapes that differ keep the first tree's branch.
        self.assertEqual(median_tree([{"l": [1, 2]}, {"l": [5]}]), {"l": [1, 2]})

    def test_spread_of(self):
        trees = [{"a": [0, 4.0]}, {"a": [0, 2.0]}, {"a": [0, 9.0]}]
        self.assertEqual(spread_of(trees, "a", 1), (2.0, 9.0, 3))
        self.assertIsNone(spread_of(trees[:1], "a", 1))
        self.assertIsNone(spread_of(trees, "a", 5))


def precompute_json(total, pass2_per_vertex):
    return {"settings": {"mesh": "data/meshes/dragon_vrip_res4.ply.gz", "block_coefficients": 160,
                         "coefficients": 192},
            "summary": {"vertices": 5203, "samples": 9614, "total_seconds": total, "setup_seconds": 0.01,
                        "samples_seconds": 0.05, "pass1_seconds": 2.3, "pass2_seconds": 0.9,
                        "ss_seconds": 4.9, "write_seconds": 0.006, "pass1_seconds_per_sample": 2.4e-4,
                        "pass1_rays_per_second": 5e7, "pass2_seconds_per_vertex": pass2_per_vertex,
                        "mean_nodes_visited": 1104, "ss_seconds_per_vertex": 9.4e-4, "ss_rays_per_vertex": 9719,
                        "ss_rays_per_second": 1e7, "peak_memory_after_setup_bytes": 1.4e8,
                        "peak_memory_after_samples_bytes": 1.47e8, "peak_memory_after_pass1_bytes": 1.62e8,
                        "peak_memory_after_pass2_bytes": 2.15e8, "peak_memory_after_ss_bytes": 2.16e8,
                        "file_bytes_per_vertex": 1028, "file_bytes": 5.35e6}}


def relight_file_json(ms, changes):
    return {"vertices": 5203, "relight_ms_median": ms, "relight_GBps_effective": 57.0, "light_ms_median": 0.35,
            "light_changes_per_second": changes, "light_change_ms_median": 1e3 / changes,
            "light_change_light_ms_median": 0.25}


PASS1_LOG = """mesh     data/meshes/dragon_vrip_res3.ply.gz (47794 triangles)
samples  2000, cubemap 6x32x32, 2x2 sub-directions
raw Embree packet  5.11e+07 rays/s
pass 1, every  3.65e+07 rays/s
ratio    {ratio} pass 1 / raw packet, 2.336 pass 1 / raw single
"""

CACHE_LOG = """T_cache {tc} s
T_JB 6.73 s, speedup {speedup}x, relative RMSE (linear) 0.0067
10610 caches / 302005 hit pixels = 3.51%
"""


class ReportOverRepeats(unittest.TestCase):
    def write(self, d, name, text):
        with open(os.path.join(d, name), "w") as f:
            f.write(text)

    def test_medians_and_spreads(self):
        with tempfile.TemporaryDirectory() as d:
            self.write(d, "meta.txt", "date=2026-12-02T00:00:00Z\ncpu=test\nthreads=2\nrepeat=3\n")
            names = ["pass1", "precompute", "relight_file", "cache"]
            self.write(d, "commands.tsv", "".join(f"{n}\tcmd\x1f{n}\x1f\n" for n in names))
            self.write(d, "relight.json", json.dumps({"workload": {"vertices": 1, "coefficients": 1,
                                                                   "cubemap_size": 32}}))
            # Three runs, each figure's median in a different run.
            for k, (total, p2, ms, ch, ratio, tc, speedup) in enumerate(
                    [(8.0, 1.7e-4, 0.095, 2800, 0.71, 0.43, 15.0),
                     (9.0, 1.6e-4, 0.120, 2900, 0.69, 0.50, 16.0),
                     (7.0, 1.8e-4, 0.090, 2700, 0.75, 0.40, 17.0)], start=1):
                r = "" if k == 1 else f".r{k}"
                self.write(d, f"precompute{r}.json", json.dumps(precompute_json(total, p2)))
                self.write(d, f"relight_file{r}.json", json.dumps(relight_file_json(ms, ch)))
                self.write(d, f"pass1{r}.log", PASS1_LOG.format(ratio=ratio))
                self.write(d, f"cache{r}.log", CACHE_LOG.format(tc=tc, speedup=speedup))
            out = subprocess.run([sys.executable, os.path.join(TOOLS, "bench_report.py"), d],
                                 capture_output=True, text=True, check=True).stdout
            self.assertIn("0.710 (0.69..0.75)", out)
            self.assertIn("8 s (7..9): ", out)
            self.assertIn("170 us (160..180)", out)
            self.assertIn("0.095 ms (0.09..0.12), ", out)
            self.assertIn("2,800 per second (2,700..2,900); ", out)
            self.assertIn("0.43 s / 6.73 s, **16x** (15..17)", out)
            self.assertIn("medians of 3 runs", out)
            with open(os.path.join(d, "summary.md")) as f:
                self.assertEqual(f.read().strip(), out.split("\n\nwrote")[0].strip())

    def test_live_material_rows(self):
        def edit_json(light, plain, transport_bytes, plain_bytes):
            fig = lambda m: {"median_ms": m, "min_ms": m * 0.9, "max_ms": m * 1.2, "runs": 11}
            return {"vertices": 37706, "profiles": 12, "edit": fig(0.2), "light_change": fig(light),
                    "plain_light_change": fig(plain), "light_change_ratio": light / plain,
                    "transport_bytes": transport_bytes, "plain_bytes": plain_bytes}
        with tempfile.TemporaryDirectory() as d:
            self.write(d, "meta.txt", "repeat=1\n")
            names = ["pass1", "precompute", "relight_file", "edit", "edit_blocked"]
            self.write(d, "commands.tsv", "".join(f"{n}\tcmd\x1f{n}\x1f\n" for n in names))
            self.write(d, "relight.json", json.dumps({"workload": {"vertices": 1, "coefficients": 1,
                                                                   "cubemap_size": 32}}))
            self.write(d, "precompute.json", json.dumps(precompute_json(8.0, 1.7e-4)))
            self.write(d, "relight_file.json", json.dumps(relight_file_json(0.095, 2800)))
            self.write(d, "pass1.log", PASS1_LOG.format(ratio=0.71))
            self.write(d, "edit.json", json.dumps(edit_json(1.5, 0.6, 153e6, 39e6)))
            self.write(d, "edit_blocked.json", json.dumps(edit_json(0.4, 0.25, 37.44e6, 19.6e6)))
            out = subprocess.run([sys.executable, os.path.join(TOOLS, "bench_report.py"), d],
                                 capture_output=True, text=True, check=True).stdout
            self.assertIn("**0.2 ms** (0.18..0.24)", out)
            self.assertIn("1.5 / 0.6 ms, **2.50x**; 3.92x", out)
            # The blocked file's bytes against the per-vertex plain file of edit.json.
            self.assertIn("0.4 / 0.25 ms, **1.60x**; 0.96x the plain per-vertex file's bytes", out)

    def test_a_missing_repeat_is_an_error(self):
        with tempfile.TemporaryDirectory() as d:
            self.write(d, "meta.txt", "repeat=2\n")
            self.write(d, "commands.tsv", "")
            self.write(d, "relight.json", "{}")
            self.write(d, "precompute.json", json.dumps(precompute_json(8.0, 1.7e-4)))
            proc = subprocess.run([sys.executable, os.path.join(TOOLS, "bench_report.py"), d],
                                  capture_output=True, text=True)
            self.assertNotEqual(proc.returncode, 0)
            self.assertIn("precompute.r2.json", proc.stderr)
            self.assertEqual(len(proc.stderr.strip().splitlines()), 1, proc.stderr)


if __name__ == "__main__":
    unittest.main()
