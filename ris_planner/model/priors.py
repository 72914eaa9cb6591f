"""Gaussian priors on the UE positions (section IV-A, DIR codebook): s_N ~ N(s̄_N, Σ̄).

Only the positions [p_T, p_R] enter the RIS profile design (the clock offset does not change
ξ, ζ), so a prior is a 6-vector mean and a 6×6 covariance, sampled with an explicit seed.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ris_planner.core.errors import RisPlannerError
from ris_planner.model.scenario import PositionPrior, Scenario

FloatArray = NDArray[np.float64]


def prior_mean(prior: PositionPrior, scenario: Scenario) -> FloatArray:
    """[6] mean [p̄_T, p̄_R]; missing means default to the document's (first) tx and rx."""
    tx = scenario.tx_array[0] if prior.tx_mean is None else np.asarray(prior.tx_mean, float)
    rx = scenario.rx_array[0] if prior.rx_mean is None else np.asarray(prior.rx_mean, float)
    return np.concatenate([tx, rx])


def prior_covariance(prior: PositionPrior) -> FloatArray:
    """[6, 6] covariance on [p_T, p_R]: σ²·I, a 3×3 block per UE, or the 6×6 given."""
    if prior.sigma_m is not None:
        return float(prior.sigma_m) ** 2 * np.eye(6)
    if prior.covariance is None:  # the model validator forbids this
        raise RisPlannerError("prior needs sigma_m or covariance")
    cov = np.asarray(prior.covariance, dtype=float)
    if cov.shape == (3, 3):
        return np.asarray(np.kron(np.eye(2), cov))
    return cov


def covariance_factor(cov: FloatArray) -> FloatArray:
    """A factor A with A Aᵀ = cov for a PSD (possibly singular) covariance, via eigh.

    Eigenvalues that rounding pushed slightly below zero are clipped to zero.
    """
    eig, vec = np.linalg.eigh(cov)
    return np.asarray(vec * np.sqrt(np.clip(eig, 0.0, None))[None, :])


def sample_pairs(
    prior: PositionPrior, scenario: Scenario, samples: int
) -> tuple[FloatArray, FloatArray]:
    """Draw ``samples`` TX–RX pairs from the prior with ``default_rng(prior.seed)``.

    Returns (tx [S, 3], rx [S, 3]). The draw is z @ Aᵀ + mean with z ~ N(0, I) [S, 6], so the
    same seed gives the same standard normals for every σ (curves over σ are coupled).
    """
    if samples < 1:
        raise RisPlannerError(f"the prior needs at least one sample, got {samples}")
    rng = np.random.default_rng(prior.seed)
    z = rng.standard_normal((samples, 6))
    s = prior_mean(prior, scenario)[None, :] + z @ covariance_factor(prior_covariance(prior)).T
    return np.asarray(s[:, :3]), np.asarray(s[:, 3:])
