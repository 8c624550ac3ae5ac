#!/usr/bin/env python3
"""Markdown table of a tools/bench.sh run (standard library only).

Usage: tools/bench_report.py OUT_DIR

Reads OUT_DIR/{meta.txt, commands.tsv, relight.json, pass1.log, precompute.json,
relight_file.json, relight_file_folded.json, tsis.json, cache.log, edit.json,
edit_blocked.json}, prints one Markdown
table with the command of each row and writes it to OUT_DIR/summary.md. When meta.txt
says repeat=N (tools/bench.sh --repeat N), the once-per-process benchmarks' files of
runs 2..N (NAME.rK.log / NAME.rK.json) are read too: the table shows each figure's
median over the runs, the headline figures with (min..max).
"""

import json
import os
import re
import shlex
import sys

from pointlight_log import parse_cache_log
from repeats import median_tree, spread_of


def load_json(path):
    """The JSON at path; a missing or unreadable file ends the report with one line naming it."""
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError) as e:
        sys.exit(f"bench_report: {path}: {getattr(e, 'strerror', None) or e}")


def read_text(path):
    try:
        with open(path) as f:
            return f.read()
    except OSError as e:
        sys.exit(f"bench_report: {path}: {e.strerror}")


def fmt(v, digits=3):
    """A number with `digits` significant digits, thousands separated when large."""
    if v is None:
        return "n/a"
    if abs(v) >= 10 ** digits:
        return f"{v:,.0f}"
    return f"{v:.{digits}g}"


def sci(v):
    """Rates: 3 significant digits in scientific notation (5.12e+06)."""
    return "n/a" if v is None else f"{v:.3g}"


def mb(b):
    return None if b is None else b / 1e6


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    out = sys.argv[1]
    meta = {}
    with open(os.path.join(out, "meta.txt")) as f:
        for line in f:
            if "=" in line:
                k, v = line.rstrip("\n").split("=", 1)
                meta[k] = v
    commands = {}
    with open(os.path.join(out, "commands.tsv")) as f:
        for line in f:
            name, cmd = line.rstrip("\n").split("\t", 1)
            # Arguments are separated by \x1f: quote them for a shell, and escape the
            # pipes of a Markdown table cell (GitHub shows \| in a code span as |).
            args = [a for a in cmd.split("\x1f") if a != ""] if "\x1f" in cmd else cmd.split()
            commands[name] = shlex.join(args).replace("|", "\\|")
    repeat = int(meta.get("repeat") or 1)

    def runs_of(name, ext):
        """The paths of NAME's runs: NAME.EXT, then NAME.rK.EXT for K = 2..repeat."""
        return [os.path.join(out, name + ("" if k == 1 else f".r{k}") + ext) for k in range(1, repeat + 1)]

    relight = load_json(os.path.join(out, "relight.json"))
    pres = [load_json(p) for p in runs_of("precompute", ".json")]
    pre = median_tree(pres)
    s = pre["summary"]
    rfs = [load_json(p) for p in runs_of("relight_file", ".json")]
    rf = median_tree(rfs)
    pass1_logs = [read_text(p) for p in runs_of("pass1", ".log")]
    pass1_patterns = {
        "ratio_packet": r"^ratio\s+([0-9.]+) pass 1 / raw packet",
        "ratio_single": r"pass 1 / raw packet, ([0-9.]+) pass 1 / raw single",
        "rate": r"^pass 1(?:, every)?\s+([0-9.e+]+) rays/s",
        "coherent_ratio": r"^ratio, coherent\s+([0-9.]+) effective / raw packet",
        "coherent_speedup": r"^ratio, coherent .*\(([0-9.]+)x every's time\)",
        "coherent_change": r"^coherent vs every .*relative L2 change ([0-9.e+-]+) over all samples",
        "packet_rate": r"^raw Embree packet\s+([0-9.e+]+) rays/s",
    }

    def parse_pass1(text):
        """Each pattern's number in one pass-1 log, None where the log lacks it."""
        found = {k: re.search(v, text, re.M) for k, v in pass1_patterns.items()}
        return {k: float(m.group(1)) if m else None for k, m in found.items()}

    pass1s = [parse_pass1(t) for t in pass1_logs]
    p1 = median_tree(pass1s)

    def sp(spread, scale=1.0):
        """ " (min..max)" of a headline figure over the runs, empty for one run."""
        return "" if not spread else f" ({fmt(scale * spread[0])}..{fmt(scale * spread[1])})"

    pass1_ratio_packet = p1["ratio_packet"]
    pass1_ratio_single = p1["ratio_single"]
    pass1_rate = p1["rate"]
    pass1_coherent_ratio = p1["coherent_ratio"]
    pass1_coherent_speedup = p1["coherent_speedup"]
    pass1_coherent_change = p1["coherent_change"]
    packet_rate = p1["packet_rate"]
    pass1_log = pass1_logs[0]
    m = re.search(r"^samples\s+(\d+), cubemap (\S+), (\S+) sub-directions", pass1_log, re.M)
    pass1_setup = f"{int(m.group(1)):,} samples, {m.group(2)}, {m.group(3)}" if m else ""
    m = re.search(r"^mesh\s+(\S+) \((\d+) triangles", pass1_log, re.M)
    pass1_mesh = f"{os.path.basename(m.group(1))}, {int(m.group(2)):,} triangles" if m else ""

    rows = []

    def row(what, measured, goal, cmd):
        rows.append((what, measured, goal, f"`{commands[cmd]}`" if cmd else ""))

    w = relight["workload"]
    workload = f"{w['vertices']:,} vertices x {w['coefficients']} coefficients, 6x{w['cubemap_size']}x{w['cubemap_size']}"
    for key, label in (("diffuse", "diffuse only (1 vector per vertex)"),
                       ("k4", "1 diffuse + K = 4 single-scattering terms (5 vectors per vertex)")):
        r = relight.get("relight", {}).get(key)
        if not r:
            continue
        row(f"relight, {label}, {workload}, {fmt(r['stream_MB'])} MB per frame: time per frame",
            f"{fmt(r['cold_ms_median'])} ms (median, caches flushed by a 1 GiB sum; "
            f"right after: {fmt(r['warm_ms_median'])} ms)", "", "relight")
        row(f"relight, {label}: time per frame / time to stream the same bytes at the measured bandwidth",
            f"{r['ratio_cold_median']:.2f} (median of matched pairs; of means {r['ratio_cold']:.2f})",
            "<= 1.5", "relight")
        if "ratio_change_median" in r:
            row(f"relight, {label}: per light change (a new light vector from a 1024 x 512 environment + "
                "the kernel) / the same stream time",
                f"{r['ratio_change_median']:.2f} ({fmt(r['change_ms_median'])} ms, light vector "
                f"{fmt(r['light_ms_median'])} ms)", "below 1 (SPEC section 8)", "relight")
    for key, label in (("diffuse", "diffuse only"), ("k4", "1 diffuse + K = 4 terms")):
        b = relight.get("blocked", {}).get(key)
        if not b:
            continue
        row(f"blocked relight (`--block-coefficients {b['block_coefficients']}`, blocks of 16, "
            f"{b['block_order']} block order), {label}, {fmt(b['stream_MB'])} MB per frame against "
            f"{fmt(b['stream_8byte_MB'])} MB per vertex: time per frame / time to stream today's 8-byte "
            "coefficients at the measured bandwidth",
            f"{b['ratio_vs_8byte_cold_median']:.2f} cold, {b['ratio_vs_8byte_warm_median']:.2f} warm "
            f"({fmt(b['cold_ms_median'])} ms against today's kernel {fmt(b['today_cold_ms_median'])} ms in the "
            f"same iterations: {b['speedup_median']:.2f}x; ratio to its own bytes {b['ratio_own_cold_median']:.2f})",
            "<= 0.5", "relight")
    d = relight.get("relight", {}).get("diffuse") or relight.get("relight", {}).get("k4")
    if d:
        row("memory read bandwidth (1 GiB sum, all threads, interleaved with the relights)",
            f"{d['dram_GBps']:.2f} GB/s", "", "relight")
    load = relight.get("load", {})
    if "page_cache" in load:
        l = load["page_cache"]
        row(f"transport file load (loadTransportFile, every checksum), {fmt(l['file_MB'])} MB, from the page cache",
            f"{fmt(l['ms'])} ms ({fmt(l['MBps'])} MB/s)", "", "relight")
    if "cold" in load:
        l = load["cold"]
        note = "" if l.get("cached_fraction", 0) < 0.01 else \
            f"; {100 * l['cached_fraction']:.0f}% of pages still cached: drop ineffective"
        row("transport file load, file dropped from the page cache first (posix_fadvise)",
            f"{fmt(l['ms'])} ms ({fmt(l['MBps'])} MB/s{note})", "", "relight")

    row(f"pass 1: achieved occlusion rays/s / raw Embree packet rays/s on the same rays ({pass1_mesh}, {pass1_setup})",
        f"{pass1_ratio_packet:.3f}{sp(spread_of(pass1s, 'ratio_packet'))}" if pass1_ratio_packet is not None
        else "n/a", ">= 0.8", "pass1")
    row("pass 1 / raw single-ray Embree (rtcOccluded1) on the same rays",
        f"{pass1_ratio_single:.3f}" if pass1_ratio_single is not None else "n/a", "", "pass1")
    row("pass 1 rays/s (raw packet rays/s)", f"{sci(pass1_rate)} ({sci(packet_rate)})", "", "pass1")
    if pass1_coherent_ratio is not None:
        row("pass 1 with --pass1-visibility coherent: every's rays per second of its time / raw packet rays/s; "
            "speed-up; change of the sample vectors (relative L2)",
            f"{pass1_coherent_ratio:.3f}; {pass1_coherent_speedup:.2f}x; {pass1_coherent_change:.2e}",
            "> 1 by tracing fewer rays", "pass1")

    v = s["vertices"]
    mesh = os.path.basename(pre["settings"]["mesh"])
    where = f"{mesh}, {v:,} vertices, {s['samples']:,} samples, 30 mm Marble, ms + isotropic ss"
    row(f"precompute {where}: total (setup, samples, pass 1, pass 2, single scattering, write)",
        f"{fmt(s['total_seconds'])} s{sp(spread_of(pres, 'summary', 'total_seconds'))}: "
        f"{fmt(s['setup_seconds'])}, {fmt(s['samples_seconds'])}, "
        f"{fmt(s['pass1_seconds'])}, {fmt(s['pass2_seconds'])}, {fmt(s['ss_seconds'])}, "
        f"{fmt(s['write_seconds'])} s", "", "precompute")
    row("pass 1 time per sample; rays/s",
        f"{fmt(1e3 * s['pass1_seconds_per_sample'])} ms; {sci(s['pass1_rays_per_second'])}", "", "precompute")
    row("pass 2 time per vertex; kd-tree nodes visited per vertex",
        f"{fmt(1e6 * s['pass2_seconds_per_vertex'])} us{sp(spread_of(pres, 'summary', 'pass2_seconds_per_vertex'), 1e6)}; "
        f"{fmt(s['mean_nodes_visited'])}", "", "precompute")
    row("single scattering time per vertex; rays per vertex; rays/s",
        f"{fmt(1e3 * s['ss_seconds_per_vertex'])} ms{sp(spread_of(pres, 'summary', 'ss_seconds_per_vertex'), 1e3)}; "
        f"{fmt(s['ss_rays_per_vertex'])}; "
        f"{sci(s['ss_rays_per_second'])}", "", "precompute")
    row("peak memory (process peak so far, ru_maxrss) after setup / samples / pass 1 / pass 2 / single scattering",
        " / ".join(fmt(mb(s[k])) for k in (
            "peak_memory_after_setup_bytes", "peak_memory_after_samples_bytes",
            "peak_memory_after_pass1_bytes", "peak_memory_after_pass2_bytes",
            "peak_memory_after_ss_bytes")) + " MB", "", "precompute")
    st = pre.get("settings", {})
    layout = (f"blocks of 16 sharing {st['block_coefficients']} from {st['coefficients']} per vertex"
              if st.get("block_coefficients") else f"{st.get('coefficients', 128)} coefficients per vertex")
    comps = "1 component, ss folded into ms" if st.get("fold_ss") else "2 components"
    row(f"file size per vertex (ms + isotropic ss: {comps}, {layout})",
        f"{fmt(s['file_bytes_per_vertex'])} bytes ({fmt(mb(s['file_bytes']))} MB)", "", "precompute")
    row(f"relight of that file (ms + ss, {rf['vertices']:,} vertices): time per frame; light vector (forest)",
        f"{fmt(rf['relight_ms_median'])} ms{sp(spread_of(rfs, 'relight_ms_median'))}, "
        f"{fmt(rf['relight_GBps_effective'])} GB/s effective; "
        f"{fmt(rf['light_ms_median'])} ms", "", "relight_file")
    if rf.get("light_changes_per_second"):
        row(f"light changes per second ({rf['vertices']:,} vertices; each a new light vector at a fresh angle "
            "+ the relight kernel, back to back)",
            f"{fmt(rf['light_changes_per_second'])} per second{sp(spread_of(rfs, 'light_changes_per_second'))}; "
            f"{fmt(rf['light_change_ms_median'])} ms: "
            f"light vector {fmt(rf['light_change_light_ms_median'])} ms",
            ">= 600 at 31K vertices", "relight_file")
    folded_paths = runs_of("relight_file_folded", ".json")
    if all(os.path.exists(p) for p in folded_paths) and rf.get("light_changes_per_second"):
        ffs = [load_json(p) for p in folded_paths]
        ff = median_tree(ffs)
        row("light changes per second of the same job with --fold-ss (ss folded into the ms vectors: 1 component)",
            f"{fmt(ff['light_changes_per_second'])} per second{sp(spread_of(ffs, 'light_changes_per_second'))}; "
            f"{fmt(ff['light_change_ms_median'])} ms: light "
            f"vector {fmt(ff['light_change_light_ms_median'])} ms; "
            f"{ff['light_changes_per_second'] / rf['light_changes_per_second']:.2f}x the 2-component file",
            ">= 100 at 437,645 vertices (full dragon)", "relight_file_folded")
    if rf.get("light_ms_median_from_image"):
        row("light vector from the prepared environment (row running sums, EnvironmentLight) / from the image "
            "(makeLightVector), the same fresh angles in the same run",
            f"{fmt(rf['light_ms_median'])} / {fmt(rf['light_ms_median_from_image'])} ms "
            f"({rf['light_ms_median'] / rf['light_ms_median_from_image']:.2f}); preparing the environment "
            f"{fmt(rf['environment_prepare_ms'])} ms once", "", "relight_file")

    tsis_path = os.path.join(out, "tsis.json")
    if os.path.exists(tsis_path):
        t = load_json(tsis_path)
        r = t["rows"][0]
        where = (f"{os.path.basename(t['mesh'])}, {t['triangles']:,} triangles, {t['material']}, {t['split']}, "
                 f"N = {r['samples']}, {t['width']} x {t['height']}, per {t['evaluate']}")
        row(f"point light by texture-space sampling ({where}): time per new light position (irradiance map + "
            "shadow maps + draws + per-vertex sums; median of the runs), light positions per second",
            f"{fmt(r['frame_ms'])} ms ({fmt(r['irradiance_ms'])} + {fmt(r['shadow_maps_ms'])} + "
            f"{fmt(r['draws_ms'])} + {fmt(r['sums_ms'])}); {fmt(1e3 / r['frame_ms'])} per second",
            ">= 30 per second (Chang et al.'s goal row)", "tsis")
        change = t.get("material_change", {})
        key = f"tsis {t['split']} setMaterial"
        if key in change:
            sums = next((v for k, v in change.items() if k.startswith(f"tsis {t['split']} per-vertex sums")), None)
            row("point lights: a material change (setMaterial: R_d tables, R_p, local filter) and the per-vertex "
                "sums after it, median (min .. max)",
                f"{fmt(change[key]['median_ms'])} ms ({fmt(change[key]['min_ms'])} .. {fmt(change[key]['max_ms'])})"
                + (f" + {fmt(sums['median_ms'])} ms" if sums else ""),
                "<= 20 ms before the next frame", "tsis")

    cache_paths = runs_of("cache", ".log")
    if all(os.path.exists(p) for p in cache_paths):
        cs = [parse_cache_log(read_text(p)) for p in cache_paths]
        if all(cs):
            c = median_tree(cs)
            row("point light by the translucent irradiance cache (Keng et al. 2006; bunny, Marble, 40 mm, "
                "1024 x 1024, defaults): T_cache / T_JB on the same samples and octree, speedup in the same run; "
                "caches per hit pixel; relative RMSE against Jensen-Buhler",
                f"{fmt(c['cache_seconds'])} s / {fmt(c['jb_seconds'])} s, **{fmt(c['speedup'])}x**"
                f"{sp(spread_of(cs, 'speedup'))}; "
                f"{c['cache_share']}% ({c['caches']:,} of {c['hit_pixels']:,}); {100 * c['vs_jb']:.2f}%",
                ">= 10x faster than Jensen-Buhler", "cache")

    # Live materials (prt-bench-edit; each repeats inside its own run).
    edit_path, edit_blocked_path = os.path.join(out, "edit.json"), os.path.join(out, "edit_blocked.json")
    edit = load_json(edit_path) if os.path.exists(edit_path) else None
    if edit:
        e = edit["edit"]
        row(f"live material: an edit with the light still (bunny, {edit['vertices']:,} vertices, editable file at "
            f"the defaults, J = {edit['profiles']}: weights + J multiply-adds per vertex and channel), median "
            f"(min..max) of {e['runs']}",
            f"**{fmt(e['median_ms'])} ms** ({fmt(e['min_ms'])}..{fmt(e['max_ms'])})", "<= 5 ms", "edit")
        if "light_change_ratio" in edit:
            row("live material: a light change on the recombined editable file / on a plain per-vertex file "
                "(relight kernels, medians in the same run); the editable file's bytes / the plain file's",
                f"{fmt(edit['light_change']['median_ms'])} / {fmt(edit['plain_light_change']['median_ms'])} ms, "
                f"**{edit['light_change_ratio']:.2f}x**; {edit['transport_bytes'] / edit['plain_bytes']:.2f}x",
                "<= 3x; <= 4x", "edit")
    if os.path.exists(edit_blocked_path):
        eb = load_json(edit_blocked_path)
        if "light_change_ratio" in eb:
            per_vertex = (f"; {eb['transport_bytes'] / edit['plain_bytes']:.2f}x the plain per-vertex file's bytes"
                          if edit and "plain_bytes" in edit else "")
            row("live material, blocked editable file (nested lists, 216 per block): a light change / on the "
                "default blocked file (medians in the same run); its bytes",
                f"{fmt(eb['light_change']['median_ms'])} / {fmt(eb['plain_light_change']['median_ms'])} ms, "
                f"**{eb['light_change_ratio']:.2f}x**{per_vertex}",
                "<= 3x; <= 1x the per-vertex file's bytes", "edit_blocked")

    lines = [
        f"Measured {meta.get('date', '?')} on {meta.get('cpu', '?')} ({meta.get('threads', '?')} threads, "
        f"{meta.get('memory_gib', '?')} GiB), commit {meta.get('commit', '?')}; load average "
        f"{meta.get('load_start', '?')} at the start, {meta.get('load_end', '?')} at the end."
        + (f" Pass 1, the precomputes, the file relights and the cache: medians of {repeat} runs, "
           "(min..max) after the headline figures." if repeat > 1 else ""),
        "",
        "| what | measured | goal | command |",
        "|---|---|---|---|",
    ]
    lines += [f"| {a} | {b} | {c} | {d} |" for a, b, c, d in rows]
    text = "\n".join(lines) + "\n"
    print()
    print(text, end="")
    path = os.path.join(out, "summary.md")
    tmp = path + f".tmp.{os.getpid()}"
    with open(tmp, "w") as f:
        f.write(text)
    os.replace(tmp, path)
    print(f"\nwrote {path}")


if __name__ == "__main__":
    main()
