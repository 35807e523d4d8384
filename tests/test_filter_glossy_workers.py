"""Cycles' Filter Glossy (engine/filterglossy.py's camera-path blur, engine/glossysplit.py's
split between the caustic / glow maps and the gather chains) and the world probes give
the same image for any worker count: every random stream they draw is the chunk's."""
import numpy as np

from engine import RenderSettings
from engine.api import PaperScene
from engine.render import render
from engine.scene import Material


def _scene():
    """A rough metal floor under an area lamp and a constant grey world; a mirror ball on
    the floor (camera -> floor -> mirror: blurred), a diffuse wall (the floor's glow on
    it: the split's chains) and a white diffuse block."""
    s = PaperScene(width=12, height=9, background=(0.2, 0.2, 0.2))
    s.add_material(Material("metal", (0.9, 0.9, 0.9), metallic=1.0, roughness=0.3))
    s.add_material(Material("mirror", (0.9, 0.9, 0.9), metallic=1.0, roughness=0.0))
    s.add_material(Material("white", (0.8, 0.8, 0.8), specular=0.0))
    s.add_plane((0, 0, 0), size=8.0, material="metal", name="Floor")
    s.add_plane((0, 2.0, 2.0), normal=(0, -1, 0), size=4.0, material="white", name="Wall")
    s.add_sphere((0.6, 0.5, 0.5), 0.5, material="mirror", name="Ball", segments=16)
    s.add_box((-0.8, 0.8, 0.4), (0.6, 0.6, 0.8), material="white", name="Block")
    s.add_rect_area_light((-0.5, -0.5, 2.5), size=(0.5, 0.5), power=300.0)
    s.set_camera((0.0, -3.0, 2.6), (0.0, 1.0, 0.8), view_angle=40)
    return s


def test_filter_glossy_1_is_the_same_for_one_and_two_workers():
    s = _scene()
    base = dict(photons=2_000, caustic_photons=2_000, spp=2, seed=3,
                cycles_filter_glossy=1.0)
    one = render(s, RenderSettings(workers=1, **base))
    two = render(s, RenderSettings(workers=2, **base))
    a, b = np.asarray(one.combined), np.asarray(two.combined)
    assert np.all(np.isfinite(a)) and a.mean() > 0
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(np.asarray(one.caustic), np.asarray(two.caustic))
    # (the blur and the split are on here: Filter Glossy 0 renders another image)
    zero = render(s, RenderSettings(workers=2, **dict(base, cycles_filter_glossy=0.0)))
    assert not np.array_equal(np.asarray(zero.combined), b)


def test_gather_chains_start_at_the_camera_paths_min_ray_pdf(monkeypatch):
    """Cycles' min_ray_pdf is the path's: camera -> rough metal M -> diffuse D -> S blurs
    S by min(pdf_M, pdf_D), not by D's pdf alone. The split's pdf at D
    (glossysplit.DiffusePdf) is at most the camera path's min_ray_pdf
    (SurfaceHit.min_ray_pdf, set by integrator._trace_paths): the level-0 gather chains
    start there and the maps' per-photon test reads the same number."""
    from engine import glossysplit
    from engine.bsdf import surface_hit
    from engine.integrator import Counters, gather_indirect
    from engine.render import _photon_pass, prepare_context
    s = _scene()
    ctx = prepare_context(s, RenderSettings(workers=1, photons=2_000, caustic_photons=2_000,
                                            seed=1, cycles_filter_glossy=1.0))
    try:
        _photon_pass(ctx, {}, None, None)
        assert glossysplit.maps_blurred(ctx)
        # Rays from the camera's side to the wall (y = 2): its diffuse hits.
        n = 400
        rng = np.random.default_rng(4)
        o = np.tile([0.0, -1.0, 1.5], (n, 1))
        target = np.column_stack([rng.uniform(-1, 1, n), np.full(n, 2.0),
                                  rng.uniform(1.0, 3.0, n)])
        d = target - o
        d /= np.linalg.norm(d, axis=1)[:, None]
        t, prim, u, v = ctx.accel.intersect(o, d)
        ok = prim >= 0
        hit = surface_hit(ctx.geo, ctx.table, prim[ok], u[ok], v[ok], d[ok])
        m = int(ok.sum())
        cam = np.full(m, np.inf)
        cam[::2] = 0.01  # half the hits came through a glossy bounce of pdf 0.01
        hit.min_ray_pdf = cam
        seen = []
        real = glossysplit.GatherChains.vertex

        def spy(self, y, rows_idx, *a, **k):
            seen.append((rows_idx.copy(), self.min_pdf[rows_idx].copy()))
            return real(self, y, rows_idx, *a, **k)

        monkeypatch.setattr(glossysplit.GatherChains, "vertex", spy)
        gather_indirect(ctx, hit, np.random.default_rng(5), Counters())
        # The maps' side alike: no photon counts where the camera path's pdf is below
        # Filter Glossy (the same predicate as the chains': each path counted once).
        d_pdf = glossysplit.DiffusePdf(ctx, hit, 1.0)
        assert np.all(d_pdf.largest[::2] <= 0.01)
        wi = np.tile(hit.ns[:1], (m, 1))
        assert np.all(d_pdf.pdf(np.arange(m), wi, np.tile(hit.ns[:1], (m, 1)))[::2] <= 0.01)
    finally:
        ctx.accel.close()
    rows = np.concatenate([r for r, _ in seen])
    pdfs = np.concatenate([p for _, p in seen])
    assert len(rows) > 10
    through = (rows % 2) == 0
    assert through.any() and (~through).any()
    assert np.all(pdfs[through] <= 0.01)
    assert np.all(pdfs[~through] > 0.0)
    assert (pdfs[~through] > 0.01).any()  # D's own cos / pi there


def test_blur_alphas_warns_nothing():
    """blur_alphas hands the kernel arrays of its own (np.broadcast_arrays' views made
    numba warn, FutureWarning, on every render with Filter Glossy: effects'
    filter_glossy_alpha calls it in prepare_context)."""
    import warnings
    from engine.filterglossy import blur_alpha, blur_alphas
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for fg, pdf in ((1.0, np.array([0.1, 0.2])), (np.ones(2), np.array([0.1, 2.0])),
                        (1.0, [1.0 / np.pi, 0.0]), (np.ones(3), 0.5)):
            got = blur_alphas(fg, pdf)
            want = [blur_alpha(f, p) for f, p in zip(*np.broadcast_arrays(fg, pdf))]
            np.testing.assert_array_equal(got, want)


def test_camera_paths_hand_their_min_ray_pdf_to_the_gather(monkeypatch):
    """integrator._trace_paths sets SurfaceHit.min_ray_pdf on the hits past the first
    bounce (the rough floor's reflections of the wall and the block), which the level-0
    gather reads (the test above)."""
    from engine import integrator
    seen = []
    real = integrator.gather_indirect

    def spy(ctx, hit, *a, **k):
        if k.get("level", 0) == 0 and not k.get("glow_only", False):
            m = getattr(hit, "min_ray_pdf", None)
            seen.append(np.inf if m is None or not len(m) else float(np.min(m)))
        return real(ctx, hit, *a, **k)

    monkeypatch.setattr(integrator, "gather_indirect", spy)
    render(_scene(), RenderSettings(workers=1, photons=2_000, caustic_photons=2_000, spp=1,
                                    seed=3, cycles_filter_glossy=1.0))
    assert seen and np.isinf(seen).any()  # the camera's first hits: none
    assert any(np.isfinite(v) and 0 < v < 1.0 / np.pi for v in seen)
