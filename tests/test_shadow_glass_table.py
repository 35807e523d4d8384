"""The flat passages' glass transmittance per crossing (shadowtransmittance._crossing)
reads a per-material table built once (glass_crossings) instead of setting up the whole
Principled closure per crossing: bitwise the transmittance of principled.setup's glass
lobe, TW x (1 - F), as before, for every kind of smooth glass a flat passage crosses."""
import numpy as np

from engine.closures import principled as pr
from engine.geometry import MaterialTable
from engine.photonkernels import flat_glass_materials
from engine.scene import Material
from engine.shadowtransmittance import _crossing, glass_crossings


def _materials():
    out = []
    for node in ("principled", "glass", "refraction"):
        for rough in (0.0, 0.004, 0.0099):
            for ior in (1.5, 1.33, 2.4, 0.8):
                for multi in (True, False):
                    out.append(Material(f"{node}-{rough}-{ior}-{multi}", (0.9, 0.55, 0.2),
                                        transmission=1.0, roughness=rough, ior=ior,
                                        node=node, multiscatter=multi,
                                        specular_tint=(1.0, 0.7, 0.4)))
    out.append(Material("white", (0.8, 0.8, 0.8)))  # not glass: its row is never read
    return out


def _setup_crossing(params, base, m, cos_o, front):
    """The transmittance as _crossing computed it before the table: principled.setup of
    one hit, then TW x (1 - F) per channel."""
    prm = np.empty((1, pr.N_PACK))
    w = np.empty((1, pr.N_LOBES, 3))
    pr.setup(np.array([m], np.int64), params, np.ascontiguousarray(base[m:m + 1]),
             np.array([cos_o]), np.array([front]), np.ones(1), prm, w)
    eta = prm[0, pr.P_GLASS_ETA]
    out = np.ones(3)
    for c in range(3):
        out[c] *= prm[0, pr.P_GLASS_TW + c] * (1.0 - pr._glass_F(prm[0, pr.P_GLASS_F0 + c],
                                                                  cos_o, eta))
    return out


def test_glass_table_crossing_is_bitwise_the_closure_setup():
    table = MaterialTable.build(_materials())
    flat = flat_glass_materials(table)
    assert flat[:-1].all() and not flat[-1]
    params = np.ascontiguousarray(table.closure_params, np.float64)
    base = np.ascontiguousarray(table.base_color, np.float64)
    glass = glass_crossings(params, base)
    assert glass.shape == (len(params), 2, 12)
    cosines = np.concatenate([[0.0, 1e-5, 0.3, 0.5, 1.0 - 1e-12, 1.0],
                              np.random.default_rng(3).random(40)])
    differ = 0
    for m in np.flatnonzero(flat):
        for side, front in ((0, True), (1, False)):
            for cos_o in cosines:
                want = _setup_crossing(params, base, m, cos_o, front)
                got = np.ones(3)
                _crossing(glass, m, side, cos_o, got)
                assert got.tobytes() == want.tobytes(), (table.names[m] if hasattr(
                    table, "names") else m, side, cos_o, got, want)
                differ += not np.all(want == want[0])
    assert differ > 0  # tinted glass: the channels differ (the test sees each one)


def test_glass_table_of_no_materials_is_empty():
    assert glass_crossings(np.zeros((0, pr.N_MAT)), np.zeros((0, 3))).shape == (0, 2, 12)
