"""A cut-out card between a single-plane window pane and the floor it lights
(engine/panelight.py _past_passes, photonkernels.F_PANE_PLANE, glossysplit.GatherChains'
carried panes past transparent passes; docs/accuracy.md "passages56").

The world's light through a pane is the floor's direct light, by the pane's next-event
shadow rays; a card of alpha 0.5 under the pane halves it exactly (the shadow rays cross
it as any shadow ray crosses a transparent pass). The floor's own light the pane's
underside reflects back (total internal reflection: the floor lies on the glass side)
crosses the card twice, a quarter of it each bounce. So with B_d and B the bare floor's
Direct pass and image, k = 1 - B_d / B the share each bounce under the pane returns,
the floor with the card reads (B_d / 2) / (1 - k / 4). Before, the card stopped the
shadow rays and the light came from the caustic map's unaimed photons (0.1028 where this
gives 0.1085 at Filter Glossy 0).
"""
import numpy as np
import pytest

from engine import RenderSettings
from engine.render import render
from test_split_window_card import _floor_under_window


def _passes(scene, fg):
    r = render(scene, RenderSettings(photons=20_000, caustic_photons=20_000, spp=16, seed=1,
                                     workers=1, cycles_filter_glossy=fg))
    return {k: float(np.mean(getattr(r, k))) for k in ("combined", "direct", "caustic")}


@pytest.mark.parametrize("fg", [0.0, 1.0])
def test_a_card_under_a_pane_halves_its_direct_light(fg):
    """Measured (16 spp, seed 1): see docs/accuracy.md "passages56"."""
    bare = _passes(_floor_under_window("plane"), fg)
    card = _passes(_floor_under_window("plane", card_z=0.6), fg)
    assert bare["direct"] > 0.1, bare
    assert card["direct"] / bare["direct"] == pytest.approx(0.5, abs=0.01), (card, bare)
    # (no caustic: the light through the pane and the card is direct, its photons too)
    assert card["caustic"] < 0.01 * card["combined"], card
    k = 1.0 - bare["direct"] / bare["combined"]
    expect = 0.5 * bare["direct"] / (1.0 - k / 4.0)
    assert card["combined"] == pytest.approx(expect, rel=0.03), (card, bare, expect)


def test_without_transparent_shadows_the_cards_light_rests_on_photons():
    """Transparent bounces 0: no shadow ray crosses the card (ctx.shadow is None), so
    the pane's light past it must come from the photons, caustic as before passages56
    (photons.F_PANE_PLANE dropped); it was lost from both (0.0: review56 M2)."""
    scene = _floor_under_window("plane", card_z=0.6)
    r = render(scene, RenderSettings(photons=20_000, caustic_photons=20_000, spp=8, seed=1,
                                     workers=1, transparent_max_bounces=0))
    assert float(np.mean(r.direct)) == 0.0
    with_shadows = render(scene, RenderSettings(photons=20_000, caustic_photons=20_000,
                                                spp=8, seed=1, workers=1))
    assert float(np.mean(r.caustic)) > 0.8 * float(np.mean(with_shadows.direct))
