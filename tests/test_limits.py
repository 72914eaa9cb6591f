"""Every size-driving quantity is computed from the document and refused before anything is
built: each document below would need gigabytes (or hours); under a 1.5 GiB address-space cap
each is refused with its limit named – exit status 2 and no MemoryError: nothing was built – by
the CLI and by the service. How long a refusal takes is the benchmark's figure
(benchmarks/service/bench_refusals.py, docs/validation/resources.md)."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from api_helpers import api_client
from test_api_plans import small_plan_doc
from waits import HANG_S

from ris_planner import preset_document
from ris_planner.planning import PlanDocument
from ris_planner.planning.outputs.rx_fields import heatmap_rx_index
from ris_planner.planning.resources.admission import HEATMAP_MAX_PAIRS, estimate_plan

MEMORY_CAP_MB = 1536
"""Address-space cap of the refusing process (imports need ~1 GiB of address space)."""


def ring(n: int) -> list[dict[str, Any]]:
    return [
        {
            "position": [5 * math.cos(2 * math.pi * k / n), 5 * math.sin(2 * math.pi * k / n), 2.0],
            "orientation": [2 * math.pi * k / n + math.pi, 0.0, 0.0],
        }
        for k in range(n)
    ]


def power_doc(transmissions: int, pairs: int, rows: int = 10, **codebook: Any) -> dict[str, Any]:
    doc = preset_document("2-ris-L")
    doc["system"] = dict(doc["system"]) | {"transmissions": transmissions}
    doc["ris"] = [dict(r) | {"rows": rows, "cols": rows} for r in doc["ris"]]
    rng = np.random.default_rng(0)
    doc["tx"] = rng.uniform(-3, 3, (pairs, 3)).round(3).tolist()
    doc["rx"] = (rng.uniform(-3, 3, (pairs, 3)) + np.array([0, 0, 0.5])).round(3).tolist()
    doc["codebook"] = codebook or {"kind": "random", "seed": 1}
    return doc


GRID = {"grid": {"x": [-3, 3, 1], "y": [-3, 3, 1], "z": [0, 0, 1]}}
CASES: dict[str, tuple[str, dict[str, Any], str]] = {
    # quantity: (command, document, text of the refusal)
    "sites": (
        "plan",
        small_plan_doc(
            candidates=[],
            walls=[
                {
                    "start": [0, 0],
                    "end": [1000, 0],
                    "spacing_m": 0.001,
                    "heights_m": [2 + 0.01 * i for i in range(100)],
                    "tilts_rad": [0.01 * i for i in range(100)],
                }
            ],
        ),
        "candidate-site limit",
    ),
    "road points": (
        "plan",
        small_plan_doc(
            tx_map={"roads": [{"points": [[0, 0], [1e-5, 0]], "width_m": 10, "step_m": 1e-7}]}
        ),
        "map-point limit",
    ),
    "grid points": (
        "plan",
        small_plan_doc(tx_map={"grid": {"x": [0, 1000, 1e-6], "y": [0, 0, 1], "z": [0, 0, 1]}}),
        "limit",
    ),
    "csv rows": (
        "plan",
        small_plan_doc(tx_map={"csv_text": "x,y,z\n" + "1,2,0\n" * 1_000_001}),
        "map-point limit",
    ),
    "pairs": (
        "plan",
        small_plan_doc(
            pairs="all", tx_map={"grid": {"x": [0, 100, 1], "y": [0, 100, 1], "z": [0, 0, 1]}}
        ),
        "max_pairs",
    ),
    "cache entries": (  # 600 × 50 000 site-pairs: 3.1 GiB even as float32
        "plan",
        small_plan_doc(candidates=ring(600), pairs={"sample": 50000, "seed": 1}, max_pairs=50000),
        "site-cache budget of 3072 MiB",
    ),
    "greedy layouts": (
        "plan",
        small_plan_doc(
            candidates=ring(60),
            ris_count=[4],
            search={"method": "greedy", "restarts": 1000, "max_rounds": 10000},
        ),
        "search limit",
    ),
    "memory budget": (
        "plan",
        small_plan_doc(candidates=ring(400), pairs={"sample": 9000, "seed": 1}, max_pairs=9000),
        "job memory budget",
    ),
    "power beams × positions": ("power", power_doc(4096 * 3, 256), "power-SDP limit"),
    "power beams × positions × elements": (
        "power",
        power_doc(256 * 3, 200, rows=400),
        "beam-information limit",
    ),
    "power design positions": (
        "power",
        power_doc(3000, 1, kind="directional", prior={"sigma_m": 0.1, "samples": 1000, "seed": 0}),
        "design-position limit",
    ),
}
ENV_BUDGET_MB = {"memory budget": 600}

REFUSER = r"""
import io, json, resource, sys
from contextlib import redirect_stderr
cap = int(sys.argv[1]) << 20
resource.setrlimit(resource.RLIMIT_AS, (cap, cap))
from ris_planner.cli import main
import ris_planner.planning, ris_planner.planning.resources.admission  # under the cap
import ris_planner.power.report
out = {}
for name, (command, doc, budget) in json.load(sys.stdin).items():
    import os
    os.environ["RIS_PLANNER_JOB_MEMORY_MB"] = str(budget)
    sys.stdin = io.TextIOWrapper(io.BytesIO(json.dumps(doc).encode()))
    err = io.StringIO()
    with redirect_stderr(err):
        code = main([command, "-"])
    out[name] = {"code": code, "stderr": err.getvalue()}
print(json.dumps(out))
"""


@pytest.fixture(scope="module")
def refusals() -> dict[str, dict[str, Any]]:
    """Every case run by the CLI in one process under the address-space cap."""
    cases = {
        name: (command, doc, ENV_BUDGET_MB.get(name, 6144))
        for name, (command, doc, _) in CASES.items()
    }
    env = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "PATH": "/usr/bin:/bin"}
    proc = subprocess.run(
        [sys.executable, "-c", REFUSER, str(MEMORY_CAP_MB)],
        input=json.dumps(cases),
        capture_output=True,
        text=True,
        timeout=HANG_S,
        env=env,
        cwd=Path(__file__).parent.parent,
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    result: dict[str, dict[str, Any]] = json.loads(proc.stdout)
    return result


@pytest.mark.parametrize("name", list(CASES))
def test_each_quantity_is_refused_before_it_is_built(
    refusals: dict[str, dict[str, Any]], name: str
) -> None:
    got = refusals[name]
    assert got["code"] == 2, got
    assert CASES[name][2] in got["stderr"], got["stderr"]
    assert "Traceback" not in got["stderr"] and "MemoryError" not in got["stderr"]


def test_the_service_refuses_at_submission_with_the_limit(tmp_path: Path) -> None:
    with api_client(tmp_path, workers=1) as client:
        r = client.post("/v1/plans", json=CASES["sites"][1])
        assert r.status_code == 413 and r.json()["limit"] == 100_000
        assert "candidate-site limit" in r.json()["message"]
        r = client.post("/v1/power-allocations", json=CASES["power beams × positions"][1])
        assert r.status_code == 413 and "power-SDP limit" in r.json()["message"]
        assert client.get("/v1/jobs").json()["total"] == 0  # nothing was queued


def test_heatmap_respects_its_pair_limit_for_a_million_point_map() -> None:
    big = {"grid": {"x": [0, 999, 1], "y": [0, 999, 1], "z": [0, 0, 1]}}
    doc = PlanDocument.model_validate(small_plan_doc(rx_map=big))
    sizes = estimate_plan(doc)
    assert sizes.rx_points == 1_000_000 and sizes.heatmap_pairs <= HEATMAP_MAX_PAIRS
    a, b = heatmap_rx_index(1_000_000), heatmap_rx_index(1_000_000)
    assert len(a) == HEATMAP_MAX_PAIRS and np.array_equal(a, b)  # reproducible
    assert np.all(np.diff(a) > 0)  # map order kept
    np.testing.assert_array_equal(heatmap_rx_index(1000), np.arange(1000))


def test_extreme_relative_weights_give_finite_normalised_pair_weights() -> None:
    from ris_planner.planning.inputs.ue_maps import PointMap, build_pairs

    pts = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]])
    for scale in (1e308, 1e-320):
        m = PointMap(pts, np.array([scale, scale, scale / 2]))
        pairs = build_pairs(m, m, "all", 100)
        assert np.all(np.isfinite(pairs.weights)) and math.isclose(pairs.weights.sum(), 1.0)
        # a pair's weight ∝ w_T·w_R: the (0, 1) pair weighs twice the (0, 2) pair
        w = dict(zip(zip(pairs.tx_index, pairs.rx_index, strict=True), pairs.weights, strict=True))
        assert math.isclose(w[(0, 1)], 2 * w[(0, 2)], rel_tol=1e-12)


# --- the memory estimate against measured peaks, and the refusal's advice -------------------


def test_smoke_estimates_cover_the_measured_peak_within_twice() -> None:
    """benchmarks/resources/bench_memory.py --smoke: each tiny plan run in a fresh process (plan,
    figures, GIS files, as a job); 1 ≤ estimate / peak RSS ≤ 2 (docs/validation/resources.md)."""
    sys.path.insert(0, str(Path(__file__).parent.parent / "benchmarks" / "resources"))
    from bench_memory import SMOKE, run_case

    for case in SMOKE:
        got = run_case(case, timeout=HANG_S)
        assert got["peak"] <= got["estimate"] <= 2 * got["peak"], (case.name, got)


def _refusal(doc: dict[str, Any], budget_mb: int) -> str:
    from ris_planner.core.errors import LimitExceededError
    from ris_planner.planning.resources.admission import validate_plan

    with pytest.raises(LimitExceededError) as exc:
        validate_plan(doc, memory_mb=budget_mb)
    return str(exc.value)


def _fits(doc: dict[str, Any], budget_mb: int) -> bool:
    from ris_planner.core.errors import LimitExceededError
    from ris_planner.planning.resources.admission import validate_plan

    try:
        validate_plan(doc, memory_mb=budget_mb)
    except LimitExceededError:
        return False
    return True


def _number(text: str, before: str) -> int:
    return int(text.split(before)[1].split(" (")[0].split(";")[0].replace(" ", ""))


CACHE_DOC = small_plan_doc(candidates=ring(52), pairs={"sample": 20000, "seed": 1}, max_pairs=20000)
"""52 candidates × 20 000 pairs: a 390 MiB site cache dominates the estimate."""


def test_the_refusal_names_the_site_cache_and_the_largest_pair_count_that_fits() -> None:
    budget = 700
    msg = _refusal(CACHE_DOC, budget)
    assert "above the job memory budget of 700 MiB" in msg
    assert "dominated by the site cache (52 sites × 20 000 pairs)" in msg
    best = _number(msg, "the largest pair count that fits is ")
    assert 0 < best < 20000
    # the advice is exact: that many pairs pass the same check, one more does not
    fit = CACHE_DOC | {"pairs": {"sample": best, "seed": 1}}
    assert _fits(fit, budget)
    assert not _fits(CACHE_DOC | {"pairs": {"sample": best + 1, "seed": 1}}, budget)


def test_the_refusal_names_the_ris_size_that_fits_for_spherical_element_arrays() -> None:
    doc = small_plan_doc(system={"wavefront": "spherical"}, ris={"rows": 100, "cols": 100})
    budget = 800
    msg = _refusal(doc, budget)
    assert "dominated by the per-element arrays (100 × 100 elements per RIS, spherical" in msg
    side = int(msg.split("the largest RIS that fits is ")[1].split(" × ")[0])
    assert 1 <= side < 100 and msg.rstrip().endswith(f"{side} × {side}")
    assert _fits(doc | {"ris": {"rows": side, "cols": side}}, budget)
    assert not _fits(doc | {"ris": {"rows": side + 1, "cols": side + 1}}, budget)


def test_the_users_64x64_plan_of_52_sites_fits_the_default_budget() -> None:
    """The plan the old estimate refused (50 256 MiB for 64×64 RISs, 52 sites × 1000 pairs):
    about 1.2 GiB now, its measured peak 0.75–1 GB (docs/validation/resources.md)."""
    doc = small_plan_doc(
        candidates=ring(52), ris={"rows": 64, "cols": 64}, pairs={"sample": 1000, "seed": 1}
    )
    sizes = estimate_plan(PlanDocument.model_validate(doc))
    assert sizes.memory_bytes < 2 << 30 and _fits(doc, 6144)


def test_cli_and_service_refuse_with_the_advice(tmp_path: Path, monkeypatch: Any) -> None:
    from ris_planner.cli import main

    src = tmp_path / "plan.json"
    src.write_text(json.dumps(CACHE_DOC))
    monkeypatch.setenv("RIS_PLANNER_JOB_MEMORY_MB", "700")
    import io
    from contextlib import redirect_stderr

    err = io.StringIO()
    with redirect_stderr(err):
        code = main(["plan", str(src), "--out", str(tmp_path / "out")])
    text = err.getvalue()
    assert code == 2 and "Traceback" not in text and text.count("\n") == 1, text
    assert "dominated by the site cache" in text and "largest pair count that fits" in text
    with api_client(tmp_path, workers=1, job_memory_mb=700) as client:
        r = client.post("/v1/plans", json=CACHE_DOC)
        assert r.status_code == 413, r.text
        body = r.json()
        assert body["limit"] == 700 and "largest pair count that fits is" in body["message"]
        assert client.get("/v1/jobs").json()["total"] == 0


def test_a_ris_size_sweep_is_estimated_at_its_largest_run() -> None:
    """The sweep's and the sizing question's runs are sequential: the memory is the largest
    run's (here the spherical per-element arrays of the swept 100 × 100 RIS)."""
    base = small_plan_doc(system={"wavefront": "spherical"})
    swept = estimate_plan(PlanDocument.model_validate(base | {"sweep": {"ris_size": [[100, 100]]}}))
    big = estimate_plan(PlanDocument.model_validate(base | {"ris": {"rows": 100, "cols": 100}}))
    small = estimate_plan(PlanDocument.model_validate(base))
    assert swept.memory_bytes == big.memory_bytes > small.memory_bytes


# --- the time model and its fit ---------------------------------------------------------------


def test_time_model_fit_recovers_covering_coefficients() -> None:
    """benchmarks/resources/fit_time_model.py on rows whose stage times are a known model of the
    smoke cases' sizes (each stage its work.py coefficients times a per-stage factor): every case
    lands in [low, high], and each fitted stage reproduces its rows to the fit's accuracy (a linear
    model of the same terms exists, so the L1 residual is ~0)."""
    sys.path.insert(0, str(Path(__file__).parent.parent / "benchmarks" / "resources"))
    from bench_memory import FULL, SMOKE, cache_budget_mb, case_document
    from fit_time_model import NOT_FITTED, fit
    from tolerance import assert_close

    from ris_planner.planning import PlanDocument
    from ris_planner.planning.prepare import prepare_plan
    from ris_planner.planning.resources.time_estimate import TIME_COEFFICIENTS, stage_terms

    factor = {st: 0.5 + 0.1 * i for i, st in enumerate(TIME_COEFFICIENTS)}
    rows = []
    for case in [*SMOKE, *FULL[:3]]:
        with pytest.MonkeyPatch.context() as mp:
            mp.setenv("RIS_PLANNER_CACHE_MEMORY_MB", str(cache_budget_mb(case)))
            terms = stage_terms(prepare_plan(PlanDocument.model_validate(case_document(case))))
        cpu = {
            st: factor[st] * sum(TIME_COEFFICIENTS[st][t] * v for t, v in sz.items())
            for st, sz in terms.items()
        }
        rows.append(
            {
                "case": {"name": case.name},
                "terms": terms,
                "cpu_stages_s": cpu,
                "seconds": sum(cpu.values()),
            }
        )
    coef, ratios = fit(rows, 1.08, 1.85)
    assert all(1.08 - 1e-9 <= q <= 1.85 + 1e-9 for q in ratios), ratios
    for r in rows:
        for st, sz in r["terms"].items():
            if any((st, t) in NOT_FITTED and v > 0 for t, v in sz.items()):
                continue  # kept at work.py's value: not the rows' scaled one
            model = sum(coef[st][t] * v for t, v in sz.items())
            # coefficients are rounded to 3 significant digits: 0.5 % per term at most
            assert_close(model, r["cpu_stages_s"][st], accuracy=5e-3, atol=1e-9, where=st)


def test_bench_memory_rows_carry_the_time_model_terms() -> None:
    """A bench_memory row holds the sizes the time model used (``terms``), the fit's input."""
    sys.path.insert(0, str(Path(__file__).parent.parent / "benchmarks" / "resources"))
    from bench_memory import SMOKE, run_case

    got = run_case(SMOKE[0], timeout=HANG_S)
    assert set(got["terms"]) == set(got["estimate_stages_s"]) - {"beams"}
    assert got["terms"]["search"]["per_layout_pair"] > 0


def test_every_limit_refusal_states_its_limit() -> None:
    """Every ``LimitExceededError`` the code raises carries the limit it exceeded (the service
    answers 413 with ``limit``: never a 413 without it)."""
    import ast

    root = Path(__file__).resolve().parent.parent
    missing = []
    for top in ("ris_planner", "api"):
        for path in sorted((root / top).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
                if not isinstance(node, ast.Call):
                    continue
                if getattr(node.func, "id", None) != "LimitExceededError":
                    continue
                if len(node.args) < 2 and not any(k.arg == "limit" for k in node.keywords):
                    missing.append(f"{path.relative_to(root)}:{node.lineno}")
    assert missing == []
