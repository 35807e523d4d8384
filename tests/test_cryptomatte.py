"""Cryptomatte ID mattes (engine/cryptomatte.py): the hash and its float encoding, the
ranked coverage, and a render's passes against the scene they see."""
import numpy as np
import pytest

from engine import cryptomatte as cm
from engine.api import PaperScene
from engine.settings import RenderSettings


def test_murmur3_matches_the_reference_vectors():
    # MurmurHash3_x86_32 test vectors (Appleby's SMHasher; seed 0 unless given).
    assert cm.murmur3_32(b"") == 0
    assert cm.murmur3_32(b"", 1) == 0x514E28B7
    assert cm.murmur3_32(b"hello") == 0x248BFA47
    assert cm.murmur3_32(b"Hello, world!", 1234) == 0xFAF6CDB3
    assert cm.murmur3_32(b"The quick brown fox jumps over the lazy dog") == 0x2E4FF723


def test_the_float_id_is_never_denormal_infinite_or_nan():
    for h in (0, 0x007FFFFF, 0x7F800000, 0xFF800001, 0x80000000, 0x12345678):
        f = np.float32(cm.hash_to_float(h))
        assert np.isfinite(f) and (f == 0 or abs(f) >= np.finfo(np.float32).tiny)
        bits = int(np.array([f], np.float32).view(np.uint32)[0])
        assert bits & 0x807FFFFF == h & 0x807FFFFF  # sign and mantissa kept
    # Exponents 1..254 are kept as they are.
    assert np.array([cm.hash_to_float(0x3F800000)], np.float32)[0] == 1.0


def test_metadata_keys_are_blenders():
    meta = cm.metadata("ViewLayer", "object", ["Cube", "Cube", "Sphere"])
    layer_hash = f"{cm.murmur3_32(b'ViewLayer.CryptoObject'):08x}"[:7]
    assert meta[f"cryptomatte/{layer_hash}/name"] == "ViewLayer.CryptoObject"
    assert meta[f"cryptomatte/{layer_hash}/hash"] == "MurmurHash3_32"
    assert meta[f"cryptomatte/{layer_hash}/conversion"] == "uint32_to_float32"
    import json
    manifest = json.loads(meta[f"cryptomatte/{layer_hash}/manifest"])
    assert manifest == {"Cube": f"{cm.name_hash('Cube'):08x}",
                        "Sphere": f"{cm.name_hash('Sphere'):08x}"}


def test_ranked_coverage_keeps_the_most_covered_ids_in_order():
    # Pixel 0: id 7 three times, id 5 once, id 9 twice; pixel 2: id 4 once; 4 samples.
    pix = np.array([0, 0, 0, 0, 0, 0, 2])
    ids = np.array([7, 5, 7, 9, 7, 9, 4], np.uint32)
    bits, cov = cm.ranked_coverage(pix, ids, npix=3, samples=8, ranks=2)
    assert bits[0].tolist() == [7, 9] and cov[0].tolist() == [3 / 8, 2 / 8]
    assert bits[1].tolist() == [0, 0] and cov[1].tolist() == [0, 0]
    assert bits[2].tolist() == [4, 0] and cov[2].tolist() == [1 / 8, 0]
    # Ties go by id, so the order never depends on the samples' order.
    b1, _ = cm.ranked_coverage(np.array([1, 1]), np.array([9, 3], np.uint32), 2, 2, 2)
    b2, _ = cm.ranked_coverage(np.array([1, 1]), np.array([3, 9], np.uint32), 2, 2, 2)
    assert b1[1].tolist() == b2[1].tolist() == [3, 9]


def _scene():
    s = PaperScene(width=48, height=36)
    s.add_plane((0, 0, 0), size=20.0, name="Floor")
    s.add_box((-0.6, 0, 0.5), (1, 1, 1), name="Left")
    s.add_box((0.6, 0, 0.5), (1, 1, 1), material="red_plastic_dull"
              if "red_plastic_dull" in s.materials else "white_plastic_dull", name="Right")
    s.meshes[-1].cryptomatte_asset = "Boxes"
    s.meshes[-2].cryptomatte_asset = "Boxes"
    s.add_point_light((0, -2, 4), power=200.0)
    s.set_camera((0, -5, 2.5), (0, 0, 0.5), view_angle=40.0)
    return s


@pytest.mark.parametrize("workers", [1, 2])
def test_a_renders_mattes_name_what_each_pixel_sees(workers):
    s = _scene()
    settings = RenderSettings(spp=4, photons=2000, caustic_photons=0, seed=3,
                              workers=workers, cryptomatte=("object", "asset", "material"),
                              cryptomatte_levels=3)
    film = s.render(settings)
    assert set(film.cryptomatte) == {"object", "asset", "material"}
    obj = film.cryptomatte["object"]
    assert len(obj) == 2 and obj[0].shape == (36, 48, 4)  # 3 levels: 2 passes
    ids = {n: np.float32(cm.hash_to_float(cm.name_hash(n))) for n in ("Floor", "Left", "Right")}
    first_id, first_cov = obj[0][..., 0], obj[0][..., 1]
    # The lower half sees the floor or a box in every sample, so its coverage sums to 1
    # over the ranks; pixels at the floor's far edge share their samples with the
    # background (no id), the sky none; the largest rank is one of the three.
    total = sum(p[..., 1] + p[..., 3] for p in obj)
    assert np.allclose(total[18:], 1.0)
    assert (total <= 1.0 + 1e-6).all() and (total[:3] == 0).all()
    seen = total > 0
    assert set(np.unique(first_id[seen])) <= set(ids.values())
    # The boxes' middles are all one box, their edges share pixels with the floor.
    whole = first_cov == 1.0
    for name in ("Floor", "Left", "Right"):
        assert (whole & (first_id == ids[name])).sum() > 20, name
    # The boxes stand left and right of the middle, as the camera sees them.
    cols = np.nonzero(whole & (first_id == ids["Left"]))[1]
    assert cols.max() < 24 <= np.nonzero(whole & (first_id == ids["Right"]))[1].min()
    fractional = (first_cov > 0) & (first_cov < 1)
    assert fractional.any()  # antialiased edges
    # The asset layer merges the boxes: Boxes covers at least what Left and Right do.
    asset = film.cryptomatte["asset"][0]
    boxes = np.float32(cm.hash_to_float(cm.name_hash("Boxes")))
    box_cov = sum(np.where(p[..., 0] == boxes, p[..., 1], 0) + np.where(p[..., 2] == boxes,
                                                                          p[..., 3], 0)
                  for p in film.cryptomatte["asset"])
    obj_cov = sum(np.where(np.isin(p[..., 0], [ids["Left"], ids["Right"]]), p[..., 1], 0)
                  + np.where(np.isin(p[..., 2], [ids["Left"], ids["Right"]]), p[..., 3], 0)
                  for p in obj)
    assert np.allclose(box_cov, obj_cov, atol=1e-6)
    assert (asset[..., 0] == boxes).any()
    assert film.cryptomatte_names["asset"][1:] == ["Boxes", "Boxes"]
    assert film.cryptomatte_names["object"] == ["Floor", "Left", "Right"]


def test_the_mattes_are_the_same_for_any_worker_count_and_leave_the_image_alone():
    s = _scene()
    base = dict(spp=4, photons=2000, caustic_photons=0, seed=3, cryptomatte_levels=6)
    one = s.render(RenderSettings(workers=1, cryptomatte=("object",), **base))
    two = s.render(RenderSettings(workers=2, cryptomatte=("object",), **base))
    none = s.render(RenderSettings(workers=1, **base))
    for a, b in zip(one.cryptomatte["object"], two.cryptomatte["object"]):
        assert np.array_equal(a, b)
    assert np.array_equal(one.combined, none.combined)
    assert none.cryptomatte == {}


def test_settings_refuse_unknown_kinds_and_levels():
    with pytest.raises(ValueError, match="setting 'cryptomatte' takes"):
        RenderSettings(cryptomatte=("objects",))
    with pytest.raises(ValueError, match="cryptomatte_levels"):
        RenderSettings(cryptomatte_levels=0)
    assert RenderSettings(cryptomatte="Object").cryptomatte == ("object",)


def test_the_memory_estimate_counts_the_mattes_and_names_their_setting():
    from engine.resources import ResourceError, check_resources, estimate_memory
    s = _scene()
    s.width, s.height = 1920, 1080
    plain = estimate_memory(s, RenderSettings(spp=16))
    mattes = estimate_memory(s, RenderSettings(spp=16, cryptomatte=("object", "material"),
                                               cryptomatte_levels=6))
    part = mattes.parts["cryptomatte"]
    # 2 layers x 6 ranks x 20 B a pixel, and one chunk of rays.
    assert part >= 1920 * 1080 * 12 * 20
    assert mattes.total - plain.total == part
    with pytest.raises(ResourceError, match="cryptomatte_levels"):
        check_resources(s, RenderSettings(spp=1, photons=1000, caustic_photons=0,
                                          cryptomatte=("object", "material", "asset"),
                                          cryptomatte_levels=16),
                        available=mattes.total // 2)
    # A tuple setting (data_passes) is named, not a formatting error.
    from engine.resources import _setting_text
    text = _setting_text("data_passes", s, RenderSettings(data_passes=("denoising",)))
    assert text == "setting 'data_passes' = ('denoising',)"


def test_the_cli_writes_the_mattes_as_the_specs_exr(tmp_path):
    """photonmap render --cryptomatte object,material --save-passes: name.cryptomatte.exr
    with the spec's channel names and the layers' manifests in its header; progressive
    renders make them too."""
    import OpenEXR

    from engine.cli import main
    scene = tmp_path / "s.toml"
    scene.write_text(
        "[render]\nwidth = 24\nheight = 18\nspp = 2\nphotons = 500\ncaustic_photons = 0\n"
        "[camera]\nposition = [0, -5, 2.5]\nlook_at = [0, 0, 0.5]\n"
        "[[lights]]\ntype = \"point\"\nposition = [0, -2, 4]\npower = 200\n"
        "[[objects]]\nname = \"Floor\"\ntype = \"plane\"\ncenter = [0, 0, 0]\nsize = 20\n"
        "[[objects]]\nname = \"Box\"\ntype = \"box\"\ncenter = [0, 0, 0.5]\n"
        "size = [1, 1, 1]\n")
    for extra in ([], ["--progressive", "--passes", "2"]):
        out = tmp_path / f"img{len(extra)}.png"
        code = main(["render", str(scene), "-o", str(out), "--quiet", "--save-passes",
                     "--cryptomatte", "object,material", "--cryptomatte-levels", "2",
                     *extra])
        assert code == 0
        f = OpenEXR.File(str(tmp_path / f"img{len(extra)}.cryptomatte.exr"),
                         separate_channels=True)
        channels = f.parts[0].channels
        assert {"ViewLayer.CryptoObject00.r", "ViewLayer.CryptoObject00.a",
                "ViewLayer.CryptoMaterial00.g"} <= set(channels)
        assert "ViewLayer.CryptoObject01.r" not in channels  # Levels 2: one pass
        meta = {k: v for k, v in f.parts[0].header.items() if k.startswith("cryptomatte/")}
        assert sorted(v for k, v in meta.items() if k.endswith("/name")) == [
            "ViewLayer.CryptoMaterial", "ViewLayer.CryptoObject"]
        ids = channels["ViewLayer.CryptoObject00.r"].pixels
        box = np.float32(cm.hash_to_float(cm.name_hash("Box")))
        assert (ids == box).sum() > 4
    with pytest.raises(SystemExit):
        main(["render", str(scene), "-o", str(tmp_path / "x.png"), "--cryptomatte", "objects"])
