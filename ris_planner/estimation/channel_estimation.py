"""Algorithm 1: channel parameter estimation from the separated observations Ỹ_ℓ (eq. ytilde).

Coarse stage
  * LOS delay: |d^H(τ) h_0| over an N_F-point FFT grid (eqs. coarse_los_channel,
    coarse_los_delay); RIS delays: ‖d^H(τ) Ĥ_ℓ‖ the same way (eqs. coarse_ris_H,
    coarse_delay_RIS).
  * (ξ_ℓ, ζ_ℓ) at the coarse delay: the concentrated likelihood |a^H v|² / Σ_g δ_g²|ω_g^T a|²
    with v = Σ_g δ_g conj(ω_g) s_g (s_g = d^H(τ̂) Ĥ_ℓ[:, g]), i.e. the matched filter of eq.
    coarse_ris_xizeta (erratum, docs/concepts/model.md: argmax of the correlation) normalised by
    the beam energy. a^H v over a grid is a zero-padded 2-D FFT of v on the rows × cols
    aperture; the normaliser is data-independent and computed once per setup. The grid has
    max(``angle_fft_size``, 2·max(rows, cols)) points per axis (:func:`angle_grid_size`), so a
    large aperture (64 × 64, 100 × 100: a main lobe 2/N wide) always has ≥ 2 grid points per
    lobe and is never cropped by the FFT; the normaliser's FFTs run in batches of beams
    (:data:`NORMALISER_BATCH_ELEMENTS`), so its memory stays bounded whatever G̃ and the grid.

Refinement (eq. mle_channel_estimation): maximise the concentrated likelihood
|μ^H ỹ|²/‖μ‖² (the gain ρ̂ = μ^H ỹ/‖μ‖² eliminated) by Fisher scoring: the step is EFIM⁻¹·score,
where the score is the gradient of the concentrated log-likelihood and the EFIM (gain
eliminated) is the core's ``ris_path_fim``/``los_path_fim`` + ``eliminate_nuisance`` at the
current estimate, with step halving when the likelihood would drop.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from ris_planner.estimation.signal import SignalSetup
from ris_planner.physics import fim

FloatArray = NDArray[np.float64]
ComplexArray = NDArray[np.complex128]

SCORING_STEP_TOL = 1e-4
"""Fisher scoring stops when the step is below this many CRB standard deviations
(sqrt(Δ^T·EFIM·Δ)): far below the statistical error, so the iterate is converged."""


NORMALISER_BATCH_ELEMENTS = 1 << 22
"""Complex entries (64 MiB) of one batch of beam spectra in the (ξ, ζ) normaliser."""


def angle_grid_size(requested: int, rows: int, cols: int) -> int:
    """Points per axis of the (ξ, ζ) FFT grid: the requested size, at least 2·max(rows, cols)
    (half a main lobe 2/N per grid step: the refinement starts inside the lobe)."""
    return max(int(requested), 2 * max(int(rows), int(cols)))


def wrap(value: FloatArray | float, period: FloatArray | float) -> FloatArray:
    """Map onto [−period/2, period/2) (the ambiguity of ξ, ζ and of path lengths)."""
    v = np.asarray(value, dtype=float)
    return np.asarray(v - period * np.floor(v / period + 0.5))


@dataclass(frozen=True)
class ChannelEstimate:
    """Estimated nuisance-free channel parameters η_N and gains.

    length : [L+1] path lengths c·τ [m] (entry 0: LOS, NaN without LOS);
    xi, zeta : [L]; gain : [L+1] complex ρ̂ (0 without LOS);
    efim : per path the equivalent FIM at the estimate ([1, 1] LOS, [3, 3] RIS on (ξ, ζ, cτ)),
    ``None`` for an absent LOS or a coarse estimate.
    A path missing for the pair (blocked, out of view) is not estimated: NaN length, ξ, ζ,
    gain 0 and EFIM ``None``.
    """

    length: FloatArray
    xi: FloatArray
    zeta: FloatArray
    gain: ComplexArray
    efim: tuple[FloatArray | None, ...] | None = None

    def restricted(self, ris: tuple[int, ...]) -> ChannelEstimate:
        """The LOS entry and the RIS paths ``ris`` (0-based, in that order) only."""
        if ris == tuple(range(len(self.xi))):
            return self
        sel = np.asarray(ris, dtype=int)
        keep = np.concatenate([[0], sel + 1])
        return ChannelEstimate(
            length=self.length[keep],
            xi=self.xi[sel],
            zeta=self.zeta[sel],
            gain=self.gain[keep],
            efim=None if self.efim is None else tuple(self.efim[k] for k in keep),
        )


class ChannelEstimator:
    """Algorithm 1 for one setup (caches the FFT normalisers of the (ξ, ζ) search)."""

    def __init__(self, setup: SignalSetup, delay_fft_size: int = 1024, angle_fft_size: int = 100):
        if delay_fft_size < setup.subcarriers:
            raise ValueError(f"delay_fft_size must be ≥ K = {setup.subcarriers}")
        self.setup = setup
        self.delay_fft_size = delay_fft_size
        self.angle_fft_size = angle_fft_size
        self.angle_sizes = tuple(angle_grid_size(angle_fft_size, a.rows, a.cols) for a in setup.ris)
        """Grid points per axis of each RIS's (ξ, ζ) search (:func:`angle_grid_size`)."""

    # ----- coarse ---------------------------------------------------------------------------

    @cached_property
    def angle_normalisers(self) -> tuple[FloatArray, ...]:
        """Σ_g δ_g² |ω_g^T a_R(ξ, ζ)|² on the FFT grid, one [M, M] per RIS (beams in batches
        of ≤ :data:`NORMALISER_BATCH_ELEMENTS` spectrum entries)."""
        out = []
        dl2 = self.setup.beam_weights
        for arr, prof, m in zip(self.setup.ris, self.setup.profiles, self.angle_sizes, strict=True):
            blocks = np.conj(prof).reshape(-1, arr.rows, arr.cols)
            batch = max(1, NORMALISER_BATCH_ELEMENTS // (m * m))
            acc = np.zeros((m, m))
            for b0 in range(0, blocks.shape[0], batch):
                spec = np.fft.fft2(blocks[b0 : b0 + batch], s=(m, m))
                acc += np.tensordot(dl2[b0 : b0 + batch], np.abs(spec) ** 2, axes=1)
            out.append(acc)
        return tuple(out)

    def coarse_delay(self, h: ComplexArray) -> float:
        """argmax_r ‖d^H(r) h‖ on the N_F grid, r ∈ [0, c/Δf) (eqs. coarse_los_delay,
        coarse_delay_RIS); h : [K] or [K, G̃] de-piloted observation."""
        nf = self.delay_fft_size
        spec = np.fft.ifft(h, n=nf, axis=0)
        power = np.abs(spec) ** 2 if spec.ndim == 1 else np.sum(np.abs(spec) ** 2, axis=1)
        return float(np.argmax(power)) * self.setup.delay_period_m / nf

    def coarse_angles(self, index: int, s: ComplexArray) -> tuple[float, float]:
        """(ξ̂, ζ̂) of RIS ``index`` from s_g = d^H(τ̂) Ĥ[:, g] by the 2-D FFT matched filter."""
        arr = self.setup.ris[index]
        m = self.angle_sizes[index]
        dl = np.sqrt(self.setup.beam_weights)
        v = np.conj(self.setup.profiles[index]).T @ (dl * s)
        spec = np.fft.fft2(v.reshape(arr.rows, arr.cols), s=(m, m))
        score = np.abs(spec) ** 2 / np.maximum(self.angle_normalisers[index], 1e-300)
        m_r, m_c = np.unravel_index(int(np.argmax(score)), score.shape)
        period = arr.period(self.setup.wavelength)
        # grid frequency m/M cycles per element ≡ (d/λ)·ξ (mod 1)
        xi = float(wrap(m_c / m, 1.0)) * period
        zeta = float(wrap(m_r / m, 1.0)) * period
        return xi, zeta

    def depiloted(self, ytilde: ComplexArray) -> ComplexArray:
        """Ĥ_ℓ = Ỹ_ℓ ⊙ (x* 1^T) for all ℓ (eq. coarse_ris_H), [L+1, K, G̃]."""
        return np.asarray(ytilde * np.conj(self.setup.pilots)[None, :, None])

    def coarse(self, ytilde: ComplexArray) -> ChannelEstimate:
        """The coarse stage of Algorithm 1 on Ỹ [L+1, K, G̃]."""
        setup = self.setup
        h = self.depiloted(ytilde)
        n = setup.n_ris
        present = setup.ris_present
        length = np.full(n + 1, np.nan)
        if setup.los:
            length[0] = self.coarse_delay(h[0].sum(axis=1))
        for i in present:
            length[i + 1] = self.coarse_delay(h[i + 1])
        length = unwrap_lengths(length, setup.delay_period_m)
        xi, zeta = self._unestimated_angles(), self._unestimated_angles()
        for i in present:
            cd = np.exp(1j * setup.kappa * length[i + 1])
            xi[i], zeta[i] = self.coarse_angles(i, cd @ h[i + 1])
        gain = np.zeros(n + 1, dtype=complex)
        if setup.los:
            gain[0] = self._los_terms(h[0], length[0])[2]
        for i in present:
            gain[i + 1] = self._ris_terms(i, h[i + 1], np.array([xi[i], zeta[i], length[i + 1]]))[2]
        return ChannelEstimate(length=length, xi=xi, zeta=zeta, gain=gain)

    def _unestimated_angles(self) -> FloatArray:
        """[L] ξ or ζ before estimation: 0 for present paths, NaN for missing ones."""
        return np.asarray(np.where(self.setup.present[1:], 0.0, np.nan))

    # ----- refinement -----------------------------------------------------------------------

    def _los_terms(self, h: ComplexArray, r: float) -> tuple[float, FloatArray, complex]:
        """Concentrated likelihood |u|²/w, its gradient [1] and ρ̂ for the LOS path."""
        s = self.setup
        dl = np.sqrt(s.beam_weights)
        cd = np.exp(1j * s.kappa * r)
        sq = np.sqrt(s.tx_power_w)
        u = sq * (cd @ h @ dl)
        du = sq * ((1j * s.kappa * cd) @ h @ dl)
        w = s.tx_power_w * s.subcarriers * float(dl @ dl)
        val = float(abs(u) ** 2 / w)
        grad = np.array([2 * np.real(np.conj(u) * du) / w])
        return val, grad, complex(u / w)

    def _ris_terms(
        self, index: int, h: ComplexArray, eta: FloatArray
    ) -> tuple[float, FloatArray, complex]:
        """Concentrated likelihood, gradient on (ξ, ζ, r) [3] and ρ̂ for RIS path ``index``."""
        s = self.setup
        # [G̃, 3]: ω_g^T ∂a/∂ξ, ω_g^T ∂a/∂ζ, ω_g^T a
        t = fim.transmission_vectors(
            s.profiles[index], s.ris[index].elements, eta[:1], eta[1:2], s.wavelength
        )[0]
        dl = np.sqrt(s.beam_weights)
        cd = np.exp(1j * s.kappa * eta[2])
        sv = cd @ h
        sr = (1j * s.kappa * cd) @ h
        sq = np.sqrt(s.tx_power_w)
        tc = np.conj(t[:, 2]) * dl
        u = sq * (tc @ sv)
        du = sq * np.array([(np.conj(t[:, 0]) * dl) @ sv, (np.conj(t[:, 1]) * dl) @ sv, tc @ sr])
        pk = s.tx_power_w * s.subcarriers
        w = pk * float(s.beam_weights @ np.abs(t[:, 2]) ** 2)
        dw = (
            2
            * pk
            * np.array(
                [
                    s.beam_weights @ np.real(np.conj(t[:, 2]) * t[:, 0]),
                    s.beam_weights @ np.real(np.conj(t[:, 2]) * t[:, 1]),
                    0.0,
                ]
            )
        )
        val = float(abs(u) ** 2 / w)
        grad = (2 * np.real(np.conj(u) * du) * w - abs(u) ** 2 * dw) / w**2
        return val, np.asarray(grad, dtype=float), complex(u / w)

    def los_efim(self, gain: complex) -> FloatArray:
        """EFIM on cτ0 at gain ρ̂ (the core's LOS block, gain eliminated), [1, 1]."""
        s = self.setup
        total = s.gamma * float(s.beam_weights.sum())
        block = fim.los_path_fim(total, np.array([abs(gain)]), s.radio)
        return np.asarray(fim.eliminate_nuisance(block, 1)[0])

    def ris_efim(self, index: int, eta: FloatArray, gain: complex) -> FloatArray:
        """EFIM on (ξ, ζ, cτ) at (η, ρ̂) (the core's RIS block, gain eliminated), [3, 3]."""
        s = self.setup
        arr = s.ris[index]
        tv = fim.transmission_vectors(
            s.profiles[index], arr.elements, eta[:1], eta[1:2], s.wavelength
        )
        q = s.gamma * fim.transmission_gram(tv, s.beam_weights)
        block = fim.ris_path_fim(q, np.array([abs(gain)]), s.radio)
        return np.asarray(fim.eliminate_nuisance(block, 3)[0])

    def _score(
        self,
        terms: Callable[[FloatArray], tuple[float, FloatArray, complex]],
        efim: Callable[[FloatArray, complex], FloatArray],
        eta0: FloatArray,
        periods: FloatArray,
        max_iter: int,
    ) -> tuple[FloatArray, complex, FloatArray]:
        """Fisher scoring with step halving on a concentrated likelihood; returns (η, ρ̂, EFIM)."""
        noise = self.setup.noise_variance_w / self.setup.gamma
        eta = eta0.copy()
        val, grad, rho = terms(eta)
        info = efim(eta, rho)
        for _ in range(max_iter):
            try:
                step = np.linalg.solve(info, grad / noise)
            except np.linalg.LinAlgError:  # no information left (gain estimate ~0): stop
                break
            lam = 1.0
            for _ in range(40):
                cand = eta + lam * step
                cval, cgrad, crho = terms(cand)
                if cval >= val:
                    break
                lam /= 2
            else:
                break
            size = lam * float(np.sqrt(max(float(step @ info @ step), 0.0)))
            eta = cand.copy()
            fin = np.isfinite(periods)
            eta[fin] = wrap(cand[fin], periods[fin])
            val, grad, rho = cval, cgrad, crho
            info = efim(eta, rho)
            if size < SCORING_STEP_TOL:
                break
        return eta, rho, info

    def refine(
        self, ytilde: ComplexArray, start: ChannelEstimate, max_iter: int = 50
    ) -> ChannelEstimate:
        """The MLE refinement of Algorithm 1 (eq. mle_channel_estimation), path by path."""
        setup = self.setup
        h = self.depiloted(ytilde)
        n = setup.n_ris
        length = start.length.copy()
        xi, zeta = start.xi.copy(), start.zeta.copy()
        gain = np.zeros(n + 1, dtype=complex)
        efims: list[FloatArray | None] = [None] * (n + 1)
        if setup.los:
            eta, gain[0], efims[0] = self._score(
                lambda e: self._los_terms(h[0], float(e[0])),
                lambda e, g: self.los_efim(g),
                np.array([length[0]]),
                np.array([np.inf]),
                max_iter,
            )
            length[0] = eta[0]
        for i in setup.ris_present:
            period = setup.ris[i].period(setup.wavelength)

            def terms(e: FloatArray, i: int = i) -> tuple[float, FloatArray, complex]:
                return self._ris_terms(i, h[i + 1], e)

            def info(e: FloatArray, g: complex, i: int = i) -> FloatArray:
                return self.ris_efim(i, e, g)

            eta, gain[i + 1], efims[i + 1] = self._score(
                terms,
                info,
                np.array([xi[i], zeta[i], length[i + 1]]),
                np.array([period, period, np.inf]),
                max_iter,
            )
            xi[i], zeta[i], length[i + 1] = eta
        return ChannelEstimate(length=length, xi=xi, zeta=zeta, gain=gain, efim=tuple(efims))


def unwrap_lengths(length: FloatArray, period: float) -> FloatArray:
    """Put every path length within ±period/2 of the reference (LOS, else the first RIS path
    present), so that differences of path lengths are right even when c/Δf wraps them (B is
    then known modulo c/Δf, like every delay). Missing paths (NaN) stay NaN."""
    finite = np.isfinite(length)
    if not np.any(finite):
        return length.copy()
    ref = length[int(np.argmax(finite))]
    out = length.copy()
    out[finite] = ref + wrap(out[finite] - ref, period)
    return out
