"""No leak over 1,000 load / relight / render cycles: the resident set stays bounded."""

import gc

import numpy as np

import prt


def resident_bytes():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * 4096


def cycle(scene):
    t = prt.load_transport(str(scene / "torus_ss.prt"))
    env = prt.Environment(np.full((16, 32, 3), 0.5, np.float32))
    radiance = prt.relight(t, env.light_vector(t.cubemap_size))
    mesh = prt.load_mesh(str(scene / "torus.ply"))
    views = (mesh.vertices, t.vectors("ms")["values"], env.pixels)
    try:
        prt.load_transport(str(scene / "missing.prt"))
    except FileNotFoundError:
        pass
    return float(radiance.sum()) + sum(float(v.sum()) for v in views)


def test_resident_memory_stays_bounded(scene):
    # Warm up allocators and caches, then measure the growth over 1,000 cycles.
    for _ in range(50):
        cycle(scene)
    gc.collect()
    before = resident_bytes()
    for _ in range(1000):
        cycle(scene)
    gc.collect()
    growth = resident_bytes() - before
    # One cycle holds ~3 MB (the transport file twice: arrays and scratch); a leak of
    # any one of them would add over 1 GB. 20 MB allows the allocator's own slack.
    assert growth < 20 * 1024 * 1024, growth
