import numpy as np

from engine import RenderSettings
from engine.api import cornell_box


def test_same_seed_gives_the_same_image_and_other_seed_differs():
    s = cornell_box(40, 30)
    st = dict(photons=8000, caustic_photons=8000, spp=2)
    a = s.render(RenderSettings(seed=5, **st)).combined
    b = s.render(RenderSettings(seed=5, **st)).combined
    c = s.render(RenderSettings(seed=6, **st)).combined
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def test_worker_count_does_not_change_the_image():
    s = cornell_box(40, 30)
    st = dict(photons=8000, caustic_photons=8000, spp=2, seed=2)
    one = s.render(RenderSettings(workers=1, **st)).combined
    two = s.render(RenderSettings(workers=2, **st)).combined
    np.testing.assert_array_equal(one, two)
