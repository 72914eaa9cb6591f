"""Property tests: the bounds do not depend on where the scene sits or how it is turned.

Translating every position, or rotating the whole scene about the z axis (adding the angle to
every RIS yaw), must leave PEB_T, PEB_R and CEB unchanged: traces of covariance blocks are
invariant under a rotation of the coordinates. This checks geometry, Jacobian and inversion
together through a route independent of the formulas.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from ris_planner import compute_bounds, load_scenario, preset_document

FIM_RTOL = 1e-11
"""The moved scene's FIM must be Q F Qᵀ (Q rotates p_T and p_R): entries of order max|F| agree
to rounding in the geometry (positions ~10 m, ε ≈ 1e-16, a few hundred flops per entry)."""

INVARIANCE_RTOL = 1e-8
"""Floor of the bound tolerance. The FIMs of the two routes differ by a measured relative
perturbation δ (≤ FIM_RTOL, checked first); an inversion amplifies it by at most the scaled
condition number, so the bounds may differ by 10·cond·δ – near-degenerate pairs at the centre
of the L or 3-RIS layouts reach cond ~1e9."""

coords = st.floats(-3.0, 3.0, allow_nan=False)


@settings(max_examples=25, deadline=None)
@given(
    tx=st.tuples(coords, coords, st.floats(0.0, 0.5)),
    rx=st.tuples(coords, coords, st.floats(0.0, 0.5)),
    shift=st.tuples(coords, coords, coords),
    angle=st.floats(-np.pi, np.pi),
    layout=st.sampled_from(["2-ris-L", "3-ris", "paper-table1"]),
)
def test_bounds_invariant_under_rigid_motion(
    tx: tuple[float, float, float],
    rx: tuple[float, float, float],
    shift: tuple[float, float, float],
    angle: float,
    layout: str,
) -> None:
    if np.linalg.norm(np.subtract(tx, rx)) < 0.1:
        return
    doc = preset_document(layout) | {"codebook": {"kind": "expected_random"}}
    base = compute_bounds(load_scenario(doc), tx=tx, rx=rx)
    if not np.isfinite(base.peb_rx[0]) or base.peb_rx[0] > 100:
        return  # blind spots are invariant too, but their size is rounding-dominated
    c, s = np.cos(angle), np.sin(angle)
    rot = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    moved = dict(doc)
    moved["ris"] = [
        r
        | {
            "position": (rot @ np.asarray(r["position"], float) + shift).tolist(),
            "orientation": [r["orientation"][0] + angle, *r["orientation"][1:]],
        }
        for r in doc["ris"]
    ]
    res = compute_bounds(
        load_scenario(moved), tx=rot @ np.asarray(tx) + shift, rx=rot @ np.asarray(rx) + shift
    )
    q = np.eye(7)
    q[:3, :3] = q[3:6, 3:6] = rot
    f, f_moved = base.fim[0], q.T @ res.fim[0] @ q  # back in the original frame
    scale = np.sqrt(np.outer(np.diag(f), np.diag(f)))
    delta = float(np.max(np.abs(f_moved - f) / scale))
    assert np.max(np.abs(f_moved - f)) <= FIM_RTOL * np.max(np.abs(f))
    cond = float(np.linalg.cond(f / scale))
    rtol = max(INVARIANCE_RTOL, 10 * cond * max(delta, np.finfo(float).eps))
    for a, b in ((base.peb_tx, res.peb_tx), (base.peb_rx, res.peb_rx), (base.ceb, res.ceb)):
        assert a is not None and b is not None
        np.testing.assert_allclose(b, a, rtol=rtol)
