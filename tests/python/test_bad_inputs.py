"""The command line's bad inputs (tests/bad_inputs_test.sh) through Python: the same
one-line message, as FileNotFoundError or ValueError; wrong argument types and shapes
as TypeError / ValueError naming the argument."""

import shutil
import subprocess

import numpy as np
import pytest

import prt
from conftest import tool_error


@pytest.fixture(scope="module")
def work(scene, tmp_path_factory):
    """bad_inputs_test.sh's inputs, in a folder the tests run in (relative names)."""
    root = tmp_path_factory.mktemp("bad")
    for name in ("torus.ply", "sphere.ply", "sky.exr", "torus.prt"):
        shutil.copy(scene / name, root / name)
    (root / "empty.obj").write_text("")
    (root / "garbage.ply").write_text("garbage\nmore garbage\n")
    (root / "nan.obj").write_text("v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (root / "index.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n")
    (root / "flat.obj").write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n")
    good = (root / "torus.prt").read_bytes()
    (root / "truncated.prt").write_bytes(good[:1000])
    corrupted = bytearray(good)
    corrupted[600000:600002] = b"\xff\xfe"
    (root / "corrupted.prt").write_bytes(bytes(corrupted))
    shutil.copy(root / "sky.exr", root / "not-a-transport.prt")
    (root / "fake.png").write_text("not a PNG at all")
    (root / "typo-lights.json").write_text('{"lights": [ {"type": "point", "positon": [0, 50, 0], "intensity": 1} ]}\n')
    (root / "negative-lights.json").write_text('{"lights": [ {"type": "point", "position": [0, 50, 0], "intensity": -1} ]}\n')
    (root / "a-file").write_text("")
    subprocess.run(["oiiotool", "--pattern", "constant:color=0,1,1", "64x32", "3", "-d", "float", "--powc", "-1,1,1",
                    "-o", str(root / "inf.exr")], check=True, capture_output=True)
    subprocess.run(["oiiotool", "--pattern", "constant:color=0.5,0.5,0.5", "32x32", "3", "-d", "float", "-o",
                    str(root / "small.exr")], check=True, capture_output=True)
    return root


def obj():
    return prt.load_object("torus.ply", "torus.prt")


def sky():
    return prt.load_environment("sky.exr")


P = ["prt-precompute"]
R = ["prt-relight", "render", "torus.ply", "-o", "out"]
L = ["prt-pointlight", "torus.ply", "-o", "out"]
F = ["prt-reference", "torus.ply", "-W", "16", "-H", "16", "-o", "out"]
ON = "point:0,50,0:1"


def lit(lights=ON, **options):
    return prt.render_point_lights("torus.ply", lights, **options)


def ref(**options):
    return prt.render_reference("torus.ply", width=16, height=16, **options)


CASES = [
    # (name, Python call, command line, exception)
    ("missing mesh", lambda: prt.load_mesh("missing.obj"), P + ["missing.obj", "-o", "o.prt"], FileNotFoundError),
    ("empty mesh", lambda: prt.load_mesh("empty.obj"), P + ["empty.obj", "-o", "o.prt"], ValueError),
    ("not a PLY", lambda: prt.load_mesh("garbage.ply"), P + ["garbage.ply", "-o", "o.prt"], ValueError),
    ("NaN vertex", lambda: prt.load_mesh("nan.obj"), P + ["nan.obj", "-o", "o.prt"], ValueError),
    ("index out of range", lambda: prt.load_mesh("index.obj"), P + ["index.obj", "-o", "o.prt"], ValueError),
    ("degenerate mesh", lambda: prt.load_mesh("flat.obj"), P + ["flat.obj", "-o", "o.prt"], ValueError),
    ("negative size", lambda: prt.precompute("torus.ply", size_mm=-5), P + ["torus.ply", "--size-mm", "-5", "-o", "o.prt"], ValueError),
    ("unknown material", lambda: prt.precompute("torus.ply", material="Unobtainium"),
     P + ["torus.ply", "-m", "Unobtainium", "-o", "o.prt"], ValueError),
    ("cubemap not a power of two", lambda: prt.precompute("torus.ply", cubemap_size=33),
     P + ["torus.ply", "--cubemap-size", "33", "-o", "o.prt"], ValueError),
    ("zero coefficients", lambda: prt.precompute("torus.ply", coefficients=0),
     P + ["torus.ply", "--coefficients", "0", "-o", "o.prt"], ValueError),
    ("eta out of range", lambda: prt.precompute("torus.ply", eta=0), P + ["torus.ply", "--eta", "0", "-o", "o.prt"], ValueError),
    ("negative epsilon", lambda: prt.precompute("torus.ply", epsilon=-1),
     P + ["torus.ply", "--epsilon", "-1", "-o", "o.prt"], ValueError),
    ("unknown component", lambda: prt.precompute("torus.ply", components="xs"),
     P + ["torus.ply", "--components", "xs", "-o", "o.prt"], ValueError),
    ("g out of range", lambda: prt.precompute("torus.ply", components="ms,ss", g=1.5),
     P + ["torus.ply", "--components", "ms,ss", "--g", "1.5", "-o", "o.prt"], ValueError),
    ("negative threads", lambda: prt.precompute("torus.ply", threads=-1),
     P + ["torus.ply", "--threads", "-1", "-o", "o.prt"], ValueError),
    ("missing output directory", lambda: prt.precompute("torus.ply", "nodir/o.prt"),
     P + ["torus.ply", "-o", "nodir/o.prt"], FileNotFoundError),
    ("missing transport", lambda: prt.load_object("torus.ply", "missing.prt"),
     R + ["-t", "missing.prt", "-e", "sky.exr"], FileNotFoundError),
    ("mesh does not match", lambda: prt.load_object("sphere.ply", "torus.prt"),
     ["prt-relight", "render", "sphere.ply", "-t", "torus.prt", "-e", "sky.exr", "-o", "out"], ValueError),
    ("truncated transport", lambda: prt.load_object("torus.ply", "truncated.prt"),
     R + ["-t", "truncated.prt", "-e", "sky.exr"], ValueError),
    ("corrupted transport", lambda: prt.load_transport("corrupted.prt"),
     ["prt-relight", "info", "--full", "corrupted.prt"], ValueError),
    ("info: missing transport", lambda: prt.transport_info("missing.prt"), ["prt-relight", "info", "missing.prt"],
     FileNotFoundError),
    ("info: truncated transport", lambda: prt.transport_info("truncated.prt"), ["prt-relight", "info", "truncated.prt"],
     ValueError),
    ("not a transport file", lambda: prt.transport_info("not-a-transport.prt"),
     ["prt-relight", "info", "not-a-transport.prt"], ValueError),
    ("missing environment", lambda: prt.load_environment("nowhere.exr"),
     R + ["-t", "torus.prt", "-e", "nowhere.exr"], FileNotFoundError),
    ("Inf pixels", lambda: prt.load_environment("inf.exr"), R + ["-t", "torus.prt", "-e", "inf.exr"], ValueError),
    ("not an image", lambda: prt.load_environment("fake.png"), R + ["-t", "torus.prt", "-e", "fake.png"], ValueError),
    ("square environment", lambda: prt.load_environment("small.exr"),
     R + ["-t", "torus.prt", "-e", "small.exr"], ValueError),
    ("zero width", lambda: prt.render(obj(), sky(), width=0), R + ["-t", "torus.prt", "-e", "sky.exr", "-W", "0"], ValueError),
    ("zero fov", lambda: prt.render(obj(), sky(), fov=0), R + ["-t", "torus.prt", "-e", "sky.exr", "--fov", "0"], ValueError),
    ("component the file lacks", lambda: prt.render(obj(), sky(), components="ss"),
     R + ["-t", "torus.prt", "-e", "sky.exr", "--components", "ss"], ValueError),
    ("material on a plain file", lambda: prt.render(obj(), sky(), material="Skin1"),
     R + ["-t", "torus.prt", "-e", "sky.exr", "--material", "Skin1"], ValueError),
    ("block coefficients beyond 6 N^2", lambda: prt.precompute("torus.ply", block_coefficients=7000),
     P + ["torus.ply", "--block-coefficients", "7000", "-o", "o.prt"], ValueError),
    ("absurd sample count", lambda: prt.precompute("torus.ply", "o.prt", samples=800000000),
     P + ["torus.ply", "--samples", "800000000", "-o", "o.prt"], ValueError),
    ("over --max-memory", lambda: prt.precompute("torus.ply", "o.prt", samples=100000, max_memory=0.01),
     P + ["torus.ply", "--samples", "100000", "--max-memory", "0.01", "-o", "o.prt"], ValueError),
    ("negative --max-memory", lambda: prt.precompute("torus.ply", max_memory=-1),
     P + ["torus.ply", "--max-memory", "-1", "-o", "o.prt"], ValueError),
    ("output under a file", lambda: prt.precompute("torus.ply", "a-file/o.prt"),
     P + ["torus.ply", "-o", "a-file/o.prt"], FileNotFoundError),
    ("pointlight: no light", lambda: lit([]), L, ValueError),
    ("pointlight: bad light syntax", lambda: lit("point:1,2:1"), L + ["--light", "point:1,2:1"], ValueError),
    ("pointlight: light inside the object", lambda: lit("point:5,0,0:1", size_mm=20),
     L + ["--size-mm", "20", "--light", "point:5,0,0:1"], ValueError),
    ("pointlight: misspelt lights key", lambda: lit([], lights_file="typo-lights.json"),
     L + ["--lights", "typo-lights.json"], ValueError),
    ("pointlight: negative intensity", lambda: lit([], lights_file="negative-lights.json"),
     L + ["--lights", "negative-lights.json"], ValueError),
    ("pointlight: missing lights file", lambda: lit([], lights_file="nowhere.json"), L + ["--lights", "nowhere.json"],
     FileNotFoundError),
    ("pointlight: unknown method", lambda: lit(method="magic"), L + ["--light", ON, "--method", "magic"], ValueError),
    ("pointlight: atlas not a power of two", lambda: lit(method="tsis", atlas_size=1000),
     L + ["--light", ON, "--method", "tsis", "--atlas-size", "1000"], ValueError),
    ("pointlight: unknown split", lambda: lit(method="tsis", split="both"),
     L + ["--light", ON, "--method", "tsis", "--split", "both"], ValueError),
    ("pointlight: zero samples", lambda: lit(method="tsis", tsis_samples=0),
     L + ["--light", ON, "--method", "tsis", "--tsis-samples", "0"], ValueError),
    ("pointlight: cache bound a = 0", lambda: lit(a=0), L + ["--light", ON, "--a", "0"], ValueError),
    ("pointlight: unknown near-field rule", lambda: lit(near_field="exact"),
     L + ["--light", ON, "--near-field", "exact"], ValueError),
    ("reference: missing environment", lambda: ref(transport="torus.prt", environment="nowhere.exr"),
     F + ["-t", "torus.prt", "-e", "nowhere.exr"], FileNotFoundError),
    ("reference: the file's seed", lambda: ref(transport="torus.prt", environment="sky.exr", seed=1),
     F + ["-t", "torus.prt", "-e", "sky.exr", "--seed", "1"], ValueError),
    ("reference: both an environment and lights", lambda: ref(transport="torus.prt", environment="sky.exr", lights=[ON]),
     F + ["-t", "torus.prt", "-e", "sky.exr", "--light", ON], ValueError),
    ("reference: no light at all", lambda: ref(transport="torus.prt"), F + ["-t", "torus.prt"], ValueError),
    ("reference: environment without a transport file", lambda: ref(environment="sky.exr"),
     F + ["-e", "sky.exr"], ValueError),
    ("reference: single scattering under lights", lambda: ref(lights=[ON], components="ms,ss"),
     F + ["--light", ON, "--components", "ms,ss"], ValueError),
    ("reference: a size with the transport file", lambda: ref(transport="torus.prt", lights=[ON], size_mm=20),
     F + ["-t", "torus.prt", "--light", ON, "--size-mm", "20"], ValueError),
    ("reference: a light inside the object", lambda: ref(size_mm=20, lights=["point:5,0,0:1"]),
     F + ["--size-mm", "20", "--light", "point:5,0,0:1"], ValueError),
    ("reference: misspelt light scene key", lambda: ref(lights_file="typo-lights.json"),
     F + ["--lights", "typo-lights.json"], ValueError),
    ("reference: zero pixel stride", lambda: ref(lights=[ON], pixel_stride=0),
     F + ["--light", ON, "--pixel-stride", "0"], ValueError),
    ("compare: missing image", lambda: prt.compare("nowhere.exr", "sky.exr"),
     ["prt-compare", "nowhere.exr", "sky.exr"], FileNotFoundError),
    ("compare: different sizes", lambda: prt.compare("small.exr", "sky.exr"),
     ["prt-compare", "small.exr", "sky.exr"], ValueError),
]


@pytest.mark.parametrize("name,call,command,kind", CASES, ids=[c[0] for c in CASES])
def test_same_message_as_the_command_line(work, monkeypatch, name, call, command, kind):
    monkeypatch.chdir(work)
    expected = tool_error(*command, cwd=work)
    with pytest.raises(kind) as e:
        call()
    assert str(e.value) == expected
    assert not (work / "o.prt").exists() and not (work / "out.exr").exists()
    assert not list(work.glob("*.tmp*"))


def test_arrays_of_the_wrong_kind_name_the_argument(scene):
    with pytest.raises(TypeError, match="pixels: expected a float array"):
        prt.Environment(np.zeros((4, 8, 3), np.int32))
    with pytest.raises(ValueError, match=r"pixels: expected an \(H, W, C\) array .* got shape \(4, 8, 5\)"):
        prt.Environment(np.zeros((4, 8, 5), np.float32))
    with pytest.raises(TypeError, match="pixels: expected a numpy array"):
        prt.Environment([[1.0]])
    with pytest.raises(ValueError, match="twice as wide as high"):
        prt.Environment(np.zeros((4, 4, 3), np.float32))
    bad = np.ones((4, 8, 3), np.float32)
    bad[1, 2, 0] = np.nan
    with pytest.raises(ValueError, match=r"environment: pixel \(2, 1\) is NaN"):
        prt.Environment(bad)
    t = prt.load_transport(str(scene / "torus.prt"))
    light = prt.Environment(np.ones((8, 16, 3), np.float32)).light_vector(8)
    with pytest.raises(TypeError, match="light: expected a prt.LightVector"):
        prt.relight(t, "sky")
    with pytest.raises(ValueError, match=r"out: expected shape \(1152, 3\)"):
        prt.relight(t, light, out=np.empty((10, 3), np.float32))
    with pytest.raises(TypeError, match="out: expected a float32 array"):
        prt.relight(t, light, out=np.empty((1152, 3), np.float64))
    with pytest.raises(ValueError, match="light: its cubemap is 6x4"):
        prt.relight(t, prt.Environment(np.ones((8, 16, 3), np.float32)).light_vector(4))
    with pytest.raises(ValueError, match="sigma_a: expected three numbers"):
        prt.Material(sigma_a=[1, 2], sigma_s_prime=1)
    with pytest.raises(TypeError, match="output: expected a string"):
        prt.precompute(str(scene / "torus.ply"), 3)
    with pytest.raises(TypeError, match="eye: mixes strings and numbers"):
        prt.render_point_lights(str(scene / "torus.ply"), "point:0,40,0:1", eye=[1, "a"])
    with pytest.raises(TypeError, match="eye: expected numbers"):
        prt.render_point_lights(str(scene / "torus.ply"), "point:0,40,0:1", eye=[1, {}])
    with pytest.raises(ValueError, match="non_finite"):
        prt.load_environment(str(scene / "sky.exr"), non_finite="ignore")
