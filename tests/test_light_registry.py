"""One module per light kind behind one registry (engine/lights/): the scene, the scene
file and the Blender export take their kinds from it, and every kind packs for the
direct-light kernels."""
import numpy as np
import pytest

import engine
from engine.api import PaperScene
from engine.geometry import prepare
from engine.lights import DECLARED_KINDS, LIGHT_KINDS, MESH, WORLD, prepare_lights
from engine.lights.packing import P, pack_lights
from engine.scene import Light, Material, SceneError


def test_registry_names_every_kind_once():
    assert set(DECLARED_KINDS) == {"POINT", "SPOT", "AREA", "SUN"}
    assert set(LIGHT_KINDS) == set(DECLARED_KINDS) | {MESH, WORLD}
    assert engine.DECLARED_KINDS == DECLARED_KINDS  # what addon/export.py reads
    for kind, cls in LIGHT_KINDS.items():
        assert cls.kind == kind


def test_unknown_kind_is_refused_with_the_registry_names():
    with pytest.raises(SceneError, match="unknown kind 'LASER' \\(POINT, SPOT, AREA, SUN\\)"):
        Light("beam", "LASER", 10.0)


def test_each_declared_light_prepares_as_its_class_and_packs():
    s = PaperScene(8, 6, background=(0.1, 0.1, 0.1))
    s.add_plane((0, 0, 0), (0, 0, 1), 4.0, "white_diffuse", name="floor")
    s.add_sphere((0, 0, 1), 0.3, Material("glow", emission=(2, 2, 2)), name="glow", segments=8)
    s.add_point_light((0, 0, 2), 10.0)
    s.add_spot_light((0, 1, 2), (0, 0, 0), 10.0)
    s.add_rect_area_light((0, 0, 3), (1.0, 1.0), 10.0)
    s.add_sun((0, 0, -1), 1.0)
    s.set_camera((0, -5, 2), (0, 0, 0))
    geo, table = prepare(s)
    lights = prepare_lights(s, geo, table)
    assert [type(li).kind for li in lights] == ["POINT", "SPOT", "AREA", "SUN", MESH, WORLD]
    codes, params, mesh = pack_lights(lights)
    assert len(set(codes.tolist())) == 6 and params.shape == (6, P)
    assert len(mesh[0]) == len(lights[4].tri_index) > 0
    assert np.all(np.isfinite(params))
