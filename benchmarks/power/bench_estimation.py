"""Benchmark: one full estimate (Algorithm 1 + 2, coarse and refined) for the Table I scenario.

Median wall time over ``--repeats`` realisations at 30 dBm (noise figure 0 dB) of each stage –
signal simulation and separation (not part of the estimate), coarse channel (FFT delays, 2-D FFT
(ξ, ζ)), channel MLE (Fisher scoring), coarse position (1331 TX candidates, vectorised), position
MLE (trf) – and of the whole estimate; target ≤ 2 s on the 2-core machine. Naive references
measured in the same run: the (ξ, ζ) search as a Python loop over the paper's 0.02-step grid,
the delay search as a Python loop over the N_F grid, and the coarse position search as a Python
loop over the candidates; each checked to pick the same grid point as the fast version.

``--sizes 16,64,100`` (the apertures plans use) then times one full estimate with
both RISs of Table I resized to N × N (the (ξ, ζ) FFT grid max(100, 2N) per axis, its
normaliser in batches: channel_estimation.angle_grid_size), as the median of ``--repeats``
realisations and as a ratio to the 10 × 10 estimate measured in the same run; each size's
refined p_R error is printed next to PEB_R (the estimate is right, not only fast).

    python benchmarks/power/bench_estimation.py [--repeats 20] [--sizes 16,64,100] [--quick]

``--quick``: 2 repeats.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: fixtures, harness

from fixtures import table1_document

from ris_planner import load_scenario
from ris_planner.estimation.channel_estimation import wrap
from ris_planner.estimation.pipeline import Estimator
from ris_planner.estimation.position_estimation import candidate_costs
from ris_planner.estimation.signal import (
    realisation_paths,
    received_signal,
    separate_paths,
    signal_setup,
)
from ris_planner.model.simulation import EstimatorSettings, Multipath


def naive_angles(setup, index, s, m):  # type: ignore[no-untyped-def]
    """Grid loop of the concentrated likelihood over ξ, ζ ∈ {(λ/d)·wrap(i/M)}."""
    arr = setup.ris[index]
    k = 2 * np.pi / setup.wavelength
    y, z = arr.elements[:, 1], arr.elements[:, 2]
    prof = setup.profiles[index]
    best, arg = -1.0, (0.0, 0.0)
    axis = [float(wrap(i / m, 1.0)) * arr.period(setup.wavelength) for i in range(m)]
    for xi in axis:
        for zeta in axis:
            t = prof @ np.exp(1j * k * (y * xi + z * zeta))
            val = abs(np.conj(t) @ s) ** 2 / float(np.sum(np.abs(t) ** 2))
            if val > best:
                best, arg = val, (xi, zeta)
    return arg


def naive_delay(setup, h, nf):  # type: ignore[no-untyped-def]
    best, arg = -1.0, 0.0
    for n in range(nf):
        r = n * setup.delay_period_m / nf
        val = float(np.sum(np.abs(np.exp(1j * setup.kappa * r) @ h) ** 2))
        if val > best:
            best, arg = val, r
    return arg


def naive_position(setup, channel, cand):  # type: ignore[no-untyped-def]
    best, arg = np.inf, 0
    for i in range(cand.shape[0]):
        c = candidate_costs(setup.ris, setup.wavelength, channel, cand[i : i + 1]).cost[0]
        if c < best:
            best, arg = c, i
    return arg


def timed(fn, repeats):  # type: ignore[no-untyped-def]
    times, out = [], None
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), out


def size_runs(size: int, repeats: int) -> tuple[float, float, float, float, int]:
    """(setup s, median full estimate s, median refined ‖Δp_R‖, PEB_R, (ξ, ζ) grid) of Table I
    with both RISs N × N at 30 dBm, noise figure 0 dB."""
    from ris_planner.bounds.compute import compute_bounds

    doc = table1_document()
    doc["system"]["noise_figure_db"] = 0.0
    for r in doc["ris"]:
        r["rows"] = r["cols"] = size
    sc = load_scenario(doc)
    t0 = time.perf_counter()
    setup = signal_setup(sc)
    settings = EstimatorSettings()
    est = Estimator(setup, settings, settings.search_area.candidates(sc.tx_array[0]))
    _ = est.channel.angle_normalisers
    t_setup = time.perf_counter() - t0
    rng = np.random.default_rng(size)
    times, errs = [], []
    for _ in range(repeats):
        paths = realisation_paths(setup, Multipath(), rng)
        yt = separate_paths(setup, received_signal(setup, paths, rng))
        t1 = time.perf_counter()
        fe = est.estimate(yt)
        times.append(time.perf_counter() - t1)
        errs.append(float(np.linalg.norm(fe.position_refined.rx - sc.rx_array[0])))
    peb_r = float(compute_bounds(sc).peb_rx[0])
    return (
        t_setup,
        statistics.median(times),
        statistics.median(errs),
        peb_r,
        est.channel.angle_sizes[0],
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=20)
    parser.add_argument(
        "--sizes", default="", help="comma-separated N of N × N RISs, e.g. 16,64,100"
    )
    parser.add_argument("--quick", action="store_true", help="2 repeats")
    args = parser.parse_args()
    if args.quick:
        args.repeats = 2
    if args.sizes:
        ref = size_runs(10, args.repeats)[1]
        print(
            f"one full estimate per RIS size (median of {args.repeats}),"
            f" ratio to 10×10 = {ref * 1e3:.1f} ms"
        )
        for n in (int(v) for v in args.sizes.split(",")):
            t_setup, t_est, err, peb, grid = size_runs(n, args.repeats)
            print(
                f"  {n:4d}×{n:<4d} grid {grid:4d}²  setup {t_setup * 1e3:8.1f} ms  estimate"
                f" {t_est * 1e3:8.1f} ms  ({t_est / ref:5.1f}× 10×10)  median ‖Δp_R‖"
                f" {err:.2e} m, PEB_R {peb:.2e} m"
            )
        return
    doc = table1_document()
    doc["system"]["noise_figure_db"] = 0.0
    sc = load_scenario(doc)
    t0 = time.perf_counter()
    setup = signal_setup(sc)
    settings = EstimatorSettings()
    cand = settings.search_area.candidates(sc.tx_array[0])
    est = Estimator(setup, settings, cand)
    _ = est.channel.angle_normalisers
    t_setup = time.perf_counter() - t0
    rng = np.random.default_rng(0)
    stages: dict[str, list[float]] = {}
    total, sim = [], []
    fe = None
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        paths = realisation_paths(setup, Multipath(), rng)
        yt = separate_paths(setup, received_signal(setup, paths, rng))
        t1 = time.perf_counter()
        fe = est.estimate(yt)
        t2 = time.perf_counter()
        sim.append(t1 - t0)
        total.append(t2 - t1)
        for k, v in fe.seconds.items():
            stages.setdefault(k, []).append(v)
    assert fe is not None
    print(f"Table I, 30 dBm, {args.repeats} realisations (median wall times)")
    print(f"  setup (profiles, FFT normalisers, once)  {t_setup * 1e3:8.2f} ms")
    print(f"  simulate + separate (not in estimate)     {statistics.median(sim) * 1e3:8.2f} ms")
    for k, v in stages.items():
        print(f"  {k:40s} {statistics.median(v) * 1e3:8.2f} ms")
    full = statistics.median(total)
    print(
        f"  full estimate (Alg. 1 + 2)               {full * 1e3:8.2f} ms"
        f"   target ≤ 2000 ms: {'PASS' if full <= 2.0 else 'FAIL'}"
    )
    # naive references on the last realisation
    h = est.channel.depiloted(yt)
    length = fe.channel_coarse.length
    s = np.exp(1j * setup.kappa * length[1]) @ h[1]
    m = settings.angle_fft_size
    t_fft, fast = timed(lambda: est.channel.coarse_angles(0, s), 5)
    t_naive, slow = timed(lambda: naive_angles(setup, 0, s, m), 1)
    assert np.allclose(fast, slow), (fast, slow)
    print(
        f"  (ξ, ζ) search {m}×{m} grid: 2-D FFT {t_fft * 1e3:.2f} ms, Python grid loop"
        f" {t_naive * 1e3:.0f} ms, ratio {t_naive / t_fft:.0f}×"
    )
    nf = settings.delay_fft_size
    t_fft, fast_r = timed(lambda: est.channel.coarse_delay(h[1]), 5)
    t_naive, slow_r = timed(lambda: naive_delay(setup, h[1], nf), 1)
    assert abs(fast_r - slow_r) < 1e-9
    print(
        f"  delay search N_F = {nf}: FFT {t_fft * 1e3:.2f} ms, Python grid loop"
        f" {t_naive * 1e3:.0f} ms, ratio {t_naive / t_fft:.0f}×"
    )
    ch = fe.channel_coarse
    t_vec, _ = timed(lambda: candidate_costs(setup.ris, setup.wavelength, ch, cand), 5)
    t_naive, arg = timed(lambda: naive_position(setup, ch, cand), 1)
    assert np.allclose(cand[arg], fe.position_coarse.tx)
    print(
        f"  coarse position, {cand.shape[0]} candidates: vectorised {t_vec * 1e3:.2f} ms,"
        f" Python loop {t_naive * 1e3:.0f} ms, ratio {t_naive / t_vec:.0f}×"
    )


if __name__ == "__main__":
    main()
