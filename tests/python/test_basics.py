"""Meshes, materials, images and comparisons from Python against the library's own
closed forms and the command-line tools."""

import math

import numpy as np
import pytest

import prt
from conftest import run_tool


def test_mesh_arrays_are_views_of_the_loaded_mesh(scene):
    mesh = prt.load_mesh(str(scene / "torus.ply"))
    v, f, n = mesh.vertices, mesh.faces, mesh.normals
    assert v.shape == (1152, 3) and v.dtype == np.float32
    assert f.shape == (2304, 3) and f.dtype == np.uint32
    assert n.shape == v.shape
    # No copies: two reads share the mesh's memory, and the arrays are read-only views.
    assert np.shares_memory(mesh.vertices, v)
    assert not v.flags.writeable
    with pytest.raises(ValueError):
        v[0, 0] = 1.0
    # The view keeps the mesh alive after the Python name is gone.
    del mesh
    assert np.isfinite(v).all()
    # Unit normals; a torus has Euler characteristic 0.
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-5)
    m = prt.load_mesh(str(scene / "torus.ply"))
    assert m.report["euler_characteristic"] == 0
    # The area from the arrays equals the library's.
    a, b, c = (v[f[:, k]].astype(np.float64) for k in range(3))
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum()
    assert area == pytest.approx(m.area, rel=1e-9)


def test_mesh_scale_and_save_round_trip(scene, tmp_path):
    mesh = prt.load_mesh(str(scene / "torus.ply"), size_mm=20)
    lo, hi = (np.array(x) for x in mesh.bounds)
    assert np.linalg.norm(hi - lo) == pytest.approx(20.0, rel=1e-6)
    raw = prt.load_mesh(str(scene / "torus.ply"))
    assert np.allclose(mesh.vertices, raw.vertices * mesh.mm_per_unit, rtol=1e-6)
    # The transport file records the same scale prt-precompute applied.
    info = prt.transport_info(str(scene / "torus.prt"))
    assert info["mm_per_unit"] == pytest.approx(mesh.mm_per_unit, rel=1e-12)
    mesh.save(str(tmp_path / "copy.ply"))
    back = prt.load_mesh(str(tmp_path / "copy.ply"))
    assert np.array_equal(back.vertices, mesh.vertices)
    assert np.array_equal(back.faces, mesh.faces)
    assert back.fingerprint == mesh.fingerprint


def dipole_total_reflectance(alpha_prime, eta):
    """Jensen et al. 2001, Eq. 8 of the dipole's plane integral, with Egan-Hilgeman's F_dr."""
    fdr = -1.440 / eta**2 + 0.710 / eta + 0.668 + 0.0636 * eta
    a = (1 + fdr) / (1 - fdr)
    s = np.sqrt(3 * (1 - alpha_prime))
    return 0.5 * alpha_prime * (1 + np.exp(-4.0 / 3.0 * a * s)) * np.exp(-s)


def test_materials_follow_the_dipole_closed_forms():
    names = prt.material_names()
    assert "Marble" in names and "Skin1" in names and len(names) == len(set(names))
    for name in names:
        m = prt.material(name)
        sa, ss = np.array(m.sigma_a), np.array(m.sigma_s_prime)
        st = sa + ss
        assert np.allclose(m.sigma_t_prime, st)
        assert np.allclose(m.alpha_prime, ss / st)
        assert np.allclose(m.sigma_tr, np.sqrt(3 * sa * st))
        assert np.allclose(m.zr, 1 / st)
        assert np.allclose(m.total_diffuse_reflectance, dipole_total_reflectance(ss / st, m.eta), rtol=1e-9)
        # The artist's pair inverts back to the coefficients (Spectralon, sigma_a = 0, has
        # an infinite mean free path: no pair gives it).
        colour, mfp = m.appearance
        if not np.isfinite(mfp).all():
            assert name == "Spectralon"
            continue
        back = prt.material_from_appearance(colour, mfp, eta=m.eta)
        assert np.allclose(back.sigma_a, sa, rtol=1e-6) and np.allclose(back.sigma_s_prime, ss, rtol=1e-6)
    # Scaling the coefficients by s is the same look on an object 1/s the size.
    m = prt.material("Ketchup")
    assert np.allclose(np.array(m.scaled(2.0).sigma_tr), 2 * np.array(m.sigma_tr))
    custom = prt.Material(sigma_a=[0.01, 0.02, 0.03], sigma_s_prime=1.5, eta=1.4)
    assert custom.sigma_s_prime == (1.5, 1.5, 1.5) and custom.eta == 1.4
    assert prt.material("sigma:0.01,0.02,0.03:1.5,1.5,1.5", eta=1.4).sigma_a == custom.sigma_a


def test_images_round_trip_and_compare_matches_prt_compare(scene, tmp_path):
    rng = np.random.default_rng(7)
    image = rng.random((24, 32, 4), dtype=np.float32)
    image[..., 3] = (rng.random((24, 32)) > 0.3).astype(np.float32)
    prt.write_exr(str(tmp_path / "a.exr"), image)
    assert np.array_equal(prt.read_image(str(tmp_path / "a.exr")), image)
    other = image.copy()
    other[..., :3] *= 1.0 + 0.05 * rng.standard_normal((24, 32, 3)).astype(np.float32)
    prt.write_exr(str(tmp_path / "b.exr"), other)
    result = prt.compare(other, image)
    from_files = prt.compare(str(tmp_path / "b.exr"), str(tmp_path / "a.exr"))
    assert result["text"] == from_files["text"]
    cli = run_tool("prt-compare", tmp_path / "b.exr", tmp_path / "a.exr").stdout
    assert result["text"] in cli
    # The relative RMSE over the reference's alpha by hand.
    mask = image[..., 3] > 0.5
    diff = (other[..., :3] - image[..., :3])[mask].astype(np.float64)
    expected = math.sqrt((diff**2).sum() / (image[..., :3][mask].astype(np.float64) ** 2).sum())
    assert result["relative_rmse"] == pytest.approx(expected, rel=1e-6)
    assert prt.compare(image, image)["relative_rmse"] == 0.0


def test_tone_mapping_follows_the_formulas_and_reaches_the_png(tmp_path):
    rng = np.random.default_rng(3)
    image = (rng.random((16, 16, 4)) * 4.0).astype(np.float32)
    image[..., 3] = (rng.random((16, 16)) > 0.25).astype(np.float32)
    # Chang et al. 2008 (R / (1 + R), the printed (1 + R) / R corrected) over the mean
    # luminance of the object pixels, one stop up.
    rgb = image[..., :3].astype(np.float64)
    lum = rgb @ np.array([0.2126, 0.7152, 0.0722])
    r = 2.0 * rgb / lum[image[..., 3] > 0.5].mean()
    assert np.allclose(prt.tonemap(image, exposure=1.0, tonemap="chang"), r / (1.0 + r), atol=1e-6)
    x = 0.5 * rgb
    filmic = np.clip(x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0)
    assert np.allclose(prt.tonemap(image, exposure=-1.0, tonemap="filmic"), filmic, atol=2e-6)
    # The PNG holds the sRGB encoding of those values, to the 8-bit rounding.
    prt.write_png(str(tmp_path / "f.png"), image, exposure=-1.0, tonemap="filmic")
    back = prt.read_image(str(tmp_path / "f.png")).astype(np.float64)
    srgb = np.where(filmic <= 0.0031308, 12.92 * filmic, 1.055 * filmic ** (1 / 2.4) - 0.055)
    assert np.abs(back - srgb).max() <= 0.5 / 255 + 1e-6
    with pytest.raises(ValueError, match="--tonemap: unknown operator 'gamma'"):
        prt.tonemap(image, tonemap="gamma")


def test_install_script_puts_the_module_in_a_venv(tmp_path):
    import os
    import subprocess
    import sys
    from pathlib import Path

    from conftest import BIN

    source = Path(os.environ.get("PRT_SOURCE", Path(__file__).resolve().parents[2]))
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", "--without-pip", str(venv)], check=True)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    env["BUILD_DIR"] = str(BIN.parent)
    result = subprocess.run(["bash", str(source / "tools/install-python.sh"), str(venv / "bin/python")],
                            capture_output=True, text=True, env=env)
    assert result.returncode == 0, result.stderr
    check = subprocess.run([str(venv / "bin/python"), "-c", "import prt; print(prt.__file__, prt.material('Skin1').sigma_a)"],
                           capture_output=True, text=True, env=env)
    assert check.returncode == 0, check.stderr
    assert str(venv) in check.stdout and "(0.032, 0.17, 0.48)" in check.stdout
