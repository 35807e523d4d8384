"""Bad scene files get one clear line naming the key, never a traceback and never a
silent guess (issue 16): each case measured in the issue is refused here."""
import subprocess
import sys

import pytest

from helpers import ROOT
from engine.scenefile import SceneFileError, load_scene

CAMERA = '[camera]\nposition = [0, -6, 2]\nlook_at = [0, 0, 1]\n'
SPHERE = '[[objects]]\ntype = "sphere"\nname = "ball"\n'
LIGHT = '[[lights]]\ntype = "spot"\nname = "key"\nposition = [0, 0, 4]\n'


def _load(tmp_path, text):
    path = tmp_path / "scene.toml"
    path.write_text(text, encoding="utf-8")
    return load_scene(str(path))


def test_a_fog_material_loads(tmp_path):
    scene, _ = _load(tmp_path, CAMERA + '[materials.fog]\nvolume_only = true\n'
                     'absorption = [0.1, 0.1, 0.2]\nscattering = [0.5, 0.5, 0.4]\n'
                     'anisotropy = 0.3\n' + SPHERE + 'material = "fog"\n')
    fog = scene.materials["fog"]
    assert fog.volume_only and fog.anisotropy == 0.3
    assert list(fog.scattering) == [0.5, 0.5, 0.4]


def test_a_valid_scene_still_loads(tmp_path):
    scene, settings = _load(tmp_path, '[render]\nwidth = 32\nheight = 24\nfinal_gather = false\n'
                            + CAMERA + SPHERE + 'translate = [0, 0, 1]\nscale = 2\nsegments = 8\n'
                            + LIGHT + 'spot_size = 30\nvisible = true\n')
    assert (scene.width, scene.height) == (32, 24) and settings == {"final_gather": False}
    assert scene.lights[0].visible_camera is True


CASES = [
    # (what the issue measured, scene text, expected fragment of the one-line error)
    ("translate nan", CAMERA + SPHERE + "translate = [nan, 0, 0]\n",
     "objects[0] (ball): 'translate' must be 3 finite numbers"),
    ("scale inf", CAMERA + SPHERE + "scale = inf\n", "'scale' must be a finite, non-zero"),
    ("clip_start nan", CAMERA + "clip_start = nan\n", "[camera]: 'clip_start' must be a finite"),
    ("width inf", "[render]\nwidth = inf\n" + CAMERA, "[render]: 'width' must be a whole number"),
    ("width 1e6", "[render]\nwidth = 1000000\nheight = 1000000\n" + CAMERA,
     "'width' must be a number >= 1 and <= 65536"),
    ("width float", "[render]\nwidth = 1e6\n" + CAMERA, "'width' must be a whole number"),
    ("lights string", 'lights = "x"\n' + CAMERA, "'lights' must be an array of tables"),
    ("objects string", 'objects = 3\n' + CAMERA, "'objects' must be an array of tables"),
    ("segments huge", CAMERA + SPHERE + "segments = 100000\n",
     "'segments' must be a number >= 3 and <= 2048"),
    ("segments fraction", CAMERA + SPHERE + "segments = 2.7\n",
     "'segments' must be a whole number, got 2.7"),
    ("visible no", CAMERA + LIGHT + 'visible = "no"\n',
     "lights[0] (key): 'visible' must be true or false"),
    ("final_gather no", '[render]\nfinal_gather = "no"\n' + CAMERA,
     "[render]: setting 'final_gather' must be true or false"),
    ("fov true", CAMERA + "fov = true\n", "'fov' must be a finite number, got True"),
    ("fov 180", CAMERA + "fov = 180\n", "'fov' must be a number > 0 and < 180"),
    ("negative radius", CAMERA + SPHERE + "radius = -1\n", "'radius' must be a number > 0"),
    ("negative plane size", CAMERA + '[[objects]]\ntype = "plane"\nsize = -4\n',
     "'size' must be a number > 0"),
    ("negative box size", CAMERA + '[[objects]]\ntype = "box"\nsize = [1, -1, 1]\n',
     "'size' must be a number > 0 or 3 numbers > 0"),
    ("spot size negative", CAMERA + LIGHT + "spot_size = -30\n",
     "'spot_size' must be a number > 0 and <= 180"),
    ("negative power", CAMERA + LIGHT + "power = -5\n", "'power' must be a number >= 0"),
    ("spread on a spot", CAMERA + LIGHT + "spread = 30\n",
     "lights[0] (key): 'spread' applies to area lights only, not to a spot light"),
    ("sun angle on a spot", CAMERA + LIGHT + "angle = 2\n", "'angle' applies to sun lights"),
    ("power string", CAMERA + LIGHT + 'power = "bright"\n', "'power' must be a finite number"),
    ("light type", CAMERA + '[[lights]]\ntype = "laser"\n', "'type' must be point, spot"),
    ("light direction zero", CAMERA + LIGHT + "direction = [0, 0, 0]\n",
     "'direction' must be a non-zero vector"),
    ("material colour", CAMERA + '[materials.red]\nbase_color = [1, 0, "x"]\n',
     "[materials.red]: 'base_color' must be 3 finite numbers"),
    ("material range", CAMERA + '[materials.red]\nmetallic = 2\n',
     "'metallic' must be a number >= 0 and <= 1"),
    ("anisotropy 1", CAMERA + '[materials.fog]\nvolume_only = true\nscattering = [1, 1, 1]\n'
     'anisotropy = 1\n', "'anisotropy' must be a number > -1 and < 1"),
    ("negative scattering", CAMERA + '[materials.fog]\nscattering = [1, -1, 1]\n',
     "[materials.fog]: 'scattering'"),
    ("background", 'background = [0, 0]\n' + CAMERA, "'background' must be 3 finite numbers"),
    ("camera type", CAMERA + 'type = "fisheye"\n', "'type' must be one of persp, ortho"),
    ("camera at look_at", '[camera]\nposition = [1, 1, 1]\nlook_at = [1, 1, 1]\n',
     "'look_at' must differ from 'position'"),
    ("camera missing", SPHERE, "[camera]: 'position' is required"),
    ("clip_end before start", CAMERA + "clip_start = 2\nclip_end = 1\n", "'clip_end' must be"),
    ("material name type", CAMERA + SPHERE + "material = 3\n", "'material' must be a string"),
    ("unknown key", CAMERA + SPHERE + "radios = 1\n", "unknown key(s) radios"),
    ("spp float", '[render]\nspp = 2.5\n' + CAMERA, "setting 'spp' must be a whole number"),
    # Beyond float32's range (the engine traces in float32): as infinite as inf.
    ("translate 1e308", CAMERA + SPHERE + "translate = [1e308, 0, 0]\n",
     "objects[0] (ball): 'translate' must be 3 finite numbers"),
    ("power 1e39", CAMERA + LIGHT + "power = 1e39\n", "'power' must be a finite number"),
    ("background 1e39", 'background = [1e39, 0, 0]\n' + CAMERA,
     "'background' must be 3 finite numbers"),
]


@pytest.mark.parametrize("label, text, expected", CASES, ids=[c[0] for c in CASES])
def test_bad_scene_file_is_refused_in_one_line_naming_the_key(tmp_path, label, text,
                                                              expected):
    with pytest.raises(SceneFileError) as info:
        _load(tmp_path, text)
    msg, problems = str(info.value), info.value.problems
    # One line per refused key, each naming the file too (1e6 x 1e6: width and height).
    assert all("\n" not in p and "scene.toml" in p for p in problems), msg
    assert any(expected in p for p in problems), msg
    assert len(problems) == 1 or label == "width 1e6", msg
    if len(problems) == 1:
        assert msg == problems[0]


def _with_file(tmp_path, name, content: bytes):
    (tmp_path / name).write_bytes(content)
    return _load(tmp_path, CAMERA + f'[[objects]]\ntype = "file"\npath = "{name}"\n')


def test_ply_header_claiming_too_many_vertices_is_refused_before_loading(tmp_path):
    header = (b"ply\nformat binary_little_endian 1.0\nelement vertex 1000000000000\n"
              b"property float x\nproperty float y\nproperty float z\nend_header\n")
    with pytest.raises(SceneFileError, match=r"claims 1,000,000,000,000 vertex elements "
                                             r"but the file has \d+ bytes"):
        _with_file(tmp_path, "huge.ply", header + b"\0" * 36)


@pytest.mark.parametrize("name, content", [
    ("empty.obj", b""),
    ("garbage.obj", b"this is not a mesh\n\x00\x01 nothing here\n"),
    ("points.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\n"),
])
def test_empty_or_garbage_mesh_files_are_refused(tmp_path, name, content):
    with pytest.raises(SceneFileError, match=f"{name}.*no triangles found"):
        _with_file(tmp_path, name, content)


@pytest.mark.parametrize("name, content", [
    ("dangling.obj", b"v 0 0 0\nf 1 2 3\n"),
    ("broken.gltf", b'{"asset": {"version": "2.0"}, "meshes": [{"primitives": [{}]}]}'),
    ("cut.glb", b"glTF\x02\x00\x00\x00\xff\xff\x00\x00"),
])
def test_damaged_mesh_files_are_refused_in_words(tmp_path, name, content):
    """A damaged file is named with what is wrong, not only a library's IndexError."""
    with pytest.raises(SceneFileError) as info:
        _with_file(tmp_path, name, content)
    msg = str(info.value)
    assert name in msg and "\n" not in msg, msg
    assert "not a readable" in msg or "no triangles found" in msg, msg


def test_a_folder_as_mesh_file_is_named_as_such(tmp_path):
    (tmp_path / "meshes").mkdir()
    with pytest.raises(SceneFileError, match="'.*meshes' is a folder, not a mesh file"):
        _load(tmp_path, CAMERA + '[[objects]]\ntype = "file"\npath = "meshes"\n')


def test_cli_reports_a_bad_scene_and_a_nan_exposure_in_one_line(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text(CAMERA + SPHERE + "translate = [nan, 0, 0]\n", encoding="utf-8")
    for args, expected in (([str(bad)], "'translate' must be 3 finite numbers"),
                           (["scenes/figure3.toml", "--exposure", "nan"],
                            "--exposure: must be a finite number"),
                           # 2 ** 1500 overflowed when the image was written: a
                           # traceback after the whole render.
                           (["scenes/figure3.toml", "--exposure", "1500"],
                            "--exposure: must be from -32 to 32 stops")):
        res = subprocess.run([sys.executable, "-m", "engine.cli", "render", *args, "-o",
                              str(tmp_path / "x.png")],
                             cwd=ROOT, capture_output=True, text=True, timeout=120)
        assert res.returncode != 0
        lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
        assert expected in lines[-1] and "Traceback" not in res.stderr, res.stderr
        if "exposure" not in expected:
            assert len(lines) == 1
        assert not (tmp_path / "x.png").exists()


def test_without_the_schema_library_scene_files_are_refused_in_one_line(tmp_path,
                                                                         monkeypatch):
    """fastjsonschema is imported lazily (only scene files need it): without it the
    reader says which package to install instead of failing with a traceback."""
    from engine import scenefile
    monkeypatch.setattr(scenefile, "_VALIDATORS", {})
    monkeypatch.setitem(sys.modules, "fastjsonschema", None)
    with pytest.raises(SceneFileError, match="needs the 'fastjsonschema' package"):
        _load(tmp_path, CAMERA + SPHERE)


SCHEMA_CASES = [
    ("material table type", "materials = 3\n" + CAMERA, "'materials' must be a table of"),
    ("material not a table", CAMERA + "[materials]\nred = 3\n",
     "[materials.red]: must be a table"),
    ("object not a table", "objects = [1]\n" + CAMERA, "'objects' must be an array of tables"),
    ("vector of 4", CAMERA + SPHERE + "center = [0, 0, 0, 1]\n",
     "'center' must be 3 finite numbers"),
    ("negative colour", CAMERA + '[materials.red]\nbase_color = [1, -1, 0]\n',
     "'base_color' must be 3 numbers >= 0"),
    ("zero scale component", CAMERA + SPHERE + "scale = [1, 0, 1]\n",
     "'scale' must be a finite, non-zero number or 3 of them"),
    ("mesh without faces", CAMERA + '[[objects]]\ntype = "mesh"\nvertices = []\n',
     "'faces' is required"),
    ("light shape", CAMERA + '[[lights]]\ntype = "area"\nshape = "star"\n',
     "'shape' must be one of rectangle, square, disk, ellipse"),
    ("render unknown", "[render]\nphotonz = 3\n" + CAMERA, "[render]: unknown key(s) photonz"),
    ("top unknown", "lamps = 3\n" + CAMERA, "scene file: unknown key(s) lamps"),
]


@pytest.mark.parametrize("label, text, expected", SCHEMA_CASES, ids=[c[0] for c in SCHEMA_CASES])
def test_schema_refusals_name_the_table_and_key(tmp_path, label, text, expected):
    with pytest.raises(SceneFileError) as info:
        _load(tmp_path, text)
    msg = str(info.value)
    assert "\n" not in msg and expected in msg, msg


def test_case_of_kind_names_and_whole_floats_are_accepted(tmp_path):
    scene, _ = _load(tmp_path, "[render]\nwidth = 32.0\nheight = 24\n" + CAMERA
                     + 'type = "Ortho"\northo_scale = 4\n[[objects]]\ntype = "Sphere"\n'
                     + '[[lights]]\ntype = "AREA"\nshape = "Disk"\n')
    assert scene.width == 32 and scene.camera.kind == "ORTHO"
    assert scene.lights[0].shape == "DISK"


def test_principled_v2_material_keys(tmp_path):
    """Coat, sheen, specular IOR level and tint, distribution and node load into the
    Material; a bad value is refused with its key named."""
    mat = ('[materials.m]\nroughness = 0.6\nspecular = 1.0\nspecular_ior_level = 0.8\n'
           'specular_tint = [1, 0.5, 0.2]\ncoat_weight = 1.0\ncoat_roughness = 0.1\n'
           'coat_ior = 1.6\ncoat_tint = [0.9, 0.9, 1]\nsheen_weight = 0.5\n'
           'sheen_roughness = 0.3\nsheen_tint = [1, 0.8, 0.6]\nmultiscatter = false\n'
           'node = "glossy"\nglossy_color = [0.9, 0.9, 0.9]\n')
    scene, _ = _load(tmp_path, CAMERA + mat)
    m = scene.materials["m"]
    assert (m.specular_ior_level, m.coat_weight, m.coat_roughness, m.coat_ior) == \
        (0.8, 1.0, 0.1, 1.6)
    assert list(m.specular_tint) == [1, 0.5, 0.2] and list(m.sheen_tint) == [1, 0.8, 0.6]
    assert (m.sheen_weight, m.sheen_roughness, m.multiscatter, m.node) == \
        (0.5, 0.3, False, "glossy")
    with pytest.raises(SceneFileError, match="'coat_ior' must be"):
        _load(tmp_path, CAMERA + '[materials.m]\ncoat_ior = 0.5\n')
    with pytest.raises(SceneFileError, match="'node' must be one of"):
        _load(tmp_path, CAMERA + '[materials.m]\nnode = "metal"\n')


def test_translucent_material_keys(tmp_path):
    """A Translucent BSDF's share and colour load into the Material; a share outside
    0..1 is refused with its key named."""
    mat = '[materials.m]\ntranslucent = 0.4\ntranslucent_color = [0.9, 0.7, 0.2]\n'
    scene, _ = _load(tmp_path, CAMERA + mat)
    m = scene.materials["m"]
    assert m.translucent == 0.4 and list(m.translucent_color) == [0.9, 0.7, 0.2]
    with pytest.raises(SceneFileError, match="'translucent' must be"):
        _load(tmp_path, CAMERA + '[materials.m]\ntranslucent = 1.5\n')


def test_every_refused_key_of_a_file_is_reported_at_once(tmp_path):
    """A bad camera key does not hide the other problems: each refused key (its first
    problem) on its own line, naming the file, the table and the key."""
    text = ("lamps = 3\n[render]\nspp = 0\n"
            "[camera]\nposition = [0, -6, 2]\nlook_at = [0, 0, 1]\nfov = 200\n"
            "up = [0, 0, 0]\n[materials.red]\nmetallic = 2\nbase_color = [1, -1, -1]\n"
            + SPHERE + "radius = -1\nsegments = 2.5\n"
            + '[[objects]]\ntype = "cube"\n'
            + LIGHT + 'visible = "no"\nspread = 30\n')
    with pytest.raises(SceneFileError) as info:
        _load(tmp_path, text)
    problems = info.value.problems
    expected = ["scene file: unknown key(s) lamps", "[render]: setting 'spp'",
                "[camera]: 'fov' must be", "[camera]: 'up' must be a non-zero vector",
                "[materials.red]: 'metallic' must be", "[materials.red]: 'base_color' must be",
                "objects[0] (ball): 'radius' must be", "objects[0] (ball): 'segments' must be",
                "objects[1] (cube): 'type' must be sphere",
                "lights[0] (key): 'visible' must be true or false",
                "lights[0] (key): 'spread' applies to area lights only"]
    for fragment in expected:
        assert sum(fragment in p for p in problems) == 1, (fragment, problems)
    assert len(problems) == len(expected), problems  # base_color once, not per number
    assert all("scene.toml: " in p and "\n" not in p for p in problems)
    msg = str(info.value)
    assert msg.splitlines()[0].endswith(f"scene.toml: {len(expected)} problems:")
    assert msg.count("\n") == len(expected)


MESH = '[[objects]]\ntype = "mesh"\nname = "tri"\nvertices = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]\n'


@pytest.mark.parametrize("faces, expected", [
    ("[[0, 1, 2], [1, 2, 3]]", "'faces' row 1 [1, 2, 3] indexes a vertex outside 0..2"),
    ("[[1, 2, 3]]", "row 0 [1, 2, 3] indexes a vertex outside 0..2 (3 vertices; indices "
                    "count from 0)"),  # OBJ-style indices from 1
    ("[[0, 1, -1]]", "row 0 [0, 1, -1] indexes a vertex outside"),
    ("[[0, 1, 2], [0, 5, 1], [7, 0, 1]]", "row 1 [0, 5, 1] indexes a vertex outside 0..2 "
                                          "(3 vertices; indices count from 0) (and 1 more"),
    ("[[0, 1]]", "'faces' must be rows of 3 whole-number vertex indices"),
])
def test_mesh_face_indices_outside_the_vertices_are_refused_naming_the_face(
        tmp_path, faces, expected):
    """A face index outside the vertex list is a mistake in the file: refused, naming the
    object and the face, never dropped (which would render another object)."""
    with pytest.raises(SceneFileError) as info:
        _load(tmp_path, CAMERA + MESH + f"faces = {faces}\n")
    msg = str(info.value)
    assert "objects[0] (tri): " in msg and expected in msg, msg


def test_a_valid_inline_mesh_keeps_all_its_faces(tmp_path):
    scene, _ = _load(tmp_path, CAMERA + MESH + "faces = [[0, 1, 2], [2, 1, 0]]\n")
    mesh = scene.meshes[-1]
    assert mesh.name == "tri" and len(mesh.faces) == 2 and not scene.all_warnings()


def test_api_vertices_beyond_float32_are_dropped_naming_the_mesh():
    """Python API: a vertex at 1e39 m is infinite to Embree's float32. Its faces are
    dropped with a warning naming the mesh (the BVH build refused the whole scene
    without naming anything, and Accel.__del__ printed a second traceback)."""
    import numpy as np
    from engine import RenderSettings, render
    from engine.api import cornell_box
    from engine.scene import Mesh
    scene = cornell_box()
    scene.width, scene.height = 16, 12
    v = np.array([[0, 0, 0.5], [0.2, 0, 0.5], [0, 0.2, 0.5], [1e39, 0, 0.5]], float)
    scene.meshes.append(Mesh("far", v, [[0, 1, 2], [0, 1, 3]], materials=["white_diffuse"]))
    film = render(scene, RenderSettings(spp=1, photons=1000, caustic_photons=0))
    assert any("far" in w and "infinite" in w for w in film.warnings), film.warnings
    assert np.isfinite(film.combined).all()
