"""Glass transmits per Fresnel, mirrors reflect where geometry says."""
import numpy as np

from engine import RenderSettings
from engine.api import PaperScene
from engine.bsdf import fresnel_dielectric
from engine.scene import Camera, Material


def test_fresnel_limits():
    assert np.isclose(fresnel_dielectric(np.array([1.0]), np.array([1.5]))[0], 0.04)
    assert fresnel_dielectric(np.array([1.0]), np.array([1.0]))[0] < 1e-12
    # Total internal reflection leaving glass at a grazing angle.
    assert fresnel_dielectric(np.array([0.2]), np.array([1 / 1.5]))[0] == 1.0


def test_glass_slab_transmittance_matches_fresnel():
    n = 1.5
    s = PaperScene(width=8, height=8)
    s.add_material(Material("backdrop", (0, 0, 0), emission=(1.0, 1.0, 1.0)))
    s.add_box((0, 0, 0), (4, 4, 0.2), "glass", name="slab")
    s.add_plane((0, 0, -1), (0, 0, 1), 6, "backdrop", name="backdrop")
    s.camera = Camera(position=(0, 0, 3), rotation=np.eye(3), kind="ORTHO", ortho_scale=1.0)
    film = s.render(RenderSettings(spp=2048, max_depth=32, photon_mapping=False, seed=1))
    R = ((n - 1) / (n + 1)) ** 2
    expected = (1 - R) / (1 + R)  # two faces with all internal reflections (incoherent)
    assert abs(film.combined.mean() - expected) / expected < 0.01


def test_mirror_reflects_where_geometry_says():
    s = PaperScene(width=40, height=40)
    s.add_material(Material("lamp", (0, 0, 0), emission=(2.0, 2.0, 2.0)))
    # Mirror plane y + z = 0 turns rays travelling along -y upwards (+z).
    s.add_plane((0, 0, 0), (0, 1, 1), 6, "mirror", name="mirror")
    s.add_plane((0, 0, 3), (0, 0, -1), 1.0, "lamp", name="lamp")
    rot = np.array([[1, 0, 0], [0, 0, 1], [0, 1, 0]], float)  # looks along -y, up = +z
    rot[:, 2] = [0, 1, 0]
    s.camera = Camera(position=(0, 10, 0), rotation=rot, kind="ORTHO", ortho_scale=2.0)
    film = s.render(RenderSettings(spp=4, photon_mapping=False))
    img = film.combined[..., 0]
    c = (np.arange(40) + 0.5) / 40 * 2 - 1
    x = np.tile(c, (40, 1))
    z = np.tile(-c[:, None], (1, 40))
    inside = (np.abs(x) < 0.45) & (np.abs(z) < 0.45)
    outside = (np.abs(x) > 0.55) | (np.abs(z) > 0.55)
    assert np.allclose(img[inside], 2.0 * 0.95, rtol=0.01)
    assert img[outside].max() == 0.0
    assert film.specular[inside].mean() > 0 and film.emission[inside].max() == 0
