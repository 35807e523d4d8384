"""The sampler's dimensions are handed out so that no two consumers share one (issue 13):
a light's shadow samples and the final-gather rays each get their own stratification."""
import numpy as np
import pytest

from engine.integrator import camera_dimensions
from engine.sampling import SampleDimensions, StratifiedSampler


def test_no_two_consumers_share_a_dimension():
    # 70 samples per light: before allocation, light 0's sample 63 took gather ray 1's
    # dimension (65) and its samples 64.. took light 1's (66..).
    dims = camera_dimensions(2, [70, 70, 1])
    numbers = list(dims.numbers().values())
    assert len(dims) == 2 + 70 + 70 + 1
    assert len(set(numbers)) == len(numbers)


def test_numbers_kept_where_nothing_collided():
    dims = camera_dimensions(3, [4, 1, 16])
    assert dims.moved == []
    for g in range(3):
        assert dims[("gather", g)] == 1 + 64 * g
    for li, n in enumerate([4, 1, 16]):
        for si in range(n):
            assert dims[("light", li, si)] == 2 + 64 * li + si


def test_only_the_later_of_two_colliding_streams_moves():
    dims = camera_dimensions(2, [66, 3])
    # gather 1 keeps 65; light 0's sample 63 moves; its samples 64, 65 lose 66, 67 to
    # light 1's samples 0, 1 (lower sample index claims first).
    assert dims[("gather", 1)] == 65
    assert set(dims.moved) == {("light", 0, 63), ("light", 0, 64), ("light", 0, 65)}
    assert dims[("light", 1, 0)] == 66 and dims[("light", 1, 1)] == 67
    top = max(2 + 64 * li + si for li, n in enumerate([66, 3]) for si in range(n))
    assert all(dims[k] > top for k in dims.moved)


def test_bad_requests_are_refused_clearly():
    with pytest.raises(ValueError, match="requested twice"):
        SampleDimensions([(("gather", 0), 1), (("gather", 0), 5)])
    dims = SampleDimensions([(("gather", 0), 1)])
    with pytest.raises(KeyError, match="not requested"):
        dims[("light", 0, 0)]


def test_streams_of_distinct_dimensions_are_not_stratified_alike():
    """Two keys with distinct dimensions visit their pixels' cells in different orders
    (the hash shift differs for most pixels); with a shared dimension they were equal."""
    spp, npix = 16, 4096
    sample = np.arange(npix * spp)
    dims = camera_dimensions(2, [64, 1])
    s = StratifiedSampler(sample % spp, sample // spp, spp, np.random.default_rng(1), dims)
    a, _ = s.uv(("light", 0, 63))
    b, _ = s.uv(("gather", 1))
    cell_a, cell_b = np.floor(a * 4), np.floor(b * 4)
    assert np.mean(cell_a == cell_b) < 0.5
