"""Free-space cases whose bounds and simulated signals must stay bit-for-bit what they were
before the environment (obstacles, fields of view) existed (environment.md: "without it every result
is what it was in free space").

``python tests/free_space_cases.py`` writes ``tests/data/free_space_reference.json``; it was
run at commit 0cb7c82 (before bounds and simulator knew of the environment) and the file is
compared exactly by ``tests/test_environment_bounds.py``.

It was rewritten once, when the planar products of the profile codebooks changed their
rounding for speed (separable steering vectors on the element grid, the Gram formed entry by
entry; tests/test_fast_paths.py bounds both against the old routes). Against the 0cb7c82 file
the rewrite moved the FIMs of the random and DIR cases by ≤ 1.0e-15 on the √(F_ii F_jj) scale
and the PEBs/CEB by ≤ 7e-16 beyond what the square-root inversion had already moved them
(≤ 1.4e-7, within each pair's conditioning tolerance); the expected-random cases and both
simulated signals were unchanged bit for bit.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

from conftest import small_scenario_doc

from ris_planner import compute_bounds, load_scenario, preset_document
from ris_planner.estimation.signal import direct_paths, noise_free_signal, signal_setup

REFERENCE = Path(__file__).parent / "data" / "free_space_reference.json"


def _batch(doc: dict[str, Any], seed: int, n: int) -> dict[str, Any]:
    rng = np.random.default_rng(seed)
    tx = rng.uniform(-4, 4, (n, 3))
    rx = rng.uniform(-4, 4, (n, 3))
    tx[:, 2], rx[:, 2] = rng.uniform(0, 1, n), rng.uniform(0, 1, n)
    return doc | {"tx": tx.tolist(), "rx": rx.tolist()}


def bounds_cases() -> dict[str, tuple[dict[str, Any], dict[str, Any]]]:
    """name → (scenario document, compute_bounds keyword arguments)."""
    rng = np.random.default_rng(41)
    behind = small_scenario_doc(rng, n_ris=3)  # random orientations: UEs behind some RISs
    behind = _batch(behind, 5, 6)
    no_los = preset_document("3-ris")
    no_los["system"] = no_los["system"] | {"los": False}
    one_ris = preset_document("paper-table1")
    one_ris["ris"] = one_ris["ris"][:1]
    one_ris["system"] = one_ris["system"] | {"los": False}
    directional = preset_document("2-ris-P") | {
        "codebook": {"kind": "directional", "prior": {"sigma_m": 0.1, "samples": 4, "seed": 1}}
    }
    table1 = preset_document("paper-table1")
    return {
        "table1": (table1, {}),
        "2-ris-L-batch": (_batch(preset_document("2-ris-L"), 1, 5), {}),
        "2-ris-L-height": (_batch(preset_document("2-ris-L"), 2, 4), {"known": ["height"]}),
        "4-ris-clock-tx": (_batch(preset_document("4-ris"), 3, 4), {"known": ["clock", "tx"]}),
        "3-ris-no-los-expected": (
            _batch(no_los | {"codebook": {"kind": "expected_random"}}, 4, 4),
            {},
        ),
        "random-behind": (behind, {}),
        "one-ris-underdetermined": (one_ris, {}),
        "directional": (directional, {}),
        "table1-degenerate": (
            table1,
            {"tx": [[0.0, 0.0, 0.0], table1["ris"][0]["position"]], "rx": [[1.0, 2.0, 0.5]] * 2},
        ),
    }


def signal_cases() -> dict[str, dict[str, Any]]:
    """name → scenario document (one pair) for the noise-free simulated signal."""
    rng = np.random.default_rng(43)
    small = small_scenario_doc(rng, n_ris=3)
    return {
        "small-los": small,
        "small-no-los": small | {"system": small["system"] | {"los": False}},
    }


def bounds_values(doc: dict[str, Any], kwargs: dict[str, Any]) -> dict[str, Any]:
    res = compute_bounds(load_scenario(doc), **kwargs)
    return {"json": res.to_json(batch=True), "fim": res.fim.tolist()}


def signal_values(doc: dict[str, Any]) -> dict[str, Any]:
    sc = load_scenario(doc)
    setup = signal_setup(sc)
    phases = np.linspace(0.1, 2.0, setup.n_ris + 1)
    paths = direct_paths(setup, sc.tx_array[0], sc.rx_array[0], sc.system.clock_offset_m, phases)
    mu = noise_free_signal(setup, paths)
    return {"real": mu.real.tolist(), "imag": mu.imag.tolist()}


def compute_all() -> dict[str, Any]:
    return {
        "bounds": {k: bounds_values(d, kw) for k, (d, kw) in bounds_cases().items()},
        "signal": {k: signal_values(d) for k, d in signal_cases().items()},
    }


if __name__ == "__main__":
    REFERENCE.parent.mkdir(exist_ok=True)
    REFERENCE.write_text(json.dumps(compute_all()))
    print(f"wrote {REFERENCE}")
