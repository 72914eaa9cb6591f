"""The site's reflections in the simulated signal (docs/guides/estimation.md, option
``multipath.site_reflections``): with one wall, the signal equals the free-space one plus the
image paths' terms, computed here independently (mirror points by hand, the Fresnel
coefficient with cmath, each image path as the direct path of a UE at the image)."""

from __future__ import annotations

import cmath
import json
import math
from importlib import resources

import numpy as np
from tolerance import assert_close

from ris_planner.estimation.document import load_simulation
from ris_planner.estimation.signal import (
    Paths,
    direct_paths,
    noise_free_signal,
    realisation_paths,
    signal_setup,
)
from ris_planner.model.simulation import Multipath

WALL_Y = -8.0
EPS0 = 8.8541878128e-12


def _document(site_reflections: bool = True, **wall: object) -> dict:
    scenario = json.loads(
        resources.files("ris_planner.model.presets").joinpath("paper-table1.json").read_text()
    )
    scenario["environment"] = {
        "obstacles": [
            {
                "kind": "wall",
                "start": [-10, WALL_Y],
                "end": [10, WALL_Y],
                "height_m": 5,
                "material": "glass",
            }
            | wall
        ]
    }
    return {"scenario": scenario, "multipath": {"site_reflections": site_reflections}}


def _mirror(p: np.ndarray) -> np.ndarray:
    return np.array([p[0], 2 * WALL_Y - p[1], p[2]])


def _fresnel_glass(source: np.ndarray, sink: np.ndarray, carrier_hz: float) -> complex:
    """TE coefficient of glass (ITU-R P.2040-1: η' = 6.27, σ = 0.0043 f^1.1925) for the leg
    source → wall → sink, the angle of incidence from the wall's normal (the y axis)."""
    f = carrier_hz / 1e9
    eta = complex(6.27, -0.0043 * f**1.1925 / (2 * math.pi * carrier_hz * EPS0))
    total = float(np.linalg.norm(sink - _mirror(source)))
    cos_t = (abs(source[1] - WALL_Y) + abs(sink[1] - WALL_Y)) / total
    root = cmath.sqrt(eta - (1 - cos_t**2))
    return (cos_t - root) / (cos_t + root)


def _select(paths: Paths, keep: np.ndarray, factor: np.ndarray) -> Paths:
    return Paths(
        ris=paths.ris[keep],
        length=paths.length[keep],
        gain=paths.gain[keep] * factor,
        xi=paths.xi[keep],
        zeta=paths.zeta[keep],
        direct=np.zeros(int(np.sum(keep)), dtype=bool),
    )


def test_one_wall_adds_the_image_paths() -> None:
    sim = load_simulation(_document())
    sc = sim.scenario
    setup = signal_setup(sc)
    lam, b = setup.wavelength, sc.system.clock_offset_m
    tx, rx = sc.tx_array[0], sc.rx_array[0]
    got = realisation_paths(setup, sim.multipath, np.random.default_rng(7))
    free = realisation_paths(setup, Multipath(), np.random.default_rng(7))
    phases = np.random.default_rng(7).uniform(0, 2 * np.pi, setup.n_ris + 1)
    # every reflection point lies on the wall (x within ±10 m, z within 0–5 m): checked by hand
    for s, t in [(tx, rx)] + [(p, np.asarray(r.position)) for p in (tx, rx) for r in sc.ris]:
        u = (s[1] - WALL_Y) / ((s[1] - WALL_Y) + (t[1] - WALL_Y))
        hit = _mirror(s) + u * (t - _mirror(s))
        assert abs(hit[1] - WALL_Y) < 1e-12 and -10 < hit[0] < 10 and 0 <= hit[2] < 5
    base = direct_paths(setup, tx, rx, b, phases)
    tx_image = direct_paths(
        setup, _mirror(tx), rx, b, phases
    )  # LOS and RIS paths from the TX image
    rx_image = direct_paths(setup, tx, _mirror(rx), b, phases)  # RIS paths to the RX image
    carrier = sc.system.carrier_hz
    parts = []
    for image, which in ((tx_image, "tx"), (rx_image, "rx")):
        keep = np.ones(image.ris.size, dtype=bool) if which == "tx" else image.ris > 0
        factors = []
        for m in np.flatnonzero(keep):
            ell = int(image.ris[m])
            far = rx if ell == 0 else np.asarray(sc.ris[ell - 1].position)
            source, sink = (
                (tx, far) if which == "tx" else (rx, np.asarray(sc.ris[ell - 1].position))
            )
            extra = cmath.exp(-2j * math.pi * (image.length[m] - base.length[m]) / lam)
            factors.append(_fresnel_glass(source, sink, carrier) * extra)
        parts.append(_select(image, keep, np.asarray(factors)))
    assert got.ris.size == free.ris.size + 5  # LOS + 2 TX–RIS + 2 RIS–RX reflections
    assert np.sum(got.direct) == free.ris.size
    expected = noise_free_signal(setup, free) + sum(noise_free_signal(setup, p) for p in parts)
    mu = noise_free_signal(setup, got)
    scale = float(np.max(np.abs(mu)))
    # [K, G] sums of ≤ 10 paths with phases κ·r ≲ 2π·300: ~1e-13 relative to the largest term
    assert_close(mu.real / scale, expected.real / scale, atol=1e-12)
    assert_close(mu.imag / scale, expected.imag / scale, atol=1e-12)
    # the reflected terms are not negligible: the wall changes the signal by more than 1 %
    assert float(np.max(np.abs(mu - noise_free_signal(setup, free)))) > 1e-2 * scale


def test_option_off_or_no_environment_changes_nothing() -> None:
    sim = load_simulation(_document(site_reflections=False))
    setup = signal_setup(sim.scenario)
    off = realisation_paths(setup, sim.multipath, np.random.default_rng(3))
    assert np.all(off.direct) and not sim.multipath.site_reflections and sim.multipath.empty
    doc = _document()
    del doc["scenario"]["environment"]
    bare = load_simulation(doc)
    setup = signal_setup(bare.scenario)
    on = realisation_paths(setup, bare.multipath, np.random.default_rng(3))
    plain = realisation_paths(setup, Multipath(), np.random.default_rng(3))
    assert not bare.multipath.empty
    for a, c in zip(on.astuple(), plain.astuple(), strict=True):
        np.testing.assert_array_equal(a, c)


def test_a_wall_below_the_legs_reflects_nothing_and_a_metal_one_reflects_fully() -> None:
    low = load_simulation(_document(height_m=0.5, base_m=3.0))  # z 3–3.5 m: above every point
    setup = signal_setup(low.scenario)
    paths = realisation_paths(setup, low.multipath, np.random.default_rng(1))
    assert np.all(paths.direct)
    metal = load_simulation(_document(material="metal"))
    setup = signal_setup(metal.scenario)
    paths = realisation_paths(setup, metal.multipath, np.random.default_rng(1))
    base = direct_paths(
        setup, metal.scenario.tx_array[0], metal.scenario.rx_array[0], 0.0, np.zeros(3)
    )
    los = np.flatnonzero(~paths.direct & (paths.ris == 0))[0]
    d_image = float(
        np.linalg.norm(metal.scenario.rx_array[0] - _mirror(metal.scenario.tx_array[0]))
    )
    # |R| ≈ 1 for metal: the reflected LOS is the free-space gain at the image distance
    assert abs(abs(paths.gain[los]) / (setup.wavelength / (4 * math.pi * d_image)) - 1) < 1e-3
    assert base.ris.size == 3
