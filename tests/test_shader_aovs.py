"""Shader AOVs in the engine (engine/datapasses.py, Material.aovs, RenderSettings.
shader_aovs): what a material's AOV Output node writes at the surfaces camera rays meet,
as Cycles' svm_node_aov_color / _value: a constant mask, a colour from a texture node
(the Generated-free Position of the hit through shadernodes), the colour AOV's alpha,
nothing from materials without the AOV, every surface of the transparent chain writing
until the single pass is done, the image's bits untouched, bad settings named. The
comparison against live Cycles is tests/blender/test_blender_aovs.py."""
import numpy as np
import pytest

from engine import RenderSettings
from engine.api import PaperScene
from engine.render import render
from engine.scene import Material, Mesh, SceneError
from engine.shadernodes import GeometryInfo

W, H = 12, 9
HEIGHT, HALF = 5.0, 2.5


def _quad(z, half):
    v = np.array([[-half, -half, z], [half, -half, z], [half, half, z], [-half, half, z]])
    return v, np.array([[0, 1, 2], [0, 2, 3]])


def _scene(sheet_alpha=None):
    """A plane whose material writes Mask = 1 and Where = its hit's world position, seen
    from above (the background in the corners); with sheet_alpha a sheet 1 m above it of
    that alpha writing Mask = 0.25 and no Where."""
    s = PaperScene(W, H, background=(0.2, 0.2, 0.2))
    s.add_material(Material("top", (0.6, 0.3, 0.1), aovs={
        "Mask": {"value": 1.0, "color": (1.0, 1.0, 1.0)},
        "Where": {"color": GeometryInfo("POSITION"), "value": GeometryInfo("POSITION")}}))
    v, f = _quad(0.0, HALF)
    s.add_mesh(Mesh("floor", v, f, materials=["top"]))
    if sheet_alpha is not None:
        s.add_material(Material("sheet", (0.2, 0.5, 0.9), alpha=sheet_alpha,
                                aovs={"Mask": {"value": 0.25}}))
        v, f = _quad(1.0, 40.0)
        s.add_mesh(Mesh("sheet", v, f, materials=["sheet"]))
    s.add_point_light((1.0, 1.0, 3.0), power=100.0)
    s.set_camera((0.0, 0.0, HEIGHT), (0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), view_angle=60.0)
    return s


def _settings(**kw):
    base = dict(workers=1, spp=4, seed=3, photons=2_000, caustic_photons=200,
                shader_aovs=(("Mask", "value"), ("Where", "color")),
                data_passes=("position",))
    base.update(kw)
    return RenderSettings(**base)


def test_aovs_write_the_materials_outputs_at_the_camera_hits():
    film = render(_scene(), _settings(spp=1))
    d = film.data
    assert {"aov_value:Mask", "aov_color:Where", "aov_alpha:Where"} <= set(d)
    mask = d["aov_value:Mask"]
    seen = np.abs(d["position"]).sum(axis=2) > 0  # (written by the first sample)
    assert 0.5 * seen.size < seen.sum() < seen.size  # the background in the corners
    np.testing.assert_array_equal(mask[seen], 1.0)
    np.testing.assert_array_equal(mask[~seen], 0.0)
    # The colour: the hit's world position (at 1 sample the Position pass's own point),
    # its alpha 1 where written.
    np.testing.assert_allclose(d["aov_color:Where"][seen], d["position"][seen], atol=1e-5)
    np.testing.assert_array_equal(d["aov_alpha:Where"][seen], 1.0)
    np.testing.assert_array_equal(d["aov_alpha:Where"][~seen], 0.0)


def test_aovs_average_over_samples_and_leave_the_image_alone():
    with_aovs = render(_scene(), _settings())
    without = render(_scene(), _settings(shader_aovs=()))
    for name in ("combined", "direct", "indirect"):
        np.testing.assert_array_equal(getattr(with_aovs, name), getattr(without, name))
    mask = with_aovs.data["aov_value:Mask"]
    assert mask.min() >= 0.0 and mask.max() <= 1.0 + 1e-6
    edge = (mask > 0) & (mask < 1)  # pixels the plane's rim crosses: a share of samples
    assert edge.any()
    assert not any(k.startswith("aov_") for k in without.data)


@pytest.mark.parametrize("alpha,want", [(0.3, 1.25), (0.7, 0.25)])
def test_every_surface_of_the_transparent_chain_writes_until_the_single_pass(alpha, want):
    """A sheet of alpha 0.3 over the plane (threshold 0.5): a camera path that passes it
    (the transparent share, chosen as Cycles samples its transparent closure) has not
    ended the single pass, so both write (0.25 + 1), one the sheet stops writes its 0.25;
    at alpha 0.7 the sheet ends it: its 0.25 alone, the plane's Where nothing."""
    film = render(_scene(sheet_alpha=alpha), _settings(spp=1, seed=5))
    mask = film.data["aov_value:Mask"]
    centre = mask[H // 2 - 1:H // 2 + 2, W // 2 - 1:W // 2 + 2]
    if alpha < 0.5:
        assert np.all((np.abs(centre - want) < 1e-6) | (np.abs(centre - 0.25) < 1e-6))
        assert np.any(np.abs(centre - want) < 1e-6)
    else:
        np.testing.assert_allclose(centre, want)
        assert not film.data["aov_alpha:Where"].any()


def test_bad_aovs_are_named():
    with pytest.raises(ValueError, match="shader_aovs"):
        RenderSettings(shader_aovs=(("Mask", "vector"),))
    with pytest.raises(ValueError, match="named twice"):
        RenderSettings(shader_aovs=(("Mask", "value"), ("Mask", "color")))
    with pytest.raises(SceneError, match="material 'm' aovs 'Mask'"):
        Material("m", aovs={"Mask": {"normal": 1.0}})
    with pytest.raises(SceneError, match="value: must be finite"):
        Material("m", aovs={"Mask": {"value": float("nan")}})
