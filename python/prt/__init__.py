"""Translucent precomputed radiance transport from Python (docs/python.md).

Precompute light transport through a translucent object (dipole multiple scattering,
single scattering) into per-vertex Haar wavelet vectors, relight it under any
environment, render frames, and compare them, with numpy arrays in and out.

    import prt
    t = prt.precompute("data/meshes/bunny.off", size_mm=30, material="Marble", cubemap_size=16)
    env = prt.load_environment("data/envmaps/sunset.exr")
    radiance = prt.relight(t, env.light_vector(t.cubemap_size))   # (V, 3) float32

Errors raise FileNotFoundError (a missing file), ValueError (any other bad input) or
TypeError (a wrong argument type), with the command line's one-line message.
"""

from ._prt import *  # noqa: F401,F403
from ._prt import __doc__ as _native_doc  # noqa: F401

def tqdm_progress(**tqdm_arguments):
    """A progress callable for prt.precompute that draws one tqdm bar per stage.

    Needs tqdm (Debian: python3-tqdm); any other callable taking
    (stage, done, total, unit) works as well.
    """
    from tqdm import tqdm

    state = {"stage": None, "bar": None}

    def update(stage, done, total, unit):
        if stage != state["stage"]:
            if state["bar"] is not None:
                state["bar"].close()
            state["stage"] = stage
            state["bar"] = tqdm(total=total, desc=stage, unit=" " + unit, **tqdm_arguments)
        bar = state["bar"]
        bar.update(done - bar.n)
        if done >= total:
            bar.close()

    return update


__all__ = [name for name in dir() if not name.startswith("_")]
