"""prt.precompute against prt-precompute: the same file, progress to a callable, the
GIL released, cancelling cleanly."""

import threading
import time

import numpy as np
import pytest

import prt
from conftest import run_tool, tool_error

SMALL = dict(size_mm=20, cubemap_size=8, samples=2000)


def test_precompute_writes_the_command_lines_file(scene, tmp_path):
    calls = []
    t = prt.precompute(str(scene / "torus.ply"), str(tmp_path / "py.prt"), progress=lambda *a: calls.append(a),
                       components="ms,ss", **SMALL)
    run_tool("prt-precompute", scene / "torus.ply", "--size-mm", 20, "--cubemap-size", 8, "--samples", 2000,
             "--components", "ms,ss", "-q", "-o", tmp_path / "cli.prt")
    # Only the tool line and the command may differ; compare what was computed.
    cli = prt.load_transport(str(tmp_path / "cli.prt"))
    for component in ("ms", "ss"):
        a, b = t.vectors(component), cli.vectors(component)
        for key in ("offsets", "indices", "values", "scales"):
            assert np.array_equal(a[key], b[key]), (component, key)
    assert t.parameters["input_digest"] == cli.parameters["input_digest"]
    assert t == prt.load_transport(str(tmp_path / "py.prt"))
    assert t.summary["components"] == "ms,ss"
    assert t.settings["cubemap_size"] == 8
    # Progress: each stage reported, done never decreasing within a stage, ending at total.
    stages = {}
    for stage, done, total, unit in calls:
        assert 0 <= done <= total
        assert done >= stages.get(stage, (0, 0))[0]
        stages[stage] = (done, total)
    assert any(s.startswith("pass 2") for s in stages)
    assert all(done == total for done, total in stages.values()), stages
    # Up to date: the second call reuses the file.
    again = prt.precompute(str(scene / "torus.ply"), str(tmp_path / "py.prt"), components="ms,ss", **SMALL)
    assert again.summary["skipped"] is True


def test_precompute_without_output_returns_the_transport(scene):
    t = prt.precompute(str(scene / "torus.ply"), editable=True, **SMALL)
    assert t.editable and t.path == ""
    assert t.vertex_count == 1152


def test_bad_options_raise_the_command_lines_message(scene, tmp_path):
    with pytest.raises(ValueError) as e:
        prt.precompute(str(scene / "torus.ply"), size_mm=-3)
    assert str(e.value) == tool_error("prt-precompute", scene / "torus.ply", "--size-mm", -3, "-o", tmp_path / "x.prt")
    with pytest.raises(ValueError) as e:
        prt.precompute(str(scene / "torus.ply"), material="Marmor")
    assert str(e.value) == tool_error("prt-precompute", scene / "torus.ply", "--material", "Marmor", "-o",
                                      tmp_path / "x.prt")
    with pytest.raises(ValueError, match="--sampels"):
        prt.precompute(str(scene / "torus.ply"), sampels=100)
    with pytest.raises(FileNotFoundError) as e:
        prt.precompute("missing.obj")
    assert str(e.value) == tool_error("prt-precompute", "missing.obj", "-o", tmp_path / "x.prt")
    with pytest.raises(TypeError, match="seed"):
        prt.precompute(str(scene / "torus.ply"), seed={"a": 1})
    with pytest.raises(TypeError, match="progress"):
        prt.precompute(str(scene / "torus.ply"), progress=3)
    assert not (tmp_path / "x.prt").exists()


def test_the_gil_is_released_during_a_precompute(scene):
    ticks = []
    stop = threading.Event()

    def count():
        while not stop.is_set():
            ticks.append(time.monotonic())
            time.sleep(0.002)

    thread = threading.Thread(target=count)
    thread.start()
    start = time.monotonic()
    # Long enough to see the other thread run (a second or so).
    prt.precompute(str(scene / "torus.ply"), size_mm=20, cubemap_size=16, samples=4000)
    end = time.monotonic()
    stop.set()
    thread.join()
    during = [t for t in ticks if start < t < end]
    # With the GIL held for the whole call the thread could not tick in between.
    assert len(during) >= 10, (len(during), end - start)


def test_an_interrupt_cancels_cleanly(scene, tmp_path):
    output = tmp_path / "cancelled.prt"
    output.write_bytes(b"old output")

    def interrupt(stage, done, total, unit):
        if stage.startswith("pass 2"):
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        prt.precompute(str(scene / "torus.ply"), str(output), progress=interrupt, force=True, size_mm=20,
                       cubemap_size=16, samples=4000)
    # The good file is untouched and no temporary file is left beside it.
    assert output.read_bytes() == b"old output"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cancelled.prt"]
    # The cancel does not outlive the call.
    assert prt.precompute(str(scene / "torus.ply"), **SMALL).vertex_count == 1152


def test_ctrl_c_stops_a_precompute_in_a_script(scene, tmp_path):
    import os
    import signal
    import subprocess
    import sys

    output = tmp_path / "interrupted.prt"
    script = (
        "import prt, sys\n"
        "print('started', flush=True)\n"
        f"prt.precompute({str(scene / 'torus.ply')!r}, {str(output)!r}, size_mm=20, cubemap_size=32, samples=60000)\n"
    )
    child = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             text=True, env=os.environ.copy())
    assert child.stdout.readline().strip() == "started"
    time.sleep(1.0)
    child.send_signal(signal.SIGINT)
    start = time.monotonic()
    _, err = child.communicate(timeout=60)
    assert child.returncode != 0
    assert "KeyboardInterrupt" in err
    assert time.monotonic() - start < 10  # a cancel, not the whole job (about a minute)
    assert not output.exists()
    assert list(tmp_path.iterdir()) == []


def test_tqdm_draws_one_bar_per_stage(scene):
    import io

    out = io.StringIO()
    t = prt.precompute(str(scene / "torus.ply"), progress=prt.tqdm_progress(file=out, mininterval=0), **SMALL)
    assert t.vertex_count == 1152
    text = out.getvalue()
    # tqdm's own lines: each stage's bar reached 100% of its total.
    assert "pass 1 (irradiance transport): 100%" in text and "2000/2000" in text, text
    assert "pass 2 (multiple scattering): 100%" in text and "1152/1152" in text, text
