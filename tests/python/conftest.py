"""Fixtures of the Python module's tests (tests/python; docs/python.md).

CTest runs them with PYTHONPATH = <build>/python and PRT_BIN = <build>/bin, so each
test can run the command-line tool beside the Python call it checks.
"""

import os
import subprocess
from pathlib import Path

import pytest

BIN = Path(os.environ.get("PRT_BIN", Path(__file__).resolve().parents[2] / "build" / "bin"))


def run_tool(*args, check=True, cwd=None):
    """Runs a prt-* tool; returns the CompletedProcess (text output)."""
    program = str(BIN / args[0])
    result = subprocess.run([program, *map(str, args[1:])], capture_output=True, text=True, cwd=cwd)
    if check and result.returncode != 0:
        raise AssertionError(f"{args[0]} failed ({result.returncode}): {result.stderr}")
    return result


def tool_error(*args, cwd=None):
    """The one-line error a tool prints for a bad input, without its "<program>: error: " prefix."""
    result = run_tool(*args, check=False, cwd=cwd)
    assert result.returncode == 1, (args, result.returncode, result.stderr)
    lines = [l for l in result.stderr.splitlines() if ": error: " in l]
    assert len(lines) == 1, result.stderr
    return lines[0].split(": error: ", 1)[1]


@pytest.fixture(scope="session")
def scene(tmp_path_factory):
    """The viewer test's generated scene (torus, sphere, sky.exr, dusk.exr) and four
    small transport files of the torus: multiple scattering (blocked, the default, and per
    vertex), + single scattering, editable."""
    root = tmp_path_factory.mktemp("scene")
    run_tool("prt-make-test-scene", "scene", root)
    common = ["--size-mm", 20, "--cubemap-size", 8, "--samples", 2000, "-q"]
    run_tool("prt-precompute", root / "torus.ply", *common, "-o", root / "torus.prt")
    run_tool("prt-precompute", root / "torus.ply", *common, "--block-coefficients", 0, "-o",
             root / "torus_vertexwise.prt")
    run_tool("prt-precompute", root / "torus.ply", *common, "--components", "ms,ss", "-o", root / "torus_ss.prt")
    run_tool("prt-precompute", root / "torus.ply", *common, "--editable", "-o", root / "torus_edit.prt")
    return root
