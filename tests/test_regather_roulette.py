"""Russian roulette on the level-2 regathers (integrator.REGATHER_SURVIVAL): a quarter of
the ends gather again, the others keep their lookup, the drawn ones add their correction
over the lookup x 4. Same expectation as regathering them all: checked over seeds on a
box whose corners regather twice, with the roulette on both levels (the default plays it
at level 2 only, whose share of the image is too small to test this way)."""
import numpy as np
import pytest

import engine.integrator as integ
from engine import RenderSettings, render
from engine.api import cornell_box


def _renders(monkeypatch, survival, seeds):
    monkeypatch.setattr(integ, "REGATHER_SURVIVAL", survival)
    scene = cornell_box(40, 30, glass_sphere=False)
    out = []
    for seed in seeds:
        film = render(scene, RenderSettings(spp=8, photons=40_000, caustic_photons=0,
                                            workers=1, seed=seed))
        out.append((np.asarray(film.combined, np.float64), film.stats["ray_stages"]))
    return out


def test_the_roulette_keeps_the_regathers_expectation(monkeypatch):
    seeds = range(4)
    full = _renders(monkeypatch, (1.0, 1.0), seeds)
    roulette = _renders(monkeypatch, (0.25, 0.25), seeds)
    a = np.mean([img.mean() for img, _ in full])
    b = np.mean([img.mean() for img, _ in roulette])
    assert b == pytest.approx(a, rel=0.01)
    # Corners' pixels (the box's edges) hold most level-2 regathers: compare them too.
    ia = np.mean([img for img, _ in full], axis=0)
    ib = np.mean([img for img, _ in roulette], axis=0)
    assert np.isfinite(ib).all()
    assert np.abs(ib - ia).mean() / ia.mean() < 0.03
    ends_full = sum(st.get("regathered 2", 0) for _, st in full)
    ends_rr = sum(st.get("regathered 2", 0) for _, st in roulette)
    kept = sum(st.get("regather kept lookup 2", 0) for _, st in roulette)
    assert ends_full > 0 and kept > 0
    ends1_full = sum(st.get("regathered 1", 0) for _, st in full)
    ends1_rr = sum(st.get("regathered 1", 0) for _, st in roulette)
    assert ends1_rr == pytest.approx(0.25 * ends1_full, rel=0.1)
    # (level 2's ends: a quarter of a quarter's)
    assert ends_rr == pytest.approx(0.0625 * ends_full, rel=0.3)
