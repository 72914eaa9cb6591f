"""Phased roll-out (ris_planner.planning.search.rollout): nested layouts are supersets of the
previous
count's, the price of nesting against an exhaustive free optimum is ≥ 0 and is the brute-force
best superset's, and free layouts that are not nested are flagged."""

from __future__ import annotations

import itertools
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from tolerance import assert_close

from ris_planner.cli import main
from ris_planner.planning import SerialExecutor, run_plan
from ris_planner.planning.search.rollout import extend


def ring(n: int) -> list[dict[str, Any]]:
    out = []
    for k in range(n):
        phi = 2 * math.pi * k / n + 0.1
        pos = [4.5 * math.cos(phi), 4.5 * math.sin(phi), 2.0 + 0.5 * (k % 2)]
        out.append({"position": pos, "orientation": [phi + math.pi, math.pi / 6, 0.0]})
    return out


GRID = {"grid": {"x": [-3, 3, 1], "y": [-3, 3, 1], "z": [0, 0, 1]}}


def doc(**over: Any) -> dict[str, Any]:
    base: dict[str, Any] = {
        "candidates": ring(7),
        "tx_map": GRID,
        "rx_map": GRID,
        "pairs": {"sample": 200, "seed": 2},
        "objective": {"kind": "mean_capped", "metric": "rx", "cap_m": 1.0},
        "ris_count": [2, 3, 4],
    }
    return base | over


@pytest.fixture(scope="module")
def nested() -> Any:
    return run_plan(doc(rollout="nested"), executor=SerialExecutor())


def test_nested_layouts_are_supersets_with_nonnegative_price(nested: Any) -> None:
    roll = nested.to_json()["rollout"]
    assert roll["mode"] == "nested"
    rows = roll["counts"]
    assert [r["ris_count"] for r in rows] == [2, 3, 4]
    assert rows[0]["nested_layout"] == rows[0]["free_layout"] and rows[0]["price"] == 0
    for a, b in itertools.pairwise(rows):
        assert set(a["nested_layout"]) < set(b["nested_layout"])
        assert len(b["nested_layout"]) == b["ris_count"]
    for r, cr in zip(rows, nested.counts, strict=True):
        assert cr.outcome.method == "exhaustive"  # the free optimum is the true one here
        assert r["price"] >= 0
        assert r["nested_objective"] >= r["free_objective"]  # mean_capped: lower is better
        assert_close(r["price"], r["nested_objective"] - r["free_objective"], ulps=4)
        if r["price"] > 0:
            assert_close(r["price_relative"], r["price"] / abs(r["free_objective"]), ulps=4)


def test_nested_extension_is_the_brute_force_best_superset(nested: Any) -> None:
    rows = nested.to_json()["rollout"]["counts"]
    scorer, n = nested.scorer, len(nested.sites)
    for a, b in itertools.pairwise(rows):
        base = set(a["nested_layout"])
        supers = [c for c in itertools.combinations(range(n), b["ris_count"]) if base <= set(c)]
        losses = scorer.exact_loss(np.array(supers))
        assert tuple(b["nested_layout"]) == supers[int(np.argmin(losses))]
        assert b["method"] == "exhaustive" and b["layouts_evaluated"] == len(supers)


def test_greedy_extension_when_exhaustive_is_out_of_reach(nested: Any) -> None:
    spec = nested.document.search.model_copy(update={"max_exhaustive": 1})
    base = tuple(nested.counts[0].ranked[0][0])
    step = extend(nested.scorer, nested.feasibility, base, 4, spec)
    assert step.method == "greedy" and step.layout is not None
    assert set(base) < set(step.layout) and len(step.layout) == 4
    # a superset search cannot beat the exhaustive best superset
    exact = extend(nested.scorer, nested.feasibility, base, 4, nested.document.search)
    assert step.loss >= exact.loss


def test_free_mode_flags_non_nested_layouts() -> None:
    # search each count's best freely; a layout that drops a site of the previous count's
    # is flagged, and the cheap chain gives its price
    res = run_plan(doc(), executor=SerialExecutor())
    rows = res.to_json()["rollout"]["counts"]
    assert res.to_json()["rollout"]["mode"] == "free"
    best = [set(cr.ranked[0][0]) for cr in res.counts]
    for i in range(1, len(rows)):
        assert rows[i]["nested"] is (best[i - 1] <= best[i])
        assert rows[i]["price"] is not None and rows[i]["price"] >= 0
        if not rows[i]["nested"] and rows[i - 1]["nested_layout"] == rows[i - 1]["free_layout"]:
            # not nested, from a nested start: nesting costs something or ties
            assert rows[i]["nested_objective"] >= rows[i]["free_objective"]
    assert any(r["nested"] is False for r in rows[1:]), [r["free_layout"] for r in rows]


def test_cli_nested_flag(tmp_path: Path, nested: Any) -> None:
    path = tmp_path / "doc.json"
    path.write_text(json.dumps(doc()))
    assert main(["plan", str(path), "--nested", "--out", str(tmp_path), "--workers", "1"]) == 0
    plan = json.loads((tmp_path / "plan.json").read_text())
    assert plan["rollout"]["mode"] == "nested"
    # the same chain as the document's rollout = "nested" (same process, same scorer route)
    assert plan["rollout"]["counts"] == nested.to_json()["rollout"]["counts"]


def test_free_mode_leaves_the_price_out_when_the_chain_is_not_cheap(
    nested: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    from ris_planner.planning.search import rollout

    free = [(cr.ris_count, cr.ranked[0][0], cr.ranked[0][1]) for cr in nested.counts]
    args = (nested.scorer, nested.feasibility, free, nested.document.search, 200)
    cheap = rollout.plan_rollout("free", *args, search_work=0.0)
    assert all(r["price"] is not None for r in cheap["counts"]) and "price_note" not in cheap
    monkeypatch.setattr(rollout, "FREE_CHAIN_WORK", 0)
    dear = rollout.plan_rollout("free", *args, search_work=1e9)  # 5 % of it: still cheap
    assert dear["counts"] == cheap["counts"]
    out = rollout.plan_rollout("free", *args, search_work=0.0)
    assert all(r["price"] is None and "nested_layout" not in r for r in out["counts"])
    assert "price_note" in out
    assert [r["nested"] for r in out["counts"]] == [r["nested"] for r in cheap["counts"]]
    # nested mode searches the chain whatever it costs
    assert rollout.plan_rollout("nested", *args, search_work=0.0)["counts"][1]["price"] is not None
