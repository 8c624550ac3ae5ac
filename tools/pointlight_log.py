"""What `prt-pointlight --method cache --compare-jb` prints, read back (standard library only).

Shared by tools/bench_report.py and tools/plot_scaling.py.
"""

import re


def parse_cache_log(text):
    """The cache run's figures from its log, or None when a line is missing:
    cache_seconds (T_cache), jb_seconds (T_JB), speedup (T_JB / T_cache, same run),
    vs_jb (the cache's linear relative RMSE against Jensen-Buhler), caches, hit_pixels
    and cache_share (caches per hit pixel, percent)."""
    tc = re.search(r"T_cache ([0-9.]+) s$", text, re.M)
    jb = re.search(r"T_JB ([0-9.]+) s, speedup ([0-9.]+)x.*relative RMSE \(linear\) ([0-9.e+-]+)", text)
    caches = re.search(r"([0-9]+) caches / ([0-9]+) hit pixels = ([0-9.]+)%", text)
    if not (tc and jb and caches):
        return None
    return {
        "cache_seconds": float(tc.group(1)), "jb_seconds": float(jb.group(1)), "speedup": float(jb.group(2)),
        "vs_jb": float(jb.group(3)), "caches": int(caches.group(1)), "hit_pixels": int(caches.group(2)),
        "cache_share": float(caches.group(3)),
    }
