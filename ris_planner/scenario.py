"""The scenario document: pydantic models that are the JSON contract (docs/concepts/conventions.md).

One document drives the Python API, the CLI (``ris-planner bounds``) and the REST service
(``POST /v1/bounds``). Defaults are the paper's Table I (``table_Simulation_parameters``).
Units are SI unless the field name says otherwise (``tx_power_dbm``, ``noise_figure_db``).
"""

from __future__ import annotations

import json
import math
from functools import cached_property
from importlib import resources
from pathlib import Path
from typing import Annotated, Any, ClassVar, Literal

import numpy as np
from numpy.typing import NDArray
from pydantic import Field, field_validator, model_validator

from ris_planner.document import (
    _POINTS_SCHEMA,
    MAX_COORDINATE_M,
    MIN_UE_RIS_DISTANCE_M,
    DocumentModel,
    Point3,
    field_error,
    finite_point,
)
from ris_planner.environment.model import Environment
from ris_planner.units import SPEED_OF_LIGHT, db_to_linear, dbm_to_watt

KnownPart = Literal["clock", "height", "tx"]
"""State parts that may be known: ``clock`` (B, round trip), ``height`` (z of both UEs), ``tx``."""


Wavefront = Literal["planar", "spherical"]


class SystemParams(DocumentModel):
    """Radio parameters (Table I). ``P`` is the per-transmission power of eq.
    transmission_matrix; the noise variance is σ² = W·N0·NF (linear)."""

    # physical ranges (not only > 0): with them every FIM entry stays far inside float range,
    # e.g. (k·aperture)² ≤ 1e26 and |ρ|² ≤ 1e18 (a 3e150 m spacing overflowed in the products)
    carrier_hz: float = Field(
        30e9, ge=1e6, le=1e15, allow_inf_nan=False, description="Carrier f_c [Hz], 1 MHz–1 PHz"
    )
    bandwidth_hz: float = Field(
        400e6, ge=1, le=1e13, allow_inf_nan=False, description="Bandwidth W [Hz], 1 Hz–10 THz"
    )
    subcarriers: int = Field(512, ge=1, le=65536, description="Pilot subcarriers K")
    transmissions: int = Field(192, ge=1, le=100000, description="OFDM transmissions G")
    tx_power_dbm: float = Field(
        30.0, ge=-100, le=100, allow_inf_nan=False, description="Transmit power P [dBm]"
    )
    noise_psd_dbm_hz: float = Field(
        -173.855, ge=-250, le=0, allow_inf_nan=False, description="Noise PSD N0 [dBm/Hz]"
    )
    noise_figure_db: float = Field(
        10.0, ge=0, le=60, allow_inf_nan=False, description="Receiver noise figure [dB]"
    )
    clock_offset_m: float = Field(
        5.0, ge=-1e6, le=1e6, allow_inf_nan=False, description="Clock offset B [m]"
    )
    los: bool = Field(True, description="Whether the TX–RX line-of-sight path exists")
    wavefront: Wavefront = Field(
        "planar",
        description="RIS response model: 'planar' (the paper's far-field a_R(ξ, ζ)) or"
        " 'spherical' (exact per-element distances; for pairs inside the Fraunhofer distance)",
    )

    @model_validator(mode="after")
    def _check_derived(self) -> SystemParams:
        """Individually valid extremes can underflow or overflow a derived quantity (e.g.
        ``bandwidth_hz`` = 5e-324 gives σ² = 0 and a division by zero): reject them, naming it."""
        with np.errstate(all="ignore"):  # overflow to inf is what is checked below
            sigma2 = self.noise_variance_w
            power = self.tx_power_w
        omega = 2 * math.pi * self.bandwidth_hz
        derived = {
            "wavelength c/carrier_hz": self.wavelength,
            "subcarrier spacing bandwidth_hz/subcarriers": self.subcarrier_spacing,
            "noise variance bandwidth_hz·N0·NF": sigma2,
            "transmit power": power,
            "SNR P/σ²": power / sigma2 if sigma2 > 0 else math.inf,
            "delay information scale (2π·bandwidth_hz)²·subcarriers": (
                omega * omega * self.subcarriers
            ),
        }
        for name, value in derived.items():
            if not (math.isfinite(value) and value > 0):
                raise ValueError(
                    f"system parameters give {name} = {value:g}, out of floating-point range;"
                    " use physical values"
                )
        return self

    @property
    def wavelength(self) -> float:
        """λ = c / f_c [m]."""
        return SPEED_OF_LIGHT / self.carrier_hz

    @property
    def subcarrier_spacing(self) -> float:
        """Δf = W / K [Hz] (docs/concepts/model.md: the spacing of the paper's figures)."""
        return self.bandwidth_hz / self.subcarriers

    @property
    def tx_power_w(self) -> float:
        return float(dbm_to_watt(self.tx_power_dbm))

    @property
    def noise_variance_w(self) -> float:
        """σ² = W · N0 · NF [W]."""
        return float(
            self.bandwidth_hz
            * dbm_to_watt(self.noise_psd_dbm_hz)
            * db_to_linear(self.noise_figure_db)
        )


class RISGrid(DocumentModel):
    """The element grid, field of view and pattern of a RIS: the fields a scenario's ``ris[i]``
    and a plan document's shared ``ris`` have in common (docs/concepts/conventions.md)."""

    rows: int = Field(10, ge=1, le=512, description="Elements along the local z axis")
    cols: int = Field(10, ge=1, le=512, description="Elements along the local y axis")
    spacing_m: float | None = Field(
        None,
        gt=0,
        le=1e3,
        allow_inf_nan=False,
        description="Element spacing [m], at most 1 km; default λ/2",
    )
    max_angle_deg: float = Field(
        90.0,
        gt=0,
        le=180,
        allow_inf_nan=False,
        description="Field of view: a UE is served only when the angle between the RIS normal"
        " and the direction to the UE is strictly below this [deg]; 90 = the open front"
        " half-space",
    )
    pattern_exponent: float = Field(
        0.0,
        ge=0,
        le=100,
        allow_inf_nan=False,
        description="q of the element pattern: the path gain is multiplied by"
        " (cos θ_T · cos θ_R)^q, θ the angles to the normal (0 = isotropic, the paper's model)",
    )

    @property
    def elements(self) -> int:
        return self.rows * self.cols

    def element_spacing(self, wavelength: float) -> float:
        """Element spacing d [m]: ``spacing_m``, default λ/2."""
        return wavelength / 2 if self.spacing_m is None else self.spacing_m


class RIS(RISGrid):
    """One RIS: pose and element grid (docs/concepts/conventions.md).

    R = Rz(yaw)·Ry(pitch)·Rx(roll); the RIS faces its local +x axis; elements on the local
    y–z plane, ``rows`` along z and ``cols`` along y; element n = r·cols + c.
    """

    position: Point3
    orientation: Annotated[
        list[float],
        Field(
            min_length=3,
            max_length=3,
            description="Euler [yaw, pitch, roll] in radians, each within ±4π",
            json_schema_extra={
                "items": {"type": "number", "minimum": -4 * math.pi, "maximum": 4 * math.pi}
            },
        ),
    ] = Field(default_factory=lambda: [0.0, 0.0, 0.0])

    @field_validator("position")
    @classmethod
    def _check_position(cls, v: list[float]) -> list[float]:
        return finite_point(v, "RIS position")

    @field_validator("orientation")
    @classmethod
    def _check_orientation(cls, v: list[float]) -> list[float]:
        arr = np.asarray(v, dtype=float)
        if not np.all(np.isfinite(arr)) or np.any(np.abs(arr) > 4 * math.pi):
            raise ValueError(f"orientation must be finite radians within ±4π, got {v}")
        return [float(x) for x in arr]


class RandomCodebook(DocumentModel):
    """Uniform random phases for the first block (section IV-A, Random Codebook), seeded."""

    kind: Literal["random"] = Field("random", description="Codebook kind (discriminator)")
    seed: int = Field(0, ge=0, description="Seed of the phase draw (numpy default_rng)")


class ExpectedRandomCodebook(DocumentModel):
    """Closed-form expectation of the FIM over uniform random phases (deterministic)."""

    kind: Literal["expected_random"] = Field(
        "expected_random", description="Codebook kind (discriminator)"
    )


class ExplicitCodebook(DocumentModel):
    """Phases of the first block: one entry per RIS, G/Γ rows × N phases [rad]."""

    kind: Literal["explicit"] = Field("explicit", description="Codebook kind (discriminator)")
    phases: list[list[list[float]]] = Field(
        description="Per RIS: G/Γ rows (beams) × N element phases in radians"
    )


PRIOR_MAX_SAMPLES = 4096
"""Upper limit on prior samples (each sample becomes beams of the first block)."""

PSD_TOLERANCE = 1e-12
"""A covariance is accepted as PSD when its smallest eigenvalue is ≥ −tol·max(1, λ_max):
rounding of a symmetric matrix entered with ~16 digits cannot push a PSD eigenvalue lower."""


class PositionPrior(DocumentModel):
    """Gaussian prior on the nuisance-free state's positions [p_T, p_R] (section IV-A,
    DIR codebook): s_N ~ N(s̄_N, Σ̄). Means default to the document's ``tx`` and ``rx``.

    Give exactly one of ``sigma_m`` (Σ̄ = σ²·I, the paper's σ_pri) or ``covariance``
    (3×3, applied to each UE independently, or 6×6 joint on [p_T, p_R]).
    """

    tx_mean: Point3 | None = Field(None, description="Prior mean of p_T [m]; default: tx")
    rx_mean: Point3 | None = Field(None, description="Prior mean of p_R [m]; default: rx")
    sigma_m: float | None = Field(
        None, ge=0, le=1e4, allow_inf_nan=False, description="Isotropic prior std σ_pri [m]"
    )
    covariance: list[list[float]] | None = Field(
        None, description="Prior covariance [m²]: 3×3 per UE or 6×6 on [p_T, p_R]"
    )
    samples: int | None = Field(
        None,
        ge=1,
        le=PRIOR_MAX_SAMPLES,
        description="Sampled TX–RX pairs; default fills the first block (G̃ or ⌊G̃/3⌋)",
    )
    seed: int = Field(0, ge=0, description="Seed of the prior draw (numpy default_rng)")

    @field_validator("tx_mean", "rx_mean")
    @classmethod
    def _check_mean(cls, v: list[float] | None) -> list[float] | None:
        return None if v is None else finite_point(v, "prior mean")

    @field_validator("covariance")
    @classmethod
    def _check_covariance(cls, v: list[list[float]] | None) -> list[list[float]] | None:
        if v is None:
            return None
        try:
            arr = np.asarray(v, dtype=float)
        except ValueError:
            raise ValueError("covariance must be a square list of lists of numbers") from None
        if arr.ndim != 2 or arr.shape[0] != arr.shape[1] or arr.shape[0] not in (3, 6):
            raise ValueError(f"covariance must be 3×3 or 6×6, got shape {list(arr.shape)}")
        if not np.all(np.isfinite(arr)):
            raise ValueError("covariance must hold finite numbers")
        if not np.allclose(arr, arr.T, rtol=1e-12, atol=0.0):
            raise ValueError("covariance must be symmetric")
        eig = np.linalg.eigvalsh(arr)
        if eig[0] < -PSD_TOLERANCE * max(1.0, float(eig[-1])):
            raise ValueError(
                f"covariance must be positive semidefinite; smallest eigenvalue {eig[0]:.3g}"
            )
        return [[float(x) for x in row] for row in arr]

    @model_validator(mode="after")
    def _one_spread(self) -> PositionPrior:
        if (self.sigma_m is None) == (self.covariance is None):
            raise ValueError("prior needs exactly one of sigma_m or covariance")
        return self


class DirectionalCodebook(DocumentModel):
    """DIR codebook (eqs. RIS_profile_sum_beam, DIR_codebook): one beam a_R*(ξ, ζ) per sampled
    TX–RX pair; the first block cycles through the beams when fewer than G̃."""

    kind: Literal["directional"] = Field("directional", description="Codebook kind (discriminator)")
    beams_per_sample: ClassVar[int] = 1
    prior: PositionPrior = Field(description="Gaussian prior on the UE positions")


class DirectionalDerivativeCodebook(DocumentModel):
    """DIR+DER codebook (eqs. sum_diff_beam_1–3, DER_codebook): per sampled pair the DIR beam
    and the two DER beams (projected to unit modulus); ``gamma_p`` is the DER/DIR amplitude
    ratio of eq. opt_formulation_3 (``None``: uniform power, i.e. γ_P = 1)."""

    kind: Literal["directional_derivative"] = Field(
        "directional_derivative", description="Codebook kind (discriminator)"
    )
    beams_per_sample: ClassVar[int] = 3
    prior: PositionPrior = Field(description="Gaussian prior on the UE positions")
    gamma_p: float | None = Field(
        None, ge=0, le=1e6, allow_inf_nan=False, description="DER/DIR amplitude ratio γ_P"
    )


Codebook = Annotated[
    RandomCodebook
    | ExpectedRandomCodebook
    | ExplicitCodebook
    | DirectionalCodebook
    | DirectionalDerivativeCodebook,
    Field(discriminator="kind"),
]
CodebookKind = Literal[
    "random", "expected_random", "explicit", "directional", "directional_derivative"
]


def _points(value: Any, what: str) -> list[list[float]]:
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 1:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != 3 or arr.shape[0] == 0:
        raise ValueError(f"{what} must be one [x, y, z] point or a non-empty list of them")
    # vectorised check (a batch of 10k pairs validated in ms, not a Python loop per point);
    # the first bad point goes through finite_point for the same message as a single point
    bad = ~np.all(np.isfinite(arr), axis=1) | np.any(np.abs(arr) > MAX_COORDINATE_M, axis=1)
    if np.any(bad):
        finite_point(arr[int(np.argmax(bad))].tolist(), what)
    points: list[list[float]] = arr.tolist()
    return points


class Scenario(DocumentModel):
    """The scenario document (docs/concepts/conventions.md).

    ``tx`` and ``rx`` are one point each or equal-length lists of points (a batch of pairs).
    """

    description: str | None = Field(None, max_length=2000, description="Free text")
    system: SystemParams = Field(
        default_factory=SystemParams, description="Radio parameters; defaults: Table I"
    )
    ris: list[RIS] = Field(min_length=1, max_length=64, description="The RISs, in path order")
    tx: list[float] | list[list[float]] = Field(
        description="TX position(s) [m]: one [x, y, z] or a non-empty list of them",
        json_schema_extra=_POINTS_SCHEMA,
    )
    rx: list[float] | list[list[float]] = Field(
        description="RX position(s) [m]: as tx, with the same number of points",
        json_schema_extra=_POINTS_SCHEMA,
    )
    codebook: Codebook = Field(
        default_factory=RandomCodebook,
        description=(
            "First-block RIS phase profiles: random (seeded), expected_random, explicit,"
            " directional or directional_derivative (prior-based, optional gamma_p)"
        ),
    )
    known: list[KnownPart] = Field(
        default_factory=list,
        description="Known state parts: clock, height, tx (each at most once)",
        json_schema_extra={"uniqueItems": True},
    )
    environment: Environment | None = Field(
        None,
        description="Obstacles (prisms, walls) that block legs; absent = free space",
    )

    @field_validator("tx", "rx", mode="before")
    @classmethod
    def _check_points(cls, v: Any) -> Any:
        try:
            _points(v, "UE position")
        except (TypeError, ValueError) as exc:
            raise ValueError(str(exc)) from None
        return v

    @field_validator("known")
    @classmethod
    def _unique_known(cls, v: list[str]) -> list[str]:
        if len(set(v)) != len(v):
            raise ValueError(f"known lists a part twice: {v}")
        return v

    @model_validator(mode="after")
    def _check_geometry(self) -> Scenario:
        tx, rx = self.tx_array, self.rx_array
        if tx.shape != rx.shape:
            raise ValueError(
                f"tx and rx must hold the same number of points, got {len(tx)} and {len(rx)}"
            )
        if self.system.los and np.any(np.linalg.norm(tx - rx, axis=-1) < MIN_UE_RIS_DISTANCE_M):
            bad = int(np.argmax(np.linalg.norm(tx - rx, axis=-1) < MIN_UE_RIS_DISTANCE_M))
            raise ValueError(f"tx equals rx in pair {bad}: the LOS gain λ/(4πd0) diverges")
        for i, r in enumerate(self.ris):
            p = np.asarray(r.position)
            for name, pts in (("tx", tx), ("rx", rx)):
                close = np.linalg.norm(pts - p, axis=-1) < MIN_UE_RIS_DISTANCE_M
                if np.any(close):
                    raise ValueError(
                        f"{name} point {int(np.argmax(close))} lies on RIS {i} at {r.position}"
                    )
        if self.environment is not None:
            self._check_outside_obstacles(self.environment, tx, rx)
        if isinstance(self.codebook, ExplicitCodebook):
            self._check_explicit(self.codebook)
        if isinstance(self.codebook, DirectionalCodebook | DirectionalDerivativeCodebook):
            self._check_prior(self.codebook)
        return self

    def _check_outside_obstacles(
        self, env: Environment, tx: NDArray[np.float64], rx: NDArray[np.float64]
    ) -> None:
        """No RIS centre and no UE more than 1 cm (``INSIDE_MARGIN_M``) inside a prism
        (environment.md); a RIS on a facade is the normal case. Errors carry the field path."""
        from ris_planner.environment.scene import INSIDE_MARGIN_M, Scene

        scene = Scene.from_environment(env)
        margin = f"more than {INSIDE_MARGIN_M * 100:g} cm"
        centres = np.array([r.position for r in self.ris], dtype=float)
        inside = scene.inside(centres)
        if np.any(inside >= 0):
            i = int(np.argmax(inside >= 0))
            raise field_error(
                "Scenario",
                ("ris", i, "position"),
                f"the centre of RIS {i} (path ris{i + 1}) at {self.ris[i].position} lies"
                f" {margin} inside {env.label(int(inside[i]))}; mount the RIS on its surface"
                " or outside it",
                self.ris[i].position,
            )
        for name, pts in (("tx", tx), ("rx", rx)):
            inside = scene.inside(pts)
            if np.any(inside >= 0):
                k = int(np.argmax(inside >= 0))
                loc: tuple[str | int, ...] = (name, k) if self.is_batch else (name,)
                raise field_error(
                    "Scenario",
                    loc,
                    f"the {name.upper()} of pair {k} at {pts[k].tolist()} lies {margin} inside"
                    f" {env.label(int(inside[k]))}; UEs must be outside obstacles",
                    pts[k].tolist(),
                )

    def _check_prior(self, cb: DirectionalCodebook | DirectionalDerivativeCodebook) -> None:
        from ris_planner.codebooks import block_length

        g_tilde = block_length(self.system.transmissions, len(self.ris))
        per_sample = cb.beams_per_sample
        if g_tilde < per_sample:
            raise ValueError(
                f"codebook {cb.kind!r} needs {per_sample} beams per sample but the first block"
                f" holds only G/Γ = {g_tilde}; raise system.transmissions"
            )
        if cb.prior.samples is not None and cb.prior.samples * per_sample > g_tilde:
            raise ValueError(
                f"codebook.prior.samples = {cb.prior.samples} needs"
                f" {cb.prior.samples * per_sample} beams but the first block holds"
                f" G/Γ = {g_tilde}; use at most {g_tilde // per_sample} samples"
            )
        for name, mean in (("tx_mean", cb.prior.tx_mean), ("rx_mean", cb.prior.rx_mean)):
            if mean is None and self.is_batch and len(self.tx_array) > 1:
                raise ValueError(
                    f"codebook.prior.{name} is required when the document lists several pairs"
                )

    def _check_explicit(self, cb: ExplicitCodebook) -> None:
        from ris_planner.codebooks import block_length

        if len(cb.phases) != len(self.ris):
            raise ValueError(
                f"explicit codebook needs one phase block per RIS ({len(self.ris)}),"
                f" got {len(cb.phases)}"
            )
        g_tilde = block_length(self.system.transmissions, len(self.ris))
        for i, (block, r) in enumerate(zip(cb.phases, self.ris, strict=True)):
            arr = np.asarray(block, dtype=float)
            if arr.shape != (g_tilde, r.elements):
                raise ValueError(
                    f"explicit codebook for RIS {i} must be G/Γ × N = {g_tilde} × {r.elements}"
                    f" phases, got shape {list(arr.shape)}"
                )
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"explicit codebook for RIS {i} has non-finite phases")

    @cached_property
    def tx_array(self) -> NDArray[np.float64]:
        """TX positions, [n_pairs, 3]."""
        return np.asarray(_points(self.tx, "tx"), dtype=float)

    @cached_property
    def rx_array(self) -> NDArray[np.float64]:
        """RX positions, [n_pairs, 3]."""
        return np.asarray(_points(self.rx, "rx"), dtype=float)

    @property
    def is_batch(self) -> bool:
        """True when tx/rx were given as lists of points (answers are lists in pair order)."""
        return bool(np.asarray(self.tx, dtype=float).ndim == 2)


PRESET_NAMES = ("paper-table1", "2-ris-L", "2-ris-P", "3-ris", "4-ris")
"""Scenario presets shipped as package data (``ris_planner/presets/NAME.json``)."""


def preset_document(name: str) -> dict[str, Any]:
    """The raw JSON document of a named preset."""
    if name not in PRESET_NAMES:
        raise ValueError(f"unknown preset {name!r}; choose one of {', '.join(PRESET_NAMES)}")
    text = resources.files("ris_planner.presets").joinpath(f"{name}.json").read_text()
    doc: dict[str, Any] = json.loads(text)
    return doc


def load_scenario(source: str | Path | dict[str, Any] | Scenario) -> Scenario:
    """A :class:`Scenario` from a preset name, a JSON file path, a dict, or a Scenario."""
    if isinstance(source, Scenario):
        return source
    if isinstance(source, dict):
        return Scenario.model_validate(source)
    if isinstance(source, str) and source in PRESET_NAMES:
        return Scenario.model_validate(preset_document(source))
    return Scenario.model_validate_json(Path(source).read_text())
