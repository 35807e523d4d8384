"""Associated (premultiplied) alpha in image lookups, as Cycles' Image Texture node reads
an 8-bit image with alpha (engine/textures.py ImageTexture associate / unassociate):
Cycles premultiplies RGB by alpha at load (blender/image.cpp load_byte_pixels), filters
the premultiplied texels, and divides by the filtered alpha only where the node's Alpha
output is linked (svm/image.h NODE_IMAGE_ALPHA_UNASSOCIATE), before the sRGB decode."""
import numpy as np

from engine.imageio import srgb_decode
from engine.textures import ImageTexture

LEAF = (0.8, 0.6, 0.4)


def _edge(**kw):
    """1 x 2 texels: a leaf texel (alpha 1) and, beyond the outline, white at alpha 0
    (an image's RGB where it is cut away: anything)."""
    px = np.array([[[*LEAF, 1.0], [1.0, 1.0, 1.0, 0.0]]], np.float32)
    return ImageTexture(px, extension="EXTEND", srgb=True, **kw)


def _between(tex, t):
    """RGBA at fraction t of the way from the leaf texel's centre to the next one's."""
    return tex.sample_rgba(np.array([[0.25 + 0.5 * t, 0.5]]))[0]


def test_alpha_linked_keeps_the_leaf_colour_up_to_the_outline():
    tex = _edge(associate=True).unassociated()
    for t in (0.25, 0.5, 0.9):
        rgba = _between(tex, t)
        assert np.isclose(rgba[3], 1.0 - t)
        assert np.allclose(rgba[:3], srgb_decode(np.array(LEAF)), rtol=1e-6)


def test_colour_only_is_premultiplied_black_where_cut_away():
    tex = _edge(associate=True)
    half = _between(tex, 0.5)
    assert np.allclose(half[:3], srgb_decode(0.5 * np.array(LEAF)), rtol=1e-6)
    assert np.allclose(_between(tex, 1.0)[:3], 0.0)   # alpha 0: black, not the white


def test_straight_images_are_as_before():
    tex = _edge()
    assert not tex.associated
    assert np.allclose(_between(tex, 0.5)[:3],
                       srgb_decode(0.5 * np.array(LEAF) + 0.5), rtol=1e-6)
    assert np.allclose(_between(_edge().unassociated(), 1.0)[:3], 1.0)  # alpha 0: kept


def test_unassociated_shares_the_pixels():
    tex = _edge(associate=True)
    other = tex.unassociated()
    assert other.pixels is tex.pixels and not tex.unassociate and other.unassociate


def _float_edge(**kw):
    """The same edge as a float image holds it: premultiplied, linear."""
    px = np.array([[[*LEAF, 1.0], [0.0, 0.0, 0.0, 0.0]]], np.float32)
    return ImageTexture(px, extension="EXTEND", **kw)


def test_premultiplied_float_pixels_are_kept_and_divided_only_with_alpha_linked():
    tex = _float_edge(premultiplied=True)
    assert tex.associated and not tex.unassociate
    assert np.allclose(_between(tex, 0.5)[:3], 0.5 * np.array(LEAF), rtol=1e-6)
    linked = tex.unassociated()
    for t in (0.25, 0.5, 0.9):
        assert np.allclose(_between(linked, t)[:3], LEAF, rtol=1e-6)


def test_associate_and_premultiplied_exclude_each_other():
    import pytest
    from engine.textures import TextureError
    with pytest.raises(TextureError, match="exclude"):
        _float_edge(premultiplied=True, associate=True)
