"""The sheen's view cosine where the glossy lobes' normal is raised (issue 14, sheen55).

Cycles raises only its specular, metal and coat closures' normal
(maybe_ensure_valid_specular_reflection); the Principled sheen is set up on the unraised
N and bsdf_sheen_setup reads its LTC tables (A, B, albedo) at dot(N, wi), clamped to
[0, 1] (svm/closure.h, closure/bsdf_sheen.h). camerakernels.hit_closures must therefore
read the sheen at clamp(ns . wo), not at the raised normal's view cosine the glossy
lobes take: read there, a Shade Smooth cap seen from below its smooth normals read
1.46-1.50x Cycles on its far rows (docs/accuracy.md, sheen55)."""
import math

import numpy as np
import pytest

from engine import camerakernels as ck
from engine.closures import principled as pr, sheen


def _rubber():
    """One Principled material row: dark base, roughness 0.8, Specular IOR Level 0,
    Sheen Weight 1 (roughness 0.5, white tint): tests/blender/test_sheen_view_below_
    normal_cycles.py's puck."""
    p = np.zeros((1, pr.N_MAT))
    p[0, pr.M_NODE] = pr.NODE_PRINCIPLED
    p[0, [pr.M_ALPHA, pr.M_ROUGH, pr.M_IOR]] = 1.0, 0.8, 1.5
    p[0, [pr.M_SHEEN_W, pr.M_SHEEN_ROUGH]] = 1.0, 0.5
    p[0, pr.M_SHEEN_TINT:pr.M_SHEEN_TINT + 3] = 1.0
    p[0, pr.M_TTINT:pr.M_TTINT + 3] = 1.0
    return p


def _closures(ns, wo):
    n = len(ns)
    prm = np.empty((n, pr.N_PACK))
    albedo = np.empty((n, pr.N_LOBES, 3))
    ng = np.tile([0.0, 0.0, 1.0], (n, 1))
    ck.hit_closures(ns, ng, wo, np.zeros(n, np.int64), _rubber(), False,
                    np.full((n, 3), 0.02), np.ones(n, np.bool_), np.ones(1), np.zeros(0),
                    prm, albedo, np.zeros(0))
    return prm, albedo


@pytest.mark.parametrize("tilt_deg", [10.0, 25.0, 40.0, 55.0])
def test_sheen_is_read_at_the_shading_normals_view_cosine(tilt_deg):
    # A smooth normal leaning away from a viewer 10 degrees above the facet: the view
    # grazes or lies below it, so the glossy normal is raised.
    b = math.radians(tilt_deg)
    t = math.radians(10.0)
    ns = np.array([[0.0, math.sin(b), math.cos(b)]])
    wo = np.array([[0.0, -math.cos(t), math.sin(t)]])
    prm, albedo = _closures(ns, wo)
    raised = np.any(prm[0, pr.P_GN:pr.P_GN + 3] != 0.0)
    assert raised  # the case this covers: the glossy lobes take a raised normal
    mu = min(max(float(ns[0] @ wo[0]), 0.0), 1.0)
    a, bb, alb = sheen.sheen_params(0.5, mu)
    assert alb > 0.0
    assert prm[0, pr.P_SHEEN_A] == a and prm[0, pr.P_SHEEN_B] == bb
    # weight x tint x albedo: equal up to rounding
    np.testing.assert_allclose(prm[0, pr.P_SHEEN_W:pr.P_SHEEN_W + 3], alb, rtol=1e-12)
    np.testing.assert_allclose(albedo[0, pr.L_SHEEN], alb, rtol=1e-12)


def test_unraised_hits_read_the_sheen_as_before():
    # The view well above the shading normal: nothing raised, one cosine for all lobes.
    ns = np.array([[0.0, 0.0, 1.0], [0.0, -0.3, math.sqrt(1.0 - 0.09)]])
    wo = np.array([[0.0, -0.6, 0.8], [0.0, -0.6, 0.8]])
    prm, _ = _closures(ns, wo)
    assert np.all(prm[:, pr.P_GN:pr.P_GN + 3] == 0.0)
    ref, _ = pr.setup_np(_rubber(), np.zeros(2, np.int64), np.full((2, 3), 0.02),
                         np.einsum("ij,ij->i", ns, wo), np.ones(2, np.bool_))
    np.testing.assert_array_equal(prm[:, :pr.P_GN], ref[:, :pr.P_GN])
