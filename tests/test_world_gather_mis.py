"""A constant world at the camera's diffuse hits by its shadow rays and the final gather's
escaping rays, both cosine-distributed: each ray of either kind counts 1 / (n_s + G) of
the world's light (integrator.world_gather, WORLD_GATHER_MIS; docs/performance.md
"worlds56").

- Furnace: a Lambert floor that sees the whole sky (the only other object below it)
  reads albedo x the world's radiance in its Direct pass at every pixel and sample, with
  and without (the weights of the n_s + G rays sum to 1 whatever each ray meets).
- Occlusion: a floor and a block (with and without an area light): the Direct pass keeps
  its mean over paired seeds, the image's variance falls, the other passes are the same
  bits (no random number moves).
- Where it does not apply (Cycles' clamps) nothing changes.
"""
import numpy as np
import pytest

from engine import RenderSettings
from engine import integrator
from engine.api import PaperScene, box_mesh
from engine.scene import Material

WORLD = (0.5, 0.65, 0.9)
ALBEDO = 0.6


def _render(scene, on, **kw):
    old = integrator.WORLD_GATHER_MIS
    integrator.WORLD_GATHER_MIS = on
    try:
        return scene.render(RenderSettings(**{"spp": 8, "photons": 4000, "seed": 1, **kw}))
    finally:
        integrator.WORLD_GATHER_MIS = old


def _applied(monkeypatch):
    """A list that records, per shade_diffuse call, whether world_gather applied."""
    seen = []
    orig = integrator.world_gather

    def spy(ctx, clamping):
        r = orig(ctx, clamping)
        seen.append(r is not None)
        return r
    monkeypatch.setattr(integrator, "world_gather", spy)
    return seen


def test_on_by_default():
    assert integrator.WORLD_GATHER_MIS is True


def _open_floor():
    s = PaperScene(width=12, height=12, background=WORLD)
    s.add_material(Material("lambert", (ALBEDO,) * 3, specular=0.0, roughness=1.0))
    s.add_plane((0, 0, 0), (0, 0, 1), 40.0, "lambert", name="floor")
    # (a second object, under the floor: the scene is not one flat surface, so the final
    # gather runs, and nothing stands above the floor)
    v, f = box_mesh((0.0, 0.0, -3.0), 1.0)
    s.add_triangles(v, f, "lambert", name="below")
    s.set_camera((0, 0, 3.0), (0, 0.001, -1), view_angle=20)
    return s


def test_furnace_floor_reads_albedo_times_world(monkeypatch):
    seen = _applied(monkeypatch)
    s = _open_floor()
    want = ALBEDO * np.array(WORLD)
    for on in (False, True):
        seen.clear()
        film = _render(s, on)
        assert all(seen) == on and seen, (on, seen)
        direct = np.asarray(film.direct, np.float64)
        # every pixel, every sample: the weights of the shadow rays and the escaping
        # gather rays sum to 1 (float32 film)
        assert np.allclose(direct, want, rtol=2e-5, atol=0), (on, direct.min(), direct.max())


def _floor_and_block():
    s = PaperScene(width=20, height=16, background=WORLD)
    s.add_material(Material("floor", (ALBEDO,) * 3, specular=0.0, roughness=1.0))
    s.add_material(Material("block", (0.2, 0.6, 0.3), specular=0.0, roughness=1.0))
    s.add_plane((0, 0, 0), (0, 0, 1), 8.0, "floor", name="floor")
    v, f = box_mesh((0.0, 0.6, 0.5), 1.0)
    s.add_triangles(v, f, "block", name="block")
    s.set_camera((0, -3.5, 1.2), (0, 0.9, -0.35), view_angle=50)
    return s


@pytest.mark.parametrize("lamp", [False, True])
def test_occluded_world_keeps_its_mean_with_less_noise(monkeypatch, lamp):
    """With a lamp too (an area light over the block: its surface stops neither the
    gather rays nor the world's shadow rays), the lamp's light by its own shadow rays."""
    seen = _applied(monkeypatch)
    s = _floor_and_block()
    if lamp:
        s.add_rect_area_light((0.8, -0.5, 2.5), (0.6, 0.6), power=40.0)
    seeds = range(6)
    films = {on: [_render(s, on, seed=k) for k in seeds] for on in (False, True)}
    assert seen and all(seen[len(seen) // 2:]) and not any(seen[:len(seen) // 2])
    direct = {on: np.stack([np.asarray(f.direct, np.float64) for f in films[on]])
              for on in films}
    # paired seeds: the difference of the pass's image means against its spread
    diff = direct[True].mean(axis=(1, 2, 3)) - direct[False].mean(axis=(1, 2, 3))
    se = diff.std(ddof=1) / np.sqrt(len(seeds))
    m_off = direct[False].mean()
    assert abs(diff.mean()) < max(4 * se, 1e-3 * m_off), (diff.mean(), se, m_off)
    comb = {on: np.stack([np.asarray(f.combined, np.float64) for f in films[on]])
            for on in films}
    var = {on: float(np.var(comb[on], axis=0, ddof=1).mean()) for on in comb}
    # (two shadow rays and one gather ray: the world's part 2/3 of its variance; the
    # lamp's part as it was)
    assert var[True] < (0.95 if lamp else 0.85) * var[False], var
    assert comb[True].min() >= 0.0
    for a, b in zip(films[False], films[True]):
        # (the escaping gather rays add to Direct alone; no stream moves)
        for n in ("indirect", "caustic", "specular", "emission"):
            assert np.array_equal(getattr(a, n), getattr(b, n)), n


def test_clamp_direct_renders_are_unchanged(monkeypatch):
    seen = _applied(monkeypatch)
    s = _floor_and_block()
    a = _render(s, False, clamp_direct=10.0, spp=4)
    b = _render(s, True, clamp_direct=10.0, spp=4)
    assert seen and not any(seen)
    assert np.array_equal(a.combined, b.combined)


def test_blenders_default_clamp_indirect_keeps_it_at_first_hits(monkeypatch):
    """Blender's Light Paths defaults (Clamp Direct 0, Indirect 10): Cycles clamps a
    first hit's world light by Clamp Direct only, so the escaping gather rays count there;
    the Direct pass keeps its mean, the other passes their bits."""
    seen = _applied(monkeypatch)
    s = _floor_and_block()
    a = _render(s, False, clamp_indirect=10.0, spp=4)
    b = _render(s, True, clamp_indirect=10.0, spp=4)
    assert any(seen)
    for n in ("indirect", "caustic", "specular", "emission"):
        assert np.array_equal(getattr(a, n), getattr(b, n)), n
    da, db = a.direct.mean(), b.direct.mean()
    assert abs(db - da) < 0.02 * da, (da, db)
