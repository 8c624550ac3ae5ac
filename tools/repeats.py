"""Medians of repeated benchmark runs, with their spread (standard library only).

Shared by tools/plot_scaling.py (flat rows of tools/scaling.sh --repeat) and
tools/bench_report.py (the JSON trees and parsed logs of tools/bench.sh --repeat).
A number that differs between the repeats becomes their median; anything else (text,
a count that every repeat agrees on) is the first repeat's.
"""

import math
import statistics


def number(v):
    """v when it is a finite int or float (not a bool), else None."""
    return v if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) else None


def aggregate(flats):
    """One row from the repeats of a run (flat dicts): a number that differs between the
    repeats (a time, a load average) becomes their median, with (min, max, count) in
    row["_spread"]; everything else is the first repeat's."""
    row = dict(flats[0])
    row["repeats"] = len(flats)
    if len(flats) == 1:
        return row
    spread = {}
    for k in row:
        vals = [f.get(k) for f in flats]
        if k == "repeats" or any(number(v) is None for v in vals) or len(set(vals)) == 1:
            continue
        row[k] = statistics.median(vals)
        spread[k] = (min(vals), max(vals), len(vals))
    row["_spread"] = spread
    return row


def median_tree(trees):
    """The element-wise median of JSON-like trees of the same shape (dicts, lists,
    numbers): every number that differs between the trees becomes the median of its
    values; where the shapes differ the first tree's branch is kept."""
    first = trees[0]
    if isinstance(first, dict):
        if not all(isinstance(t, dict) for t in trees):
            return first
        return {k: (median_tree([t[k] for t in trees]) if all(k in t for t in trees) else v)
                for k, v in first.items()}
    if isinstance(first, list):
        if not all(isinstance(t, list) and len(t) == len(first) for t in trees):
            return first
        return [median_tree([t[i] for t in trees]) for i in range(len(first))]
    vals = [number(t) for t in trees]
    if any(v is None for v in vals) or len(set(vals)) == 1:
        return first
    return statistics.median(vals)


def spread_of(trees, *path):
    """(min, max, count) of the number at `path` (keys / indices) over the trees, or
    None when there is one tree or a tree lacks a number there."""
    if len(trees) < 2:
        return None
    vals = []
    for t in trees:
        for key in path:
            try:
                t = t[key]
            except (KeyError, IndexError, TypeError):
                return None
        if number(t) is None:
            return None
        vals.append(t)
    return (min(vals), max(vals), len(vals))
