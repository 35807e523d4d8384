"""Bad input gets a clear message naming the object or argument."""
import os
import subprocess
import sys

import numpy as np
import pytest

from helpers import ROOT
from engine import Camera, Light, Material, Mesh, RenderSettings, Scene, SceneError
from engine.imageio import read_image, write_image
from engine.scenefile import SceneFileError, load_scene


def test_mesh_shape_errors_name_the_object():
    with pytest.raises(SceneError, match="mesh 'Teapot'.*vertices"):
        Mesh("Teapot", np.zeros((4, 2)), [[0, 1, 2]])
    with pytest.raises(SceneError, match="mesh 'Quad'.*triangles"):
        Mesh("Quad", np.zeros((4, 3)), [[0, 1, 2, 3]])


def test_broken_faces_are_dropped_with_a_warning():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [np.nan, 0, 0], [2, 0, 0]], float)
    f = np.array([[0, 1, 2], [0, 1, 3], [0, 1, 9], [0, 1, 4]])
    m = Mesh("Broken", v, f)
    assert len(m.faces) == 1
    text = " ".join(m.warnings)
    assert "Broken" in text and "NaN" in text and "outside" in text and "zero-area" in text


def test_light_and_material_validation():
    with pytest.raises(SceneError, match="light 'Key'.*power"):
        Light("Key", "POINT", power=-1)
    with pytest.raises(SceneError, match="light 'Key'.*kind"):
        Light("Key", "LASER")
    with pytest.raises(SceneError, match="material 'Gold'.*base_color"):
        Material("Gold", (1, 0.8, np.nan))
    # Kept above 1, as Cycles' diffuse closure keeps it (a note says so).
    m = Material("Hot", (2.0, 0.5, 0.5))
    assert m.base_color.max() == 2.0 and "Hot" in m.warnings[0]


def test_scene_without_camera_or_lights():
    s = Scene(materials={"default": Material()})
    s.meshes.append(Mesh("Tri", [[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]]))
    with pytest.raises(SceneError, match="no camera"):
        s.validate()
    s.camera = Camera.look_at((0, 0, 3), (0, 0, 0), (0, 1, 0))
    s.width, s.height = 8, 8
    from engine import render
    film = render(s, RenderSettings(spp=1, photons=100))
    assert film.combined.max() == 0.0
    assert any("no lights" in w for w in film.warnings)


def test_settings_validation_names_the_setting():
    with pytest.raises(ValueError, match="'spp'"):
        RenderSettings(spp=0)
    with pytest.raises(ValueError, match="'estimator'"):
        RenderSettings(estimator="magic")
    with pytest.raises(ValueError, match="'radius'"):
        RenderSettings(radius=-1.0)


def test_scene_file_errors(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('[camera]\nposition=[0,0,1]\nlook_at=[0,0,0]\n[[objects]]\ntype="cone"\n')
    with pytest.raises(SceneFileError, match="cone"):
        load_scene(str(bad))
    typo = tmp_path / "typo.toml"
    typo.write_text('[camera]\nposition=[0,0,1]\nlook_at=[0,0,0]\n[render]\nphotonz=5\n')
    with pytest.raises(SceneFileError, match="photonz"):
        load_scene(str(typo))


def test_scene_file_loads_obj_meshes(tmp_path):
    (tmp_path / "tri.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n")
    f = tmp_path / "s.toml"
    f.write_text('[camera]\nposition=[0,0,3]\nlook_at=[0,0,0]\nup=[0,1,0]\n'
                 '[[objects]]\ntype="file"\npath="tri.obj"\nmaterial="white_diffuse"\n'
                 'translate=[0,0,1]\n'
                 '[[lights]]\ntype="point"\nposition=[0,0,2]\npower=10\n')
    scene, _ = load_scene(str(f))
    mesh = scene.meshes[0]
    assert len(mesh.faces) == 2 and np.allclose(mesh.vertices[:, 2], 1.0)


def run_cli(*args):
    return subprocess.run([sys.executable, "-m", "engine.cli", *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)


def main_cli(capsys, *args):
    """engine.cli.main in this process (cwd = ROOT): (exit code, stderr). The same parser
    and error paths as `python -m engine.cli` (whose `sys.exit(main())` the subprocess
    cases below cover), without a Python start and engine import per case (~1.4 CPU s)."""
    from engine import cli
    capsys.readouterr()
    try:
        code = cli.main(list(args))
    except SystemExit as stop:  # argparse's errors
        code = stop.code
    return code, capsys.readouterr().err


def test_cli_renders_and_reports_errors(tmp_path, capsys, monkeypatch):
    out = tmp_path / "fig3.png"
    r = run_cli("render", "scenes/figure3.toml", "-o", str(out), "--width", "40", "--height", "30",
                "--spp", "1", "--photons", "2000", "--caustic-photons", "1000", "--quiet")
    assert r.returncode == 0, r.stderr
    img = read_image(str(out))
    assert img.shape == (30, 40, 3) and img.max() > 0
    # The process's exit codes: 1 for an error the render reports, 2 for a parser error.
    r = run_cli("render", "missing.toml", "-o", str(out))
    assert r.returncode == 1 and "missing.toml" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    r = run_cli("render", "scenes/figure3.toml", "-o", str(out), "--spp", "-3")
    assert r.returncode == 2 and "--spp" in r.stderr
    monkeypatch.chdir(ROOT)
    code, err = main_cli(capsys, "render", "scenes/figure3.toml", "-o", str(tmp_path / "x.gif"))
    assert code == 1 and "x.gif" in err
    # Zero where only a positive value makes sense is refused, not silently replaced.
    for option in ("--width", "--height", "--spp", "--light-samples"):
        code, err = main_cli(capsys, "render", "scenes/figure3.toml", "-o", str(out), option, "0")
        assert code == 2 and option in err and "must be >= 1" in err, option
    # A misspelt option is said by `photonmap render`'s parser, whose usage lists its options.
    code, err = main_cli(capsys, "render", "scenes/figure3.toml", "-o", str(out),
                         "--photonz", "5")
    assert code == 2 and "unrecognized arguments: --photonz 5" in err
    assert "usage: photonmap render " in err and "--photons" in err, err
    # An abbreviation is refused too ('--photon 100' was taken as --photons 100, unsaid),
    # by both commands' parsers (the batch's without loading Blender).
    code, err = main_cli(capsys, "render", "scenes/figure3.toml", "-o", str(out),
                         "--photon", "100")
    assert code == 2 and "unrecognized arguments: --photon 100" in err
    from addon.batch import parse_args
    with pytest.raises(SystemExit) as stop:
        parse_args(["x.blend", "-o", str(out), "--photon", "100"])
    assert stop.value.code == 2


@pytest.mark.parametrize("ext", [".png", ".exr", ".ppm", ".npy"])
def test_image_writers_round_trip(tmp_path, ext):
    img = np.random.default_rng(0).random((6, 5, 3)).astype(np.float32) * 0.9
    path = str(tmp_path / f"x{ext}")
    write_image(img, path)
    back = read_image(path)
    tol = 1e-6 if ext in (".exr", ".npy") else 0.02
    np.testing.assert_allclose(back, img, atol=tol)


def test_photons_alone_scale_the_scene_files_caustic_photons(tmp_path):
    """--photons without --caustic-photons scales the scene file's caustic count in the
    file's ratio (newuser42: paper mode's '--photons 1000' on figure6.toml kept its
    100,000 caustic photons and took 35 minutes instead of 3); a file's 0 stays 0; an
    explicit --caustic-photons wins; without either the file's counts stand."""
    from engine.cli import _scene_and_overrides, build_parser
    parser = build_parser()

    def caustic(path, *extra):
        args = parser.parse_args(["render", str(path), "-o", "x.png", *extra])
        return _scene_and_overrides(args)[1]["caustic_photons"]
    fig6 = os.path.join(ROOT, "scenes", "figure6.toml")
    assert caustic(fig6, "--photons", "1000") == 500  # the file's 200,000 : 100,000
    assert caustic(fig6, "--photons", "1000", "--caustic-photons", "7") == 7
    assert caustic(fig6) == 100_000
    text = open(fig6).read().replace("caustic_photons = 100000", "caustic_photons = 0")
    none = tmp_path / "no_caustics.toml"
    none.write_text(text)
    assert caustic(none, "--photons", "1000") == 0
