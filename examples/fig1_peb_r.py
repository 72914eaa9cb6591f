"""Fig. 1 (b) of the paper, the bounds at 20 dBm: why is our PEB_R below the paper's?

Table I geometry, noise figure 0 dB (docs/validation/paper.md: Fig. 1's setting),
P = 20 dBm. The paper plots one codebook realisation: PEB_T 0.1472 m, PEB_R 0.1336 m,
CEB 0.0946 m (its 30 dBm values are these / √10, so the curve is one fixed codebook). This
script prints, for each hypothesis, the mean and spread over random-codebook seeds (or the
expected-random bound) and the z-score of the paper's values in that spread:

* the codebook: unit-modulus U[0, 2π) phases (ours), 1-bit {0, π} and 2-bit phases, complex
  Gaussian entries (E|ω|² = 1): the spread and the means barely move;
* the model: spherical wavefront (the 10 × 10 panel's Fraunhofer distance is ~1 m, so near
  field cannot matter at 4–7 m), element spacing λ/4, a cos-pattern q = 1, TX ↔ RX swapped:
  each moves all three bounds together (or swaps PEB_T and PEB_R), never PEB_R alone;
* the RX position: a scan over ±1 m in x, y and 0–1.5 m in z for the expected-random bound
  scaled to the seed mean; the closest match misses one of the three values by ≥ 3.7 %.

    python examples/fig1_peb_r.py [--seeds 100]
"""

from __future__ import annotations

import argparse
import copy
from collections.abc import Callable
from typing import Any

import numpy as np

import ris_planner.physics.codebooks as codebooks
from ris_planner import compute_bounds, load_scenario, preset_document

PAPER = np.array([0.147212718671174, 0.133570767224502, 0.0945666402259775])
"""PEB_T, PEB_R, CEB [m] at 20 dBm from the paper's Fig. 1 (b) source data."""

Doc = dict[str, Any]


def base_document() -> Doc:
    doc = preset_document("paper-table1")
    doc["system"].update(noise_figure_db=0, tx_power_dbm=20)
    return doc


def bounds(doc: Doc) -> np.ndarray:
    """[PEB_T, PEB_R, CEB] of a one-pair document."""
    r = compute_bounds(load_scenario(doc))
    assert r.peb_tx is not None and r.ceb is not None  # TX and clock unknown in Table I
    return np.array([float(np.ravel(x)[0]) for x in (r.peb_tx, r.peb_rx, r.ceb)])


def over_seeds(doc: Doc, seeds: int) -> np.ndarray:
    """[seeds, 3] bounds of random codebooks with seeds 0 … seeds − 1."""
    out = []
    for s in range(seeds):
        d = copy.deepcopy(doc)
        d["codebook"] = {"kind": "random", "seed": s}
        out.append(bounds(d))
    return np.array(out)


def explicit_levels(doc: Doc, levels: int, seeds: int) -> np.ndarray:
    """Random phases on a grid of ``levels`` values (1-bit: 2, 2-bit: 4)."""
    beams = doc["system"]["transmissions"] // codebooks.block_count(
        doc["system"]["transmissions"], len(doc["ris"])
    )
    out = []
    for s in range(seeds):
        rng = np.random.default_rng(s)
        phases = [
            (rng.integers(0, levels, (beams, r["rows"] * r["cols"])) * 2 * np.pi / levels).tolist()
            for r in doc["ris"]
        ]
        d = copy.deepcopy(doc)
        d["codebook"] = {"kind": "explicit", "phases": phases}
        out.append(bounds(d))
    return np.array(out)


def gaussian_entries(doc: Doc, seeds: int) -> np.ndarray:
    """Complex Gaussian profile entries (not unit modulus), by swapping the random draw."""
    original = codebooks.random_phases

    def draw(n_ris: int, beams: int, elements: list[int], rng: np.random.Generator) -> Any:
        return [
            (rng.standard_normal((beams, n)) + 1j * rng.standard_normal((beams, n))) / np.sqrt(2)
            for n in elements[:n_ris]
        ]

    codebooks.random_phases = draw
    try:
        return over_seeds(doc, seeds)
    finally:
        codebooks.random_phases = original


def _spherical(d: Doc) -> None:
    d["system"]["wavefront"] = "spherical"


def _quarter_spacing(d: Doc) -> None:
    for r in d["ris"]:
        r["spacing_m"] = 0.0025  # λ/4 at 30 GHz


def _cos_pattern(d: Doc) -> None:
    for r in d["ris"]:
        r["pattern_exponent"] = 1


def _swap_ues(d: Doc) -> None:
    d["tx"], d["rx"] = d["rx"], d["tx"]


MODEL_VARIANTS: dict[str, Callable[[Doc], None]] = {
    "spherical wavefront": _spherical,
    "spacing lambda/4": _quarter_spacing,
    "pattern q = 1": _cos_pattern,
    "TX <-> RX": _swap_ues,
}


def row(name: str, values: np.ndarray) -> None:
    mean, std = values.mean(axis=0), values.std(axis=0)
    z = (PAPER - mean) / np.where(std > 0, std, np.nan)
    print(
        f"{name:26s} T {mean[0]:.4f}±{std[0]:.4f}  R {mean[1]:.4f}±{std[1]:.4f}"
        f"  CEB {mean[2]:.4f}±{std[2]:.4f}   z(paper) {np.round(z, 2)}"
    )


def rx_scan(seed_mean: np.ndarray) -> tuple[float, list[float], np.ndarray]:
    """The RX offset whose expected-random bounds, scaled by seed mean / expected at the
    Table I RX, come closest to the paper (max relative miss)."""
    doc = base_document()
    doc["codebook"] = {"kind": "expected_random"}
    scale = seed_mean / bounds(doc)
    best: tuple[float, list[float], np.ndarray] = (np.inf, [], np.zeros(3))
    for dx in np.arange(-1.0, 1.01, 0.25):
        for dy in np.arange(-1.0, 1.01, 0.25):
            for dz in (0.0, 0.5, 1.0, 1.5):
                d = copy.deepcopy(doc)
                d["rx"] = [2 + dx, 3 + dy, dz]
                v = bounds(d) * scale
                miss = float(np.abs(v / PAPER - 1).max())
                if miss < best[0]:
                    best = (miss, [float(dx), float(dy), float(dz)], v)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=100)
    ap.add_argument("--smoke", action="store_true", help="2 seeds per row (variants: 2)")
    args = ap.parse_args()
    n = 2 if args.smoke else args.seeds
    variant_seeds = n if args.smoke else max(10, n // 5)
    print(f"paper (one realisation)    T {PAPER[0]:.4f}   R {PAPER[1]:.4f}   CEB {PAPER[2]:.4f}")
    base = base_document()
    ours = over_seeds(base, n)
    row("ours: U[0,2pi) phases", ours)
    row("1-bit phases", explicit_levels(base, 2, n))
    row("2-bit phases", explicit_levels(base, 4, n))
    row("complex Gaussian entries", gaussian_entries(base, n))
    for name, change in MODEL_VARIANTS.items():
        doc = base_document()
        change(doc)
        row(name, over_seeds(doc, variant_seeds))
    miss, offset, v = rx_scan(ours.mean(axis=0))
    print(f"closest RX offset {offset}: T {v[0]:.4f} R {v[1]:.4f} CEB {v[2]:.4f}", end=" ")
    print(f"(max miss {miss:.1%})")
    closest = int(np.argmin(np.abs(ours / PAPER - 1).max(axis=1)))
    print(f"closest seed {closest}: {np.round(ours[closest], 4)}")


if __name__ == "__main__":
    main()
