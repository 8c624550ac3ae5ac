"""prt-pointlight and prt-reference from Python: the images equal the tools' EXRs bit
for bit, the extra images come back by name, bad options raise the tools' messages."""

import numpy as np
import pytest

import prt
from conftest import run_tool, tool_error

LIGHT = "point:0,40,20:2"


@pytest.mark.parametrize(
    "options,extra",
    [
        (dict(), []),
        (dict(method="jb", near_field="cells", compare_brute=True), ["--method", "jb", "--near-field", "cells", "--compare-brute"]),
        (dict(method="tsis", atlas_size=256, tsis_samples=400, compare_jb=True),
         ["--method", "tsis", "--atlas-size", "256", "--tsis-samples", "400", "--compare-jb"]),
        (dict(material="Skin1", samples="poisson", sample_count=3000, seed=7, eye=[-30, 20, 40], cache_image=True),
         ["-m", "Skin1", "--samples", "poisson", "--sample-count", "3000", "--seed", "7", "--eye=-30,20,40",
          "--cache-image"]),
    ],
)
def test_point_lights_equal_prt_pointlight(scene, tmp_path, options, extra):
    images = prt.render_point_lights(str(scene / "torus.ply"), [LIGHT, "dir:1,1,0:0.5"], size_mm=20, width=64,
                                     height=48, **options)
    run_tool("prt-pointlight", scene / "torus.ply", "--light", LIGHT, "--light", "dir:1,1,0:0.5", "--size-mm", 20,
             "-W", 64, "-H", 48, *extra, "-o", tmp_path / "cli")
    assert images["image"].shape == (48, 64, 4)
    assert np.array_equal(images["image"], prt.read_image(str(tmp_path / "cli.exr")))
    for key in ("jb", "brute"):
        if (tmp_path / f"cli_{key}.exr").exists():
            assert np.array_equal(images[key], prt.read_image(str(tmp_path / f"cli_{key}.exr")))
    expected = {"image"} | {p.stem[len("cli_"):] for p in tmp_path.iterdir() if p.stem.startswith("cli_")}
    assert set(images) == expected
    assert images["image"][..., 3].sum() > 100


def test_point_light_animation_frames_come_back_by_number(scene):
    images = prt.render_point_lights(str(scene / "torus.ply"), LIGHT, size_mm=20, width=32, height=32,
                                     material_path="Marble:Ketchup", frames=3)
    assert sorted(images) == ["0000", "0001", "0002"]
    # Ketchup absorbs green and blue far more than Marble: the last frame is redder.
    first, last = images["0000"], images["0002"]
    mask = first[..., 3] > 0
    ratio = lambda im: im[..., 0][mask].sum() / im[..., 2][mask].sum()
    assert ratio(last) > 2 * ratio(first)


def test_reference_equals_prt_reference(scene, tmp_path):
    options = dict(transport=str(scene / "torus_ss.prt"), environment=str(scene / "sky.exr"), width=40, height=32,
                   pixel_stride=3, component_images=True, env_samples=64)
    images = prt.render_reference(str(scene / "torus.ply"), **options)
    run_tool("prt-reference", scene / "torus.ply", "-t", scene / "torus_ss.prt", "-e", scene / "sky.exr", "-W", 40,
             "-H", 32, "--pixel-stride", 3, "--component-images", "--env-samples", 64, "-o", tmp_path / "cli")
    assert sorted(images) == ["image", "ms", "ss"]
    for key, name in (("image", "cli"), ("ms", "cli_ms"), ("ss", "cli_ss")):
        assert np.array_equal(images[key], prt.read_image(str(tmp_path / f"{name}.exr"))), key
    # On the object the components add up to the frame (each component image shows the
    # environment behind the object, as the frame does).
    mask = images["image"][..., 3] > 0
    assert mask.sum() > 50
    total = images["ms"][..., :3] + images["ss"][..., :3]
    assert np.allclose(total[mask], images["image"][..., :3][mask], rtol=1e-5, atol=1e-7)


def test_reference_under_lights_and_compare(scene):
    ref = prt.render_reference(str(scene / "torus.ply"), [LIGHT], size_mm=20, width=48, height=48)["image"]
    jb = prt.render_point_lights(str(scene / "torus.ply"), LIGHT, size_mm=20, width=48, height=48, method="jb")["image"]
    result = prt.compare(jb, ref)
    # Jensen-Buhler over face centroids against the independent reference: a few percent.
    assert 0.0 < result["relative_rmse"] < 0.08, result["text"]


def test_bad_options_raise_the_tools_messages(scene, tmp_path, monkeypatch):
    monkeypatch.chdir(scene)
    cases = [
        (lambda: prt.render_point_lights("torus.ply", []), ["prt-pointlight", "torus.ply", "-o", "x"]),
        (lambda: prt.render_point_lights("torus.ply", LIGHT, method="magic"),
         ["prt-pointlight", "torus.ply", "--light", LIGHT, "--method", "magic", "-o", "x"]),
        (lambda: prt.render_point_lights("torus.ply", "point:1,2:1"),
         ["prt-pointlight", "torus.ply", "--light", "point:1,2:1", "-o", "x"]),
        (lambda: prt.render_point_lights("torus.ply", LIGHT, atlas_size=100, method="tsis"),
         ["prt-pointlight", "torus.ply", "--light", LIGHT, "--method", "tsis", "--atlas-size", "100", "-o", "x"]),
        (lambda: prt.render_reference("torus.ply", transport="torus.prt", environment="nowhere.exr"),
         ["prt-reference", "torus.ply", "-t", "torus.prt", "-e", "nowhere.exr", "-o", "x"]),
        (lambda: prt.render_reference("torus.ply", transport="torus.prt", environment="sky.exr", pixel_stride=0),
         ["prt-reference", "torus.ply", "-t", "torus.prt", "-e", "sky.exr", "--pixel-stride", "0", "-o", "x"]),
    ]
    for call, command in cases:
        with pytest.raises((ValueError, FileNotFoundError)) as e:
            call()
        assert str(e.value) == tool_error(*command, cwd=scene)
    with pytest.raises(ValueError, match="--methd"):
        prt.render_point_lights("torus.ply", LIGHT, methd="jb")
    with pytest.raises(TypeError, match="output"):
        prt.render_point_lights("torus.ply", LIGHT, output="x")
    with pytest.raises(TypeError, match="width"):
        prt.render_point_lights("torus.ply", LIGHT, width={"a": 1})
    assert not (scene / "x.exr").exists()


def test_reference_reports_progress_and_cancels(scene):
    # Progress and the cancel do not depend on the reference's accuracy: 4,000 samples
    # instead of the convergence rule's (about 9 s a call on 2 cores).
    stages = set()

    def record(stage, done, total, unit):
        stages.add(stage)

    prt.render_reference(str(scene / "torus.ply"), [LIGHT], size_mm=20, width=24, height=24, samples=4000,
                         progress=record)
    assert stages, "no stage reported"

    def interrupt(stage, done, total, unit):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        prt.render_reference(str(scene / "torus.ply"), [LIGHT], size_mm=20, width=64, height=64, samples=4000,
                             progress=interrupt)
    # The cancel is over: the next call runs.
    again = prt.render_reference(str(scene / "torus.ply"), [LIGHT], size_mm=20, width=16, height=16, samples=4000)
    assert again["image"].shape == (16, 16, 4)
