"""Transport files, environments, the relight kernel, live materials and render's
frames from Python, against brute force, closed forms and prt-relight's EXRs."""

import numpy as np
import pytest

import prt
from conftest import run_tool


def dense_vectors(transport, component="ms"):
    """(V, 6 N^2 + T, 3) dense float64 vectors from the stored arrays (the slow path),
    per-vertex or blocked (the layouts of docs/transport-format.md, read here by numpy
    alone)."""
    arrays = transport.vectors(component)
    offsets, indices = arrays["offsets"], arrays["indices"]
    n = transport.cubemap_size
    dense = np.zeros((transport.vertex_count, 6 * n * n + transport.sh_terms, 3))
    values = arrays["values"].astype(np.float64)
    if not arrays["blocked"]:
        scales = arrays["scales"].astype(np.float64)
        sh_from = arrays["sh_from"]
        for v in range(transport.vertex_count):
            rows = slice(offsets[v], offsets[v + 1])
            scale = np.broadcast_to(scales[v], (offsets[v + 1] - offsets[v], 3))
            if sh_from is not None:  # 8-bit Haar values: the SH part has scales of its own
                sh = indices[rows] >= sh_from
                scale = np.where(sh[:, None], arrays["sh_scales"][v], scales[v])
            dense[v, indices[rows]] = values[rows] * scale
        return dense
    order = arrays["order"]
    for b in range(len(offsets) - 1):
        rows = slice(offsets[b], offsets[b + 1])
        idx = indices[rows].astype(np.int64)
        sh = idx >= (arrays["sh_from"] if arrays["sh_from"] is not None else np.iinfo(np.int64).max)
        for lane in range(16):
            slot = 16 * b + lane
            if slot >= transport.vertex_count:
                break
            scale = np.where(sh[:, None], arrays["sh_scales"][b, :, lane] if sh.any() else 0.0,
                             arrays["scales"][b, :, lane])
            dense[order[slot], idx] = values[rows, :, lane] * scale
    return dense


def test_transport_round_trip_and_info(scene, tmp_path):
    t = prt.load_transport(str(scene / "torus_ss.prt"), mesh=str(scene / "torus.ply"))
    assert t.components == ["ms", "ss"]
    assert t.cubemap_size == 8 and t.vertex_count == 1152
    assert t.parameters["material"] == "Marble"
    t.save(str(tmp_path / "copy.prt"))
    back = prt.load_transport(str(tmp_path / "copy.prt"))
    assert back == t
    assert (tmp_path / "copy.prt").read_bytes() == (scene / "torus_ss.prt").read_bytes()
    info = prt.transport_info(str(scene / "torus_ss.prt"))
    assert [c["name"] for c in info["components"]] == ["ms", "ss"]
    assert info["text"] in run_tool("prt-relight", "info", scene / "torus_ss.prt").stdout
    # The stored arrays and the dequantized vector of a vertex agree.
    v = 17
    idx, rgb = t.vertex_vector(v, "ms")
    assert t.vectors("ms")["blocked"]  # prt-precompute's default layout
    dense = dense_vectors(t, "ms")[v]
    assert set(np.flatnonzero(np.any(dense != 0, axis=1))) <= set(idx.tolist())
    assert np.allclose(rgb, dense[idx], rtol=1e-6, atol=0)
    per_vertex = prt.load_transport(str(scene / "torus_vertexwise.prt"))
    assert not per_vertex.vectors("ms")["blocked"]
    idx, rgb = per_vertex.vertex_vector(v, "ms")
    dense = dense_vectors(per_vertex, "ms")[v]
    assert set(np.flatnonzero(np.any(dense != 0, axis=1))) <= set(idx.tolist())
    assert np.allclose(rgb, dense[idx], rtol=1e-6, atol=0)
    with pytest.raises(IndexError):
        t.vertex_vector(1152)
    with pytest.raises(ValueError, match="'xs' is not in the file"):
        t.vectors("xs")
    # A mesh that is not the file's is refused.
    with pytest.raises(ValueError, match="torus.prt"):
        prt.load_transport(str(scene / "torus.prt"), mesh=str(scene / "sphere.ply"))


def test_relight_equals_the_dense_dot_product(scene):
    t = prt.load_transport(str(scene / "torus_ss.prt"))
    env = prt.load_environment(str(scene / "sky.exr"))
    light = env.light_vector(t.cubemap_size, rotation=30.0)
    assert light.rgb.shape == (6 * 64, 3)
    assert light.relative_l2_error == 0.0
    full = np.concatenate([light.rgb, light.sh]) if light.sh.size else light.rgb
    expected = np.einsum("vkc,kc->vc", dense_vectors(t, "ms"), full[: 6 * 64 + t.sh_terms])
    expected += np.einsum("vkc,kc->vc", dense_vectors(t, "ss"), full[: 6 * 64 + t.sh_terms])
    radiance = prt.relight(t, light)
    assert radiance.shape == (1152, 3) and radiance.dtype == np.float32
    assert np.allclose(radiance, expected, rtol=2e-5, atol=1e-6 * expected.max())
    # out= is filled in place, and the components add up.
    out = np.empty((1152, 3), np.float32)
    assert prt.relight(t, light, out=out) is not None
    assert np.array_equal(out, radiance)
    ms, ss = prt.relight(t, light, "ms"), prt.relight(t, light, "ss")
    assert np.allclose(ms + ss, radiance, rtol=1e-5, atol=1e-7)
    # Linear in the light: twice the environment, twice the radiance.
    double = prt.Environment(2 * env.pixels)
    assert np.allclose(prt.relight(t, double.light_vector(8, rotation=30.0)), 2 * radiance, rtol=1e-5)


def test_constant_environment_gives_the_rotation_invariant_answer(scene):
    t = prt.load_transport(str(scene / "torus.prt"))
    env = prt.Environment(np.full((32, 64, 3), 0.5, np.float32))
    assert np.allclose(env.integral(), 4 * np.pi * 0.5, rtol=1e-6)
    a = prt.relight(t, env.light_vector(8))
    b = prt.relight(t, env.light_vector(8, rotation=prt.rotation([1, 1, 0], 73.0)))
    assert np.allclose(a, b, rtol=1e-4)
    assert np.allclose(prt.rotation_y(90.0) @ [1.0, 0.0, 0.0], [0.0, 0.0, -1.0], atol=1e-12)


@pytest.mark.parametrize(
    "extra",
    [
        [],
        ["--env-rotation", "40", "--specular", "--components", "ms,ss", "-L", "50"],
        ["--azimuth", "60", "--elevation", "-20", "--fov", "25"],
        ["--ss-path", "normal", "--components", "ss"],
        ["--sun-split", "--sun-threshold", "2", "--components", "ms,ss"],
        ["--sun-split", "--sun-method", "cache", "--sun-cell", "20"],
    ],
)
def test_render_equals_prt_relight_render_bit_for_bit(scene, tmp_path, extra):
    run_tool("prt-relight", "render", scene / "torus.ply", "-t", scene / "torus_ss.prt", "-e", scene / "sky.exr",
             "-W", 96, "-H", 64, "-o", tmp_path / "cli", *extra)
    cli = prt.read_image(str(tmp_path / "cli.exr"))
    obj = prt.load_object(str(scene / "torus.ply"), str(scene / "torus_ss.prt"))
    env = prt.load_environment(str(scene / "sky.exr"))
    options = dict(width=96, height=64)
    flags = iter(extra)
    names = {"--env-rotation": ("env_rotation", float), "--components": ("components", str),
             "-L": ("light_terms", int), "--azimuth": ("azimuth", float), "--elevation": ("elevation", float),
             "--fov": ("fov", float), "--ss-path": ("ss_path", str), "--sun-threshold": ("sun_threshold", float),
             "--sun-cell": ("sun_cell", float), "--sun-method": ("sun_method", str)}
    for flag in flags:
        if flag == "--specular":
            options["specular"] = True
        elif flag == "--sun-split":
            options["sun_split"] = True
        else:
            key, kind = names[flag]
            options[key] = kind(next(flags))
    image = prt.render(obj, env, **options)
    assert image.shape == (64, 96, 4) and image.dtype == np.float32
    assert np.array_equal(image, cli)
    assert image[..., 3].sum() > 100  # the object is in the frame


def test_object_relights_as_its_file_and_the_eyes_path_brightens_single_scattering(scene):
    # The object holds its isotropic single scattering as a one-term phase (for the
    # eye's-path factor); its per-vertex radiance is still the file's.
    t = prt.load_transport(str(scene / "torus_ss.prt"))
    obj = prt.load_object(str(scene / "torus.ply"), str(scene / "torus_ss.prt"))
    light = prt.load_environment(str(scene / "sky.exr")).light_vector(8)
    assert np.array_equal(obj.relight(light), prt.relight(t, light))
    assert np.array_equal(obj.relight(light, "ss"), prt.relight(t, light, "ss"))
    env = prt.load_environment(str(scene / "sky.exr"))
    eye = prt.render(obj, env, width=64, height=64, components="ss")
    normal = prt.render(obj, env, width=64, height=64, components="ss", ss_path="normal")
    inside = eye[..., 3] == 1
    ratio = eye[..., :3][inside].sum() / normal[..., :3][inside].sum()
    assert 1.01 < ratio < 1.3  # 1 at a normal view, 1.25 at grazing ones (eta 1.3)
    assert np.all(eye[..., :3][inside] >= normal[..., :3][inside] * (1 - 1e-6))
    with pytest.raises(ValueError, match="--ss-path"):
        prt.render(obj, env, width=8, height=8, ss_path="eye")


def test_editable_profiles_hold_8_bit_haar_values(scene):
    t = prt.load_transport(str(scene / "torus_edit.prt"))
    assert t.components == ["profiles:0", "profiles:1", "profiles:2", "profiles:3"]
    n = t.cubemap_size
    for name in t.components:
        arrays = t.vectors(name)
        assert arrays["haar_bits"] == 8 and arrays["sh_from"] == 6 * n * n
        haar = arrays["indices"] < arrays["sh_from"]
        assert np.abs(arrays["values"][haar]).max() == 127  # each vertex's largest Haar term
        assert np.abs(arrays["values"][~haar]).max() == 32767  # the SH part keeps 16 bits
        dense = dense_vectors(t, name)
        for v in (0, 400, t.vertex_count - 1):
            idx, rgb = t.vertex_vector(v, name)
            assert np.allclose(rgb, dense[v][idx], rtol=1e-6, atol=0)


def test_live_material_equals_render_with_material(scene, tmp_path):
    obj = prt.load_object(str(scene / "torus.ply"), str(scene / "torus_edit.prt"))
    assert obj.editable and obj.material.name == "Marble"
    env = prt.load_environment(str(scene / "dusk.exr"))
    light = env.light_vector(8)
    marble = obj.relight(light, "ms")
    weights = obj.weights
    line = obj.set_material("Skin1", size_mm=25.0)
    assert "Skin1" in line
    assert obj.material.name == "Skin1"
    assert not np.array_equal(obj.weights, weights)
    skin = obj.relight(light, "ms")
    assert not np.allclose(skin, marble, rtol=1e-2)
    # The per-profile path (J multiply-adds after an edit) equals the recombined vectors.
    obj.project_light(light)
    # They differ by the recombination's 16-bit quantization, ~1e-5 of each vertex's
    # largest coefficient (the C++ test's bound on the relative RMSE, 1e-4).
    projected = obj.relight_projected().astype(np.float64)
    assert np.linalg.norm(projected - skin) / np.linalg.norm(skin) < 1e-4
    # A frame after the edit equals render --material of the same file.
    run_tool("prt-relight", "render", scene / "torus.ply", "-t", scene / "torus_edit.prt", "-e", scene / "dusk.exr",
             "-W", 64, "-H", 64, "--material", "Skin1", "--size-mm", 25, "-o", tmp_path / "cli")
    image = prt.render(obj, env, width=64, height=64)
    assert np.array_equal(image, prt.read_image(str(tmp_path / "cli.exr")))
    # Outside the basis's range: refused in one line, the material kept.
    with pytest.raises(ValueError, match="outside every radial basis range"):
        obj.set_material("Spectralon")
    assert obj.material.name == "Skin1"
    plain = prt.load_object(str(scene / "torus.ply"), str(scene / "torus.prt"))
    with pytest.raises(ValueError, match="editable"):
        plain.set_material("Skin1")


def test_an_edited_objects_arrays_and_state_stay_consistent(scene, tmp_path):
    obj = prt.load_object(str(scene / "torus.ply"), str(scene / "torus_edit.prt"))
    before = obj.transport.vectors("ms")
    values = before["values"].copy()
    obj.set_material("Ketchup")
    # The arrays taken before the edit are copies: still readable, still the old material's.
    assert np.array_equal(before["values"], values)
    after = obj.transport.vectors("ms")["values"]
    assert after.shape != values.shape or not np.array_equal(after, values)
    # None keeps the material and changes the size; text keeps the size.
    obj.set_material(size_mm=24.0)
    assert obj.material.name == "Ketchup"
    assert "24 mm" in obj.set_material("Skin2")
    assert obj.material.name == "Skin2"
    # A refused light leaves the projection it had.
    env = prt.load_environment(str(scene / "sky.exr"))
    obj.project_light(env.light_vector(8))
    good = obj.relight_projected()
    with pytest.raises(ValueError, match="light"):
        obj.project_light(env.light_vector(4))
    assert np.array_equal(obj.relight_projected(), good)
    # Its transport no longer matches its file's parameters: saving it is refused.
    with pytest.raises(ValueError, match="editable object's transport"):
        obj.transport.save(str(tmp_path / "edited.prt"))
    assert not (tmp_path / "edited.prt").exists()
    with pytest.raises(TypeError, match="material: expected a string"):
        obj.set_material(3)
    assert (prt.material("Marble") == 3) is False
    assert prt.material("Marble") == prt.material("Marble")


def test_base_colour_and_spp_follow_the_command_line(scene, tmp_path):
    # A .glb of the torus with a constant texture: render(base_colour) is c x render, and
    # both equal prt-relight render's EXR with the same options, spp included.
    glb = tmp_path / "torus.glb"
    run_tool("prt-make-asset", scene / "torus.ply", "-o", glb, "--cells", "1")
    plain = prt.load_object(str(glb), str(scene / "torus.prt"))
    tinted = prt.load_object(str(glb), str(scene / "torus.prt"), base_colour=True)
    env = prt.load_environment(str(scene / "sky.exr"))
    a = prt.render(plain, env, width=48, height=40, spp=4)
    b = prt.render(tinted, env, width=48, height=40, spp=4)
    assert a.shape == (40, 48, 4)
    covered = (a[..., 3] > 0) & (a[..., 3] < 1)
    assert covered.sum() > 10  # coverage at the silhouette
    ratio = b[..., :3][a[..., 3] == 1] / np.maximum(a[..., :3][a[..., 3] == 1], 1e-12)
    assert np.ptp(ratio, axis=0).max() < 1e-4  # one colour: the checker has one cell
    cli = tmp_path / "cli"
    run_tool("prt-relight", "render", glb, "-t", scene / "torus.prt", "-e", scene / "sky.exr",
             "-W", "48", "-H", "40", "--spp", "4", "--base-colour", "-o", cli)
    assert np.array_equal(prt.read_image(str(cli) + ".exr"), b)


def test_ground_follows_the_command_line(scene, tmp_path):
    # precompute(ground=True) writes the ground's file beside the output; an object loaded
    # with it renders the plane exactly as prt-relight render --ground does.
    out = tmp_path / "torus.prt"
    t = prt.precompute(str(scene / "torus.ply"), str(out), size_mm=20, cubemap_size=8, samples=1500,
                       ground=True, ground_cells=12, ground_albedo=[0.2, 0.4, 0.6])
    ground = tmp_path / "torus.ground.prt"
    assert ground.exists()
    assert t.summary["ground_file"] == str(ground)
    assert t.summary["ground_vertices"] == 13 * 13
    assert t.settings["ground"]["cells"] == 12
    with pytest.raises(ValueError, match="needs output="):
        prt.precompute(str(scene / "torus.ply"), size_mm=20, cubemap_size=8, samples=1500, ground=True)
    obj = prt.load_object(str(scene / "torus.ply"), str(out), ground=str(ground))
    env = prt.load_environment(str(scene / "sky.exr"))
    image = prt.render(obj, env, width=48, height=40, elevation=30)
    plain = prt.render(prt.load_object(str(scene / "torus.ply"), str(out)), env, width=48, height=40, elevation=30)
    assert (image[..., 3] == 1).sum() > (plain[..., 3] == 1).sum()  # the plane's pixels
    cli = tmp_path / "cli"
    run_tool("prt-relight", "render", scene / "torus.ply", "-t", out, "--ground", ground, "-e", scene / "sky.exr",
             "-W", "48", "-H", "40", "--elevation", "30", "-o", cli)
    assert np.array_equal(prt.read_image(str(cli) + ".exr"), image)
    with pytest.raises(ValueError, match="not a ground transport file"):
        prt.load_object(str(scene / "torus.ply"), str(out), ground=str(out))
