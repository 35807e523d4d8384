"""photonkernels.lobe_adjoint: a photon scattered off a Principled hit's diffuse base,
metal, specular or coat lobe takes the terms Cycles reads at the view direction (Multiscatter
GGX's energy compensation, the layers' albedos above the base) at its outgoing cosine
instead of its arrival cosine. Checked against the formulas of Cycles'
microfacet_ggx_preserve_energy and closure_layering_weight (engine/closures/ggx.py,
tables.py), and the invariant: the same cosine on both sides changes nothing. The scene
effect against Cycles: tests/blender/test_reflected_panel_cycles.py."""
import numpy as np
import pytest

from engine import photonkernels as pk
from engine.closures import ggx, tables
from engine.closures import principled as pr
from engine.closures.fresnel import F0_from_ior, f82_Fss


def _material(**cols):
    P = np.zeros((1, pr.N_MAT))
    P[0, pr.M_ALPHA] = 1.0
    P[0, pr.M_LEVEL] = 0.5
    P[0, pr.M_IOR] = 1.5
    P[0, pr.M_STINT:pr.M_STINT + 3] = 1.0
    P[0, pr.M_CTINT:pr.M_CTINT + 3] = 1.0
    P[0, pr.M_TTINT:pr.M_TTINT + 3] = 1.0
    for k, v in cols.items():
        P[0, getattr(pr, k)] = v
    return P


def _adjoint(P, base, mu_in, mu_out, lobe):
    """lobe_adjoint for one hit of material row 0 that arrived at cosine mu_in."""
    base = np.asarray([base], np.float64)
    prm, w = pr.setup_np(P, [0], base, [mu_in], [True])
    return np.array(pk.lobe_adjoint(P, 0, base, 0, True, 1.0, prm, w, 0, lobe, mu_out,
                                    pk.make_adjoint_scratch()))


@pytest.mark.parametrize("mu_in, mu_out", [(0.15, 0.8), (0.9, 0.3), (0.5, 0.5)])
def test_metal_takes_the_energy_compensation_at_its_outgoing_side(mu_in, mu_out):
    rough, base = 0.8, (0.9, 0.6, 0.3)
    P = _material(M_METALLIC=1.0, M_ROUGH=rough, M_MULTI=1.0)
    got = _adjoint(P, base, mu_in, mu_out, pr.L_METAL)
    E_avg = tables.ggx_Eavg(rough)
    want = [ggx.energy_factor(tables.ggx_E(rough, mu_out), E_avg, f82_Fss(f0, 0.0))
            / ggx.energy_factor(tables.ggx_E(rough, mu_in), E_avg, f82_Fss(f0, 0.0))
            for f0 in base]
    np.testing.assert_allclose(got, want, rtol=1e-12)
    if mu_in != mu_out:
        assert abs(got[0] - 1.0) > 0.01  # the compensation differs this much here


def test_plain_ggx_metal_has_no_view_dependent_weight():
    P = _material(M_METALLIC=1.0, M_ROUGH=0.8, M_MULTI=0.0)
    np.testing.assert_array_equal(_adjoint(P, (0.9, 0.6, 0.3), 0.15, 0.8, pr.L_METAL), 1.0)


@pytest.mark.parametrize("multi", [0.0, 1.0])
def test_diffuse_base_takes_the_specular_layers_albedo_at_its_outgoing_side(multi):
    # Cycles' closure_layering_weight: base x (1 - max(specular layer's albedo at the view)),
    # the albedo mix(F0, 1, s(rough, mu, ior)) x (E x compensation with Multiscatter GGX).
    rough, ior, base = 1.0, 1.5, (0.9, 0.9, 0.9)
    P = _material(M_SPEC=1.0, M_ROUGH=rough, M_MULTI=multi, M_IOR=ior)
    mu_in, mu_out = 0.2, 0.85
    f0 = F0_from_ior(ior)
    Fss = f0 + (1.0 - f0) * (pr.fresnel_dielectric_Fss(ior) - f0) / (1.0 - f0)

    def keep(mu):
        E = tables.ggx_E(rough, mu)
        dark = ggx.energy_factor(E, tables.ggx_Eavg(rough), Fss) * E if multi else 1.0
        return 1.0 - dark * (f0 + (1.0 - f0) * tables.schlick_ior_s(rough, mu, ior))

    got = _adjoint(P, base, mu_in, mu_out, pr.L_DIFFUSE)
    np.testing.assert_allclose(got, keep(mu_out) / keep(mu_in), rtol=1e-12)
    assert got[0] > 1.01  # grazing arrival: the layer took more from the base there


@pytest.mark.parametrize("lobe", [pr.L_DIFFUSE, pr.L_METAL, pr.L_SPEC, pr.L_COAT,
                                  pr.L_SHEEN, pr.L_TRANSL])
def test_same_cosine_both_sides_changes_nothing(lobe):
    # A material with every layer: the factor is coefficient(mu) / coefficient(mu).
    P = _material(M_METALLIC=0.4, M_ROUGH=0.6, M_MULTI=1.0, M_SPEC=1.0, M_COAT_W=0.7,
                  M_COAT_ROUGH=0.3, M_COAT_IOR=1.5, M_SHEEN_W=0.5, M_SHEEN_ROUGH=0.4,
                  M_TL=0.2)
    P[0, pr.M_CTINT:pr.M_CTINT + 3] = (0.8, 0.5, 0.9)
    P[0, pr.M_SHEEN_TINT:pr.M_SHEEN_TINT + 3] = 1.0
    for mu in (0.05, 0.4, 1.0):
        np.testing.assert_allclose(_adjoint(P, (0.7, 0.5, 0.2), mu, mu, lobe), 1.0,
                                   rtol=1e-14)
