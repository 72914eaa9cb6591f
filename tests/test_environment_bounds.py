"""Bounds in an environment (docs/concepts/environment.md, "The contract"):
only the paths present for a pair contribute, checked against the sub-layout of those paths
built by hand; a RIS facing away contributes exactly nothing; the pattern factor against a
hand-scaled gain; free-space results bit for bit those computed before the environment
existed; UEs and RISs inside prisms rejected with the field path (CLI exit 2, REST 422)."""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from api_helpers import api_client
from conftest import bounds_rtol, small_scenario_doc
from free_space_cases import REFERENCE, compute_all
from tolerance import BOUND_ACCURACY, EPS, assert_close

from ris_planner import compute_bounds, load_scenario, preset_document
from ris_planner.bounds.compute import (
    REASON_UNDERDETERMINED,
    first_block_profiles,
    path_information,
    underdetermined_reason,
)
from ris_planner.cli import main as cli_main
from ris_planner.environment import Scene
from ris_planner.physics.codebooks import block_count, block_length

SUBLAYOUT_ATOL = 1e-12
"""The masked FIM and the sub-layout's FIM (unit-diagonal scaled) are the same sums of the
same path terms, up to the order of the additions and, on the explicit-profile route, a beam
power scaled by Γ/Γ' (one rounding): agreement to 1e-12 leaves four digits of margin."""

SUBLAYOUT_FLOOR = 1e-12
"""Relative floor for bounds inverted from FIMs that agree to SUBLAYOUT_ATOL (raised by the
condition number, conftest.bounds_rtol)."""

PATTERN_ATOL = 1e-12
"""The pattern factor f multiplies |ρ_ℓ|, so a path's information is f² times its q = 0 value
exactly in exact arithmetic; the two routes differ by a few roundings of f and f²."""

OBSTACLES: list[dict[str, Any]] = [
    {"kind": "prism", "name": "block", "footprint": [[-1, -1], [1, -1], [1, 1], [-1, 1]],
     "height_m": 3.0},
    # a concave (L-shaped) footprint
    {"kind": "prism", "name": "ell",
     "footprint": [[-5, 3], [-3, 3], [-3, 4], [-4, 4], [-4, 5], [-5, 5]], "height_m": 4.0},
    {"kind": "wall", "name": "partition", "start": [3, -2], "end": [3, 2], "height_m": 2.0},
]  # fmt: skip


def site_doc(codebook: dict[str, Any], n_pairs: int = 60, seed: int = 3) -> dict[str, Any]:
    """Four RISs round a block, an L-shaped building and a low partition; one RIS with a
    60° field of view, one whose back faces half of the area; random pairs outside prisms."""
    ris = [
        {"position": [-6, 0, 2.5], "orientation": [0, 0, 0]},
        {"position": [6, 0, 2.5], "orientation": [math.pi, 0, 0]},
        {"position": [0, 6, 2.5], "orientation": [-math.pi / 2, 0, 0], "max_angle_deg": 60},
        {"position": [2, -6, 2.5], "orientation": [math.pi / 2, 0.3, 0]},
    ]
    for r in ris:
        r |= {"rows": 4, "cols": 4}
    env = {"obstacles": OBSTACLES}
    scene = Scene.from_environment(load_scenario(
        {"ris": ris, "tx": [0, 0, 5], "rx": [1, 0, 5], "environment": env}
    ).environment)  # fmt: skip
    rng = np.random.default_rng(seed)
    pts = rng.uniform([-5.5, -5.5, 1.0], [5.5, 5.5, 1.8], (4 * n_pairs, 3))
    pts = pts[scene.inside(pts, margin=0.0) < 0][: 2 * n_pairs]
    return {
        "system": {"subcarriers": 64, "transmissions": 192},
        "ris": ris,
        "tx": pts[:n_pairs].tolist(),
        "rx": pts[n_pairs:].tolist(),
        "codebook": codebook,
        "environment": env,
    }


def sub_layout(doc: dict[str, Any], k: int, present: dict[str, bool]) -> dict[str, Any] | None:
    """Pair k alone in free space with only its present paths (``None``: no RIS left)."""
    keep = [i for i in range(len(doc["ris"])) if present[f"ris{i + 1}"]]
    if not keep:
        return None
    sub = copy.deepcopy(doc)
    del sub["environment"]
    sub["ris"] = [doc["ris"][i] for i in keep]
    sub["system"] = sub["system"] | {"los": present["los"]}
    sub["tx"], sub["rx"] = doc["tx"][k], doc["rx"][k]
    return sub


def assert_bounds_close(a: Any, b: Any, k: int, f: np.ndarray) -> None:
    rtol = bounds_rtol(f, SUBLAYOUT_FLOOR) if np.all(np.diag(f) > 0) else SUBLAYOUT_FLOOR
    for x, y in ((a.peb_tx, b.peb_tx), (a.peb_rx, b.peb_rx), (a.ceb, b.ceb)):
        if np.isinf(y[0]):
            assert np.isinf(x[k])
        else:
            assert x[k] == pytest.approx(y[0], rel=rtol)


def scaled(f: np.ndarray) -> np.ndarray:
    d = np.sqrt(np.maximum(np.diag(f), 1e-300))
    return np.asarray(f / np.outer(d, d))


def presence_rows(res: Any) -> list[dict[str, bool]]:
    return [{name: bool(v[k]) for name, v in res.paths_present.items()} for k in range(res.n_pairs)]


# ----- per-pair removal of the missing paths ------------------------------------------------


def test_environment_equals_sub_layout_of_present_paths_expected_random() -> None:
    """``expected_random``: a path's information depends on Γ only through Γ·G̃ = G, so the
    sub-layout of the paths present (built by hand, free space) is the reference as it is."""
    doc = site_doc({"kind": "expected_random"})
    res = compute_bounds(load_scenario(doc))
    rows = presence_rows(res)
    patterns = {tuple(r.values()) for r in rows}
    assert len(patterns) >= 5  # the site really mixes blocked, out-of-view and clear paths
    assert any(not r["los"] for r in rows) and any(r["los"] for r in rows)
    determined = 0
    for k, present in enumerate(rows):
        sub = sub_layout(doc, k, present)
        if sub is None:
            assert res.reason[k].startswith(REASON_UNDERDETERMINED)
            continue
        ref = compute_bounds(load_scenario(sub))
        np.testing.assert_allclose(
            scaled(res.fim[k]), scaled(ref.fim[0]), rtol=0, atol=SUBLAYOUT_ATOL
        )
        assert_bounds_close(res, ref, k, ref.fim[0])
        keep = [f"ris{i + 1}" for i in range(len(doc["ris"])) if present[f"ris{i + 1}"]]
        sub_name = {"los": "los"} | {name: f"ris{j + 1}" for j, name in enumerate(keep)}
        for name, bounds in res.channel.items():
            if not present[name]:
                assert all(np.isinf(v[k]) for v in bounds.values())
                continue
            for key, values in bounds.items():
                expect = ref.channel[sub_name[name]][key][0]
                assert values[k] == pytest.approx(expect, rel=SUBLAYOUT_FLOOR)
        determined += bool(np.isfinite(res.peb_rx[k]))
        if (res.reason[k] or "").startswith(REASON_UNDERDETERMINED):
            assert "missing paths" in res.reason[k] and np.isinf(ref.peb_rx[0])
    assert determined >= 10


def test_environment_equals_sub_layout_with_the_layouts_profiles() -> None:
    """A seeded ``random`` codebook: Γ (from the layout's 4 RISs) shapes G̃ and the profiles,
    so the sub-layout keeps them: the layout's first-block profiles of the present RISs, G' =
    (L'+1)·G̃ transmissions (Γ' = L'+1, the same G̃) and beam powers Γ/Γ' (Γ'·Σδ'² = Γ·Σδ²)."""
    doc = site_doc({"kind": "random", "seed": 4}, n_pairs=30, seed=8)
    sc = load_scenario(doc)
    prof = first_block_profiles(sc)
    assert prof is not None
    gamma = block_count(sc.system.transmissions, len(sc.ris))
    g_tilde = block_length(sc.system.transmissions, len(sc.ris))
    res = compute_bounds(sc)
    compared = 0
    for k, present in enumerate(presence_rows(res)):
        sub = sub_layout(doc, k, present)
        if sub is None:
            continue
        compared += 1
        keep = [i for i in range(len(sc.ris)) if present[f"ris{i + 1}"]]
        gamma_sub = len(keep) + 1
        sub["system"] |= {"transmissions": gamma_sub * g_tilde}
        sub_sc = load_scenario(sub)
        assert block_count(sub_sc.system.transmissions, len(keep)) == gamma_sub
        ref = compute_bounds(
            sub_sc,
            profiles=[prof[i] for i in keep],
            beam_powers=np.full(g_tilde, gamma / gamma_sub),
        )
        np.testing.assert_allclose(
            scaled(res.fim[k]), scaled(ref.fim[0]), rtol=0, atol=SUBLAYOUT_ATOL
        )
        assert_bounds_close(res, ref, k, ref.fim[0])
    assert compared >= 20


def test_reason_names_the_missing_paths() -> None:
    """Table I (2 RISs + LOS, 7 observations for 7 states) with the LOS blocked by a wall
    between the UEs: 6 < 7, inf with the contract's reason; the RIS paths are clear."""
    doc = preset_document("paper-table1")
    doc["tx"], doc["rx"] = [[-2.0, -4.0, 1.0], [-2.0, -4.0, 1.0]], [[2.0, 3.0, 1.0], [2, -3, 1]]
    doc["environment"] = {
        "obstacles": [{"kind": "wall", "start": [-1, -1], "end": [1, 1], "height_m": 1.5}]
    }
    res = compute_bounds(load_scenario(doc))
    assert res.paths_present["los"].tolist() == [False, True]
    assert res.reason[0] == (
        "underdetermined: 6 geometric channel parameters for 7 unknown states"
        " (missing paths: los – blocked or out of view)"
    )
    assert res.reason[0] == underdetermined_reason(6, 7, ["los"])
    assert np.isinf(res.peb_rx[0]) and np.isinf(res.ceb[0])  # type: ignore[index]
    assert res.reason[1] is None and np.isfinite(res.peb_rx[1])
    # known height: 5 unknown states, 6 observations are enough
    known = compute_bounds(load_scenario(doc), known=["height"])
    assert known.reason[0] is None and np.isfinite(known.peb_rx[0])
    js = res.to_json(batch=True)
    assert js["paths_present"] == {"los": [False, True], "ris1": [True, True], "ris2": [True, True]}
    los = next(c for c in js["channel"] if c["path"] == "los")
    assert los["deb_m"][0] is None and los["deb_m"][1] is not None
    single = compute_bounds(load_scenario(doc | {"tx": doc["tx"][0], "rx": doc["rx"][0]}))
    expect = {"los": False, "ris1": True, "ris2": True}
    assert single.to_json(batch=False)["paths_present"] == expect


def test_ris_facing_away_gives_exactly_zero_information() -> None:
    """The TX behind RIS 2 (empty environment: fields of view apply): RIS 2's contribution is
    exactly 0, so the FIM equals, bit for bit, that of the layout without RIS 2
    (``expected_random``: per-path information independent of Γ) and does not change
    whatever RIS 2's orientation or size."""
    doc = preset_document("paper-table1") | {"codebook": {"kind": "expected_random"}}
    doc["tx"], doc["rx"] = [5.0, -1.0, 0.5], [2.0, 3.0, 0.0]  # RIS 2 at x = 4 faces −x
    doc["environment"] = {"obstacles": []}
    res = compute_bounds(load_scenario(doc))
    assert res.paths_present == {"los": [True], "ris1": [True], "ris2": [False]}
    alone = compute_bounds(load_scenario(doc | {"ris": doc["ris"][:1]}))
    assert np.array_equal(res.fim, alone.fim)
    turned = copy.deepcopy(doc)
    turned["ris"][1] |= {"orientation": [2.0, 0.4, 0.1], "rows": 3, "cols": 7}
    assert not compute_bounds(load_scenario(turned)).paths_present["ris2"][0]
    assert np.array_equal(compute_bounds(load_scenario(turned)).fim, res.fim)
    assert res.reason[0].startswith(REASON_UNDERDETERMINED) and "ris2" in res.reason[0]
    # the field of view is the RIS's own: without an environment it applies the same way
    free = compute_bounds(load_scenario({k: v for k, v in doc.items() if k != "environment"}))
    assert not free.paths_present["ris2"][0] and np.array_equal(free.fim, res.fim)


# ----- pattern factor -------------------------------------------------------------------------


@pytest.mark.parametrize("q", [1.0, 2.5])
def test_pattern_factor_scales_the_gain(rng: np.random.Generator, q: float) -> None:
    """(cos θ_T cos θ_R)^q on |ρ_ℓ|: the FIM equals Σ_ℓ f_ℓ² J^T Ĩ_ℓ J of the q = 0 paths with
    f from cosines computed by hand (normal = [cos ψ cos θ, sin ψ cos θ, −sin θ] for yaw ψ,
    pitch θ; a UE behind the RIS: cos clipped to 0, f = 0)."""
    doc = small_scenario_doc(rng, n_ris=3)
    tx = rng.uniform(-3, 3, (8, 3))
    rx = rng.uniform(-3, 3, (8, 3))
    sc0 = load_scenario(doc)
    sc = load_scenario(doc | {"ris": [r | {"pattern_exponent": q} for r in doc["ris"]]})
    prof = first_block_profiles(sc0)
    paths, _ = path_information(sc0, tx, rx, prof)
    expect = np.zeros((8, 7, 7))
    behind = 0
    for p in paths:
        factor = np.ones(8)
        if p.name != "los":
            r = doc["ris"][int(p.name[3:]) - 1]
            yaw, pitch = r["orientation"][0], r["orientation"][1]
            n = np.array([np.cos(yaw) * np.cos(pitch), np.sin(yaw) * np.cos(pitch), -np.sin(pitch)])
            cos = [
                np.maximum((u - r["position"]) @ n / np.linalg.norm(u - r["position"], axis=1), 0)
                for u in (tx, rx)
            ]
            factor = (cos[0] * cos[1]) ** q
            behind += int(np.sum(factor == 0))
        expect += factor[:, None, None] ** 2 * p.state_information()
    assert behind > 0  # some UE behind some RIS: f = 0 exercised
    got = compute_bounds(sc, tx=tx, rx=rx).fim
    scale = np.sqrt(np.einsum("pii->pi", expect))
    norm = scale[:, :, None] * scale[:, None, :]
    np.testing.assert_allclose(got / norm, expect / norm, rtol=0, atol=PATTERN_ATOL)


# ----- free space unchanged ---------------------------------------------------------------


BOUND_KEYS = ("peb_tx_m", "peb_rx_m", "ceb_m")
"""The reference bounds were inverted by the squared-form LDLᵀ of 0cb7c82; the square-root,
LOS-referenced inversion (ris_planner.inversion.crb) differs from it by the old route's own
rounding, cond(F)·ε per pair (conftest.bounds_rtol, floor 1e-9)."""

STORED_ULPS = 64.0
"""Everything else read back from the stored file – FIMs, channel bounds, simulated signals –
was computed in another process, possibly on another BLAS kernel and SIMD dispatch, so it is
compared by the tolerance rule (tests/tolerance.py), not bit for bit: FIM entries to 64 ulps
of √(F_ii F_jj) (sums of a few path terms; measured ≤ 7 ulps between the Haswell, Sandybridge
and AVX-512-free kernels), channel bounds (inverses of well-conditioned 3×3 path blocks,
measured ≤ 4 ulps) to 64 ulps, signals (sums of L + 1 path terms with phases of up to ~250 rad)
to 64 ulps of their largest sample (measured ≤ 3.3). Reasons, flags and shapes stay exact."""


def assert_bound_list_close(got: Any, want: Any, fims: Any, where: str) -> None:
    """PEB/CEB lists equal to each pair's conditioning tolerance (null stays null)."""
    for i, (g, w) in enumerate(zip(got, want, strict=True)):
        if w is None:
            assert g is None, f"{where}[{i}]"
        else:
            assert_close(
                g,
                w,
                cond=1.0,
                ulps=0,
                accuracy=bounds_rtol(np.asarray(fims[i]), 1e-9),
                where=f"{where}[{i}]",
            )


def assert_fim_close(got: Any, want: Any, where: str) -> None:
    """FIMs [P, n, n] entry by entry on the √(F_ii F_jj) scale (STORED_ULPS)."""
    g, w = np.asarray(got, dtype=float), np.asarray(want, dtype=float)
    d = np.sqrt(np.abs(np.einsum("pii->pi", w)))
    scale = d[:, :, None] * d[:, None, :]
    scale = np.where(scale > 0, scale, 1.0)
    assert_close(g / scale, w / scale, ulps=STORED_ULPS, atol=STORED_ULPS * EPS, where=where)


def test_free_space_results_unchanged() -> None:
    """Nine documents without environment (presets, batches, known parts, no LOS, one RIS,
    UEs all around RISs with a 180° field of view, DIR codebook, a degenerate pair) and two
    noise-free simulated signals against the values computed before bounds and simulator knew
    of the environment (tests/data/free_space_reference.json, written by
    tests/free_space_cases.py at 0cb7c82, rewritten once for a rounding-only change of the
    profile codebooks' products, see there): the PEBs and CEB to their conditioning
    (BOUND_KEYS), FIMs, channel bounds and signals by the tolerance rule (STORED_ULPS), reasons
    and flags exactly; ``paths_present`` and ``warnings`` are the new keys."""
    ref = json.loads(REFERENCE.read_text())
    now = compute_all()
    assert set(now["signal"]) == set(ref["signal"])
    for name, sig in now["signal"].items():
        want = np.asarray(ref["signal"][name]["real"]) + 1j * np.asarray(
            ref["signal"][name]["imag"]
        )
        got = np.asarray(sig["real"]) + 1j * np.asarray(sig["imag"])
        atol = STORED_ULPS * EPS * float(np.max(np.abs(want)))
        assert_close(got, want, ulps=STORED_ULPS, atol=atol, where=f"signal.{name}")
    for name, case in now["bounds"].items():
        js = dict(case["json"])
        present = js.pop("paths_present")
        js.pop("warnings")
        want = dict(ref["bounds"][name]["json"])
        for new_key in ("paths_present", "warnings"):  # checked below / not in the 0cb7c82 file
            want.pop(new_key, None)
        for key in BOUND_KEYS:
            got_v, want_v = js.pop(key), want.pop(key)
            if want_v is None:
                assert got_v is None, f"{name}.{key}"
            else:
                fims = ref["bounds"][name]["fim"]
                assert_bound_list_close(got_v, want_v, fims, f"{name}.{key}")
        assert_close(js, want, ulps=STORED_ULPS, where=name)
        assert_fim_close(case["fim"], ref["bounds"][name]["fim"], f"{name}.fim")
        n_pairs = len(case["json"]["peb_rx_m"])
        ris_names = {c["path"] for c in js["channel"]} - {"los"}
        assert set(present) == {"los"} | ris_names
        assert all(present[r] == [True] * n_pairs for r in ris_names)
        has_los = any(c["path"] == "los" for c in js["channel"])
        assert present["los"] == [has_los] * n_pairs


# ----- bad input --------------------------------------------------------------------------

BOX = {"kind": "prism", "name": "hall", "footprint": [[-1, -1], [1, -1], [1, 1], [-1, 1]]}


def boxed(**changes: Any) -> dict[str, Any]:
    doc = preset_document("paper-table1")
    doc["environment"] = {"obstacles": [BOX | {"height_m": 3.0}]}
    return doc | changes


@pytest.mark.parametrize(
    ("changes", "field", "words"),
    [
        ({"tx": [0.0, 0.5, 1.0]}, "tx", ["TX of pair 0", "obstacle 0 (prism 'hall')"]),
        (
            {"tx": [[-2.0, -4.0, 0.0], [0.2, 0.0, 2.9]], "rx": [[2.0, 3.0, 0.0]] * 2},
            "tx.1",
            ["TX of pair 1", "obstacle 0 (prism 'hall')"],
        ),
        ({"rx": [0.98, 0.0, 1.5]}, "rx", ["RX of pair 0", "more than 1 cm inside"]),
    ],
)
def test_ue_inside_a_prism_is_rejected(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    changes: dict[str, Any],
    field: str,
    words: list[str],
) -> None:
    doc = boxed(**changes)
    f = tmp_path / "doc.json"
    f.write_text(json.dumps(doc))
    assert cli_main(["bounds", str(f)]) == 2
    err = capsys.readouterr().err
    assert f"  {field}: " in err and all(w in err for w in words) and "Traceback" not in err
    with api_client(tmp_path) as client:
        r = client.post("/v1/bounds", json=doc)
    assert r.status_code == 422
    fields = r.json()["fields"]
    assert [x["field"] for x in fields] == [field] and all(w in fields[0]["message"] for w in words)


def test_ris_inside_a_prism_is_rejected_on_its_facade_accepted(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A RIS centre 5 cm inside: error at ris.0.position naming RIS and obstacle; 5 mm inside
    is within the 1 cm rule (accepted); on the facade (exactly, or a few ulps inside) it is
    the normal case and sees out of its building."""

    def building(face: float) -> dict[str, Any]:
        return BOX | {"footprint": [[-6, -1], [face, -1], [face, 1], [-6, 1]], "height_m": 4.0}

    doc = boxed()  # RIS 1 at x = −4 faces +x
    doc["environment"]["obstacles"] = [building(-3.95)]
    f = tmp_path / "doc.json"
    f.write_text(json.dumps(doc))
    assert cli_main(["bounds", str(f)]) == 2
    err = capsys.readouterr().err
    assert "ris.0.position: " in err and "RIS 0" in err and "obstacle 0 (prism 'hall')" in err
    with api_client(tmp_path) as client:
        r = client.post("/v1/bounds", json=doc)
    assert r.status_code == 422 and r.json()["fields"][0]["field"] == "ris.0.position"
    doc["environment"]["obstacles"] = [building(-3.995)]
    load_scenario(doc)  # 5 mm inside: accepted
    for face in (-4.0, -4.0 + 4e-15):
        doc["environment"]["obstacles"] = [building(face)]
        res = compute_bounds(load_scenario(doc))
        assert res.paths_present["ris1"][0] and res.reason[0] is None


def test_bounds_with_environment_cli_equals_rest(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    doc = site_doc({"kind": "expected_random"}, n_pairs=6)
    f = tmp_path / "doc.json"
    f.write_text(json.dumps(doc))
    assert cli_main(["bounds", str(f)]) == 0
    cli = json.loads(capsys.readouterr().out)
    with api_client(tmp_path) as client:
        r = client.post("/v1/bounds", json=doc)
    assert r.status_code == 200
    assert_close(r.json(), cli, accuracy=BOUND_ACCURACY)  # another process
    assert set(cli["paths_present"]) == {"los", "ris1", "ris2", "ris3", "ris4"}
    assert all(len(v) == 6 for v in cli["paths_present"].values())
    assert not all(all(v) for v in cli["paths_present"].values())


def test_visibility_work_limit_is_413(tmp_path: Path) -> None:
    """Legs × obstacle edges is refused before any work: 9 legs (LOS + 2 per RIS) × 200 walls
    = 1800 > 1000, while the FIM work (Σ 3·G̃·N·pairs = 24) is far below the limit."""
    doc = site_doc({"kind": "expected_random"}, n_pairs=1)
    doc["tx"], doc["rx"] = doc["tx"][0], doc["rx"][0]
    doc["system"] |= {"transmissions": 12}
    doc["ris"] = [r | {"rows": 1, "cols": 1} for r in doc["ris"]]
    walls = [
        {"kind": "wall", "start": [20 + i, 20], "end": [20 + i, 21], "height_m": 1.0}
        for i in range(200)
    ]
    doc["environment"] = {"obstacles": walls}
    with api_client(tmp_path, max_work=1000) as client:
        r = client.post("/v1/bounds", json=doc)
        assert r.status_code == 413 and "1800 visibility tests" in r.json()["message"]
        assert r.json()["limit"] == 1000
        doc["environment"] = {"obstacles": walls[:100]}
        assert client.post("/v1/bounds", json=doc).status_code == 200
