"""[[instances]] in scene files: placements of an object's geometry without copies."""
import numpy as np
import pytest

from engine import RenderSettings, resources
from engine.geometry import prepare
from engine.scenefile import SceneFileError, load_scene

HEAD = """
[render]
width = 40
height = 30
[camera]
position = [0, -8, 5]
look_at = [0, 0, 0.5]
[materials.red]
base_color = [0.8, 0.2, 0.1]
[[objects]]
type = "plane"
size = 20
[[lights]]
type = "point"
position = [1, -2, 6]
power = 800
"""

PLACED = [("[2, 0, 1]", "[0, 0, 30]", "0.8"), ("[-2, 0, 1]", "[20, 0, 0]", "[-1, 1, 0.7]"),
          ("[0, 2, 1]", "[0, 40, 0]", "[1.2, 0.6, 1]")]


def _write(tmp_path, text, name="s.toml"):
    p = tmp_path / name
    p.write_text(HEAD + text)
    return str(p)


def _instanced(tmp_path):
    text = ('[[objects]]\ntype = "sphere"\nname = "ball"\nsegments = 24\ntemplate = true\n')
    for i, (t, r, sc) in enumerate(PLACED):
        text += (f'[[instances]]\nobject = "ball"\ntranslate = {t}\nrotate = {r}\n'
                 f'scale = {sc}\n' + ('material = "red"\n' if i == 1 else ""))
    return _write(tmp_path, text)


def _copies(tmp_path):
    text = ""
    for i, (t, r, sc) in enumerate(PLACED):
        text += (f'[[objects]]\ntype = "sphere"\nsegments = 24\ntranslate = {t}\n'
                 f'rotate = {r}\nscale = {sc}\n' + ('material = "red"\n' if i == 1 else ""))
    return _write(tmp_path, text, "c.toml")


def test_instances_are_placements_and_render_as_copies(tmp_path, monkeypatch):
    scene, render = load_scene(_instanced(tmp_path))
    placed = [m for m in scene.meshes if m.prototype is not None]
    assert len(placed) == 3 and all(m.vertices is None for m in placed)
    assert placed[1].materials == ["red"]
    assert np.linalg.det(placed[1].matrix[:, :3]) < 0  # the mirrored one
    copies, _ = load_scene(_copies(tmp_path))
    settings = RenderSettings(spp=2, photons=20000, caustic_photons=0, seed=3)
    monkeypatch.setattr(resources, "INSTANCE_BUDGET_FRACTION", 0.0)
    scene.validate()
    geo, _ = prepare(scene)
    assert geo.shared is not None
    a = scene.render(settings)
    b = copies.render(settings)
    assert np.isclose(a.depth, b.depth, rtol=1e-4, atol=1e-5).mean() > 0.99
    assert abs(a.combined.mean() / b.combined.mean() - 1) < 0.005


@pytest.mark.parametrize("text, message", [
    ('[[instances]]\nobject = "nothing"\n', "names no \\[\\[objects\\]\\] entry"),
    ('[[objects]]\ntype = "box"\nname = "b"\n[[instances]]\nobject = "b"\nscale = [1, 1, 0]\n',
     "scale"),
    ('[[objects]]\ntype = "box"\nname = "b"\n[[instances]]\nobject = "b"\n'
     'matrix = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 0]]\n', "singular"),
    ('[[objects]]\ntype = "box"\nname = "b"\n[[instances]]\nobject = "b"\nmatrix = [[1, 0]]\n',
     "'matrix' must be 3 or 4 rows of 4 finite numbers"),
    # A short row, a word for a number, a number for a row: the message says what a
    # matrix must be (it said "must be valid").
    ('[[objects]]\ntype = "box"\nname = "b"\n[[instances]]\nobject = "b"\n'
     'matrix = [[1, 0, 0, 0], [0, 1, 0], [0, 0, 1, 0]]\n',
     "'matrix' must be 3 or 4 rows of 4 finite numbers \\(object to world\\), got"),
    ('[[objects]]\ntype = "box"\nname = "b"\n[[instances]]\nobject = "b"\n'
     'matrix = [[1, 0, 0, 0], [0, 1, "x", 0], [0, 0, 1, 0]]\n',
     "'matrix' must be 3 or 4 rows of 4 finite numbers"),
    ('[[objects]]\ntype = "box"\nname = "b"\n[[instances]]\nobject = "b"\n'
     'matrix = [[1, 0, 0, 0], 5, [0, 0, 1, 0]]\n',
     "'matrix' must be 3 or 4 rows of 4 finite numbers"),
    ('[[objects]]\ntype = "box"\nname = "b"\n[[instances]]\nobject = "b"\n'
     'matrix = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [1, 1, 1, 1]]\n',
     "'matrix' row 4 must be \\[0, 0, 0, 1\\]"),
    ('[[objects]]\ntype = "box"\nname = "b"\n[[instances]]\nobject = "b"\nvisible_camera = "no"\n',
     "visible_camera"),
    ('[[objects]]\ntype = "box"\nname = "b"\n[[instances]]\nobject = "b"\nmaterial = "nope"\n',
     "unknown material 'nope'"),
])
def test_bad_instances_are_refused_naming_the_key(tmp_path, text, message):
    with pytest.raises(SceneFileError, match=message):
        load_scene(_write(tmp_path, text))


def test_a_template_without_instances_is_not_drawn_and_said(tmp_path):
    """template = true means 'drawn only through its instances' (docs/scene_format.md):
    with no [[instances]] entry placing it, it is not drawn, and a warning says why (it
    was drawn, against the docs; found by a reviewer)."""
    scene, _ = load_scene(_write(tmp_path, '[[objects]]\ntype = "sphere"\nname = "ball"\n'
                                           'template = true\n'))
    assert [m.name for m in scene.meshes] == ["plane.000"] or "ball" not in [
        m.name for m in scene.meshes]
    assert any("'ball' is a template" in w and "not drawn" in w for w in scene.all_warnings())


def test_a_mirrored_copy_keeps_its_faces_outward(tmp_path):
    """A scene-file object under a mirroring scale (det < 0) is turned inside out by the
    transform alone: its corners go 0, 2, 1 so that its winding normal points out beside
    its shading normals, as the add-on's export and mirrored instances order them (a
    reviewer found the copies' winding inward: smooth glass 1.06x its unmirrored self)."""
    copies, _ = load_scene(_copies(tmp_path))
    copies.validate()
    geo, _ = prepare(copies)
    ball = [i for i, m in enumerate(copies.meshes) if m.vertices is not None
            and len(m.faces) > 2]
    assert len(ball) == 3
    for k in ball:
        rows = np.flatnonzero(geo.object_id == k)
        tri = geo.v0[rows] + (geo.e1[rows] + geo.e2[rows]) / 3.0
        centre = 0.5 * (tri.min(axis=0) + tri.max(axis=0))  # (geo's own frame)
        outward = np.einsum("ij,ij->i", geo.ng[rows], tri - centre)
        assert (outward > 0).mean() > 0.99, copies.meshes[k].name
        ns = geo.shading_normals(rows, np.full(len(rows), 1 / 3), np.full(len(rows), 1 / 3))
        assert (np.einsum("ij,ij->i", ns, geo.ng[rows]) > 0).all()
