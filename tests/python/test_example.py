"""The example a user runs (python/examples/coefficient_sweep.py), on a small torus so
it never goes stale: it must write its plot, and its error must fall as K grows."""

import os
import subprocess
import sys
from pathlib import Path

SOURCE = Path(os.environ.get("PRT_SOURCE", Path(__file__).resolve().parents[2]))


def test_coefficient_sweep_runs_and_the_error_falls(scene, tmp_path):
    result = subprocess.run(
        [sys.executable, str(SOURCE / "python/examples/coefficient_sweep.py"), "--mesh", str(scene / "torus.ply"),
         "--environments", str(scene / "sky.exr"), str(scene / "dusk.exr"), "--size-mm", "20", "--cubemap-size", "8",
         "--samples", "2000", "--size", "64", "--out", str(tmp_path)],
        capture_output=True, text=True, env=os.environ.copy())
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "coefficients.png").stat().st_size > 1000
    assert (tmp_path / "torus.prt").exists()
    for line in result.stdout.splitlines():
        if line.startswith(("sky:", "dusk:")):
            errors = [float(item.split()[-1].rstrip("%")) for item in line.split(": ", 1)[1].split(", ")]
            assert errors[-1] == 0.0  # every coefficient: the reference itself
            assert errors[0] > errors[-2] >= 0.0, line
            break
    else:
        raise AssertionError(result.stdout)
