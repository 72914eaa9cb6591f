"""The plan document: pydantic models that are the JSON contract of ``ris-planner plan`` and
the REST planning endpoint.

It extends the scenario document (docs/concepts/conventions.md): ``system`` is the scenario's
:class:`~ris_planner.model.scenario.SystemParams`, ``ris`` holds the element grid shared by every
candidate (the scenario's per-RIS ``rows``/``cols``/``spacing_m``), ``codebook`` and ``known``
mean what they mean there; instead of fixed RISs and UEs it names candidate sites, UE
probability maps, the pairs to evaluate, an objective, the RIS counts and the search.
``environment`` is the scenario document's (docs/concepts/environment.md,
"The contract"); ``facades`` put candidate sites on the facades of its named prisms.
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Literal

import numpy as np
from pydantic import (
    AfterValidator,
    ConfigDict,
    Field,
    ValidationError,
    field_validator,
    model_validator,
)

from ris_planner.core.errors import LimitExceededError
from ris_planner.environment.kinds.prism import Prism
from ris_planner.environment.model import Environment
from ris_planner.model.limits import (
    MAX_CANDIDATES,
    MAX_DESIGN_POSITIONS,
    MAX_FACADE_PRISMS,
    MAX_MAP_POINTS,
    MAX_PAIRS_LIMIT,
    MAX_SITES,
    MAX_WALLS,
    count,
    csv_rows,
    range_points,
)
from ris_planner.model.objectives import objective_kind, objective_names
from ris_planner.model.plan_physics import (
    ISOTROPIC_SOURCE,
    PHYSICS_FIELDS,
    PLAN_MAX_ANGLE_DEG,
    PLAN_PATTERN_EXPONENT,
    PLAN_PHYSICS_SOURCE,
)
from ris_planner.model.power import Solver
from ris_planner.model.scenario import (
    RIS,
    DocumentModel,
    KnownPart,
    Point3,
    RISGrid,
    Scenario,
    SystemParams,
    finite_point,
)
from ris_planner.model.search_methods import (
    AUTO,
    MAX_DISTRICT_RIS,
    MAX_LAYOUT_RIS,
    method_names,
    search_method,
)
from ris_planner.model.simulation import Multipath

MIN_WALL_M = 1e-6
"""A wall segment shorter than this has coinciding ends."""


def _known_method(method: str) -> str:
    """``auto`` or a registered search method's name (a ValueError naming the known ones)."""
    if method != AUTO:
        search_method(method)
    return method


MethodName = Annotated[str, AfterValidator(_known_method)]
"""A ``method`` field of the plan documents: ``auto`` or a registered search method."""

DEFAULT_MAX_PAIRS = 20_000
"""Default limit on the number of evaluated TX–RX pairs; larger maps need ``pairs.sample``."""


Range = Annotated[
    list[float],
    Field(
        min_length=3,
        max_length=3,
        description="[start, stop, step] in metres; stop included (up to rounding), step > 0",
    ),
]
Point2 = Annotated[
    list[float], Field(min_length=2, max_length=2, description="[x, y] in metres (global frame)")
]


def range_count(r: list[float], what: str) -> int:
    """Number of values of a [start, stop, step] range (stop included)."""
    start, stop, step = r
    if not step > 0:
        raise ValueError(f"{what}: step must be > 0, got {step}")
    if stop < start:
        raise ValueError(f"{what}: stop {stop} is below start {start}")
    return range_points(start, stop, step)


def finite_weights(v: list[float], what: str) -> list[float]:
    """Relative weights: finite and ≥ 0 (they are scaled by their largest before any sum, so
    1e308 or 1e-320 are fine; a map without a positive weight is refused when it is built)."""
    arr = np.asarray(v, dtype=float)
    if not np.all(np.isfinite(arr)) or np.any(arr < 0):
        raise ValueError(f"{what} must be finite and ≥ 0")
    return v


class GridMap(DocumentModel):
    """A regular grid of UE positions, x-major order (x outer, then y, then z)."""

    x: Range
    y: Range
    z: Range
    weights: list[float] | None = Field(
        None,
        max_length=MAX_MAP_POINTS,
        description="Relative weight of each grid point in x-major order (default all 1)",
    )

    @field_validator("x", "y", "z")
    @classmethod
    def _check_range(cls, v: list[float], info: Any) -> list[float]:
        v = finite_point(v, f"grid.{info.field_name}")
        n = range_count(v, f"grid.{info.field_name}")
        if n > MAX_MAP_POINTS:  # a size: the service answers 413 with the limit
            raise LimitExceededError(
                f"grid.{info.field_name} has {n} values (limit {MAX_MAP_POINTS})", MAX_MAP_POINTS
            )
        return v

    @field_validator("weights")
    @classmethod
    def _check_grid_weights(cls, v: list[float] | None) -> list[float] | None:
        return None if v is None else finite_weights(v, "grid.weights")

    @model_validator(mode="after")
    def _check_size(self) -> GridMap:
        n = self.size
        if n > MAX_MAP_POINTS:
            raise LimitExceededError(
                f"grid has {n} points, above the limit of {MAX_MAP_POINTS}", MAX_MAP_POINTS
            )
        if self.weights is not None and len(self.weights) != n:
            raise ValueError(f"grid.weights must hold one weight per point ({n})")
        return self

    @property
    def size(self) -> int:
        return range_count(self.x, "x") * range_count(self.y, "y") * range_count(self.z, "z")


class Road(DocumentModel):
    """A road: a polyline in the x–y plane with a width; UEs are sampled on a lattice along and
    across it at ``step_m`` (lateral offsets symmetric about the centre line), at ``height_m``."""

    points: list[Point2] = Field(min_length=2, description="Centre-line vertices [x, y] in metres")
    width_m: float = Field(gt=0, le=1000, allow_inf_nan=False, description="Road width [m]")
    height_m: float = Field(
        1.5, ge=-1000, le=1000, allow_inf_nan=False, description="UE height z [m]"
    )
    step_m: float = Field(gt=0, le=1000, allow_inf_nan=False, description="Sampling step [m]")
    weight: float = Field(
        1.0, ge=0, allow_inf_nan=False, description="Relative weight of each sampled point"
    )

    @field_validator("points")
    @classmethod
    def _check_points(cls, v: list[list[float]]) -> list[list[float]]:
        return [finite_point(p, "road point") for p in v]


class UEMap(DocumentModel):
    """Where UEs are: any combination of a grid, weighted points, roads and CSV rows (all
    concatenated). Weights are relative (they need not sum to one)."""

    grid: GridMap | None = Field(None, description="Regular grid of positions")
    points: list[Point3] | None = Field(None, description="Explicit positions [m]")
    weights: list[float] | None = Field(
        None, description="Relative weights of ``points`` (default all 1)"
    )
    roads: list[Road] | None = Field(
        None, min_length=1, description="Roads sampled on a lattice (at least one if given)"
    )
    csv_text: str | None = Field(
        None,
        max_length=50_000_000,
        description="CSV text with columns x, y, z [m] and optionally weight (header row)",
    )

    @field_validator("points")
    @classmethod
    def _check_points(cls, v: list[list[float]] | None) -> list[list[float]] | None:
        return None if v is None else [finite_point(p, "map point") for p in v]

    @field_validator("csv_text")
    @classmethod
    def _check_csv(cls, v: str | None) -> str | None:
        if v is not None and not v.strip().partition("\n")[2].strip():
            raise ValueError("csv_text needs a header row (x, y, z[, weight]) and at least one row")
        return v

    @field_validator("weights")
    @classmethod
    def _check_weights(cls, v: list[float] | None) -> list[float] | None:
        return None if v is None else finite_weights(v, "weights")

    @model_validator(mode="after")
    def _check_sources(self) -> UEMap:
        if all(s is None for s in (self.grid, self.points, self.roads, self.csv_text)):
            raise ValueError("a UE map needs at least one of grid, points, roads, csv_text")
        if self.weights is not None and (
            self.points is None or len(self.weights) != len(self.points)
        ):
            raise ValueError("weights must hold one weight per entry of points")
        if self.points is not None and len(self.points) == 0:
            raise ValueError("points is empty")
        return self


class PairSample(DocumentModel):
    """A seeded weighted sample of TX–RX pairs; every sampled pair weighs 1.

    Without ``max_separation_m`` TX and RX are drawn independently with probabilities ∝ their
    map weights (pairs with coinciding positions redrawn). With it, a sidelink pair is two UEs
    near each other: the pair (i, j) is drawn with probability ∝ w_i · w_j among the pairs at
    most ``max_separation_m`` apart – a straight line, or with ``separation: "street"`` the
    shortest way along the roads of the maps (both UEs on a road) – and with
    ``line_of_sight`` only among those whose TX–RX leg is clear of the environment
    (docs/concepts/planning.md, "Pairs")."""

    sample: int = Field(ge=1, le=MAX_PAIRS_LIMIT, description="Number of pairs to draw")
    seed: int = Field(0, ge=0, description="Seed of the draw (numpy default_rng)")
    max_separation_m: float | None = Field(
        None,
        gt=0,
        le=100_000,
        allow_inf_nan=False,
        description="Largest TX–RX separation [m] of a drawn pair (absent: any separation)",
    )
    separation: Literal["straight", "street"] = Field(
        "straight",
        description="How the separation is measured: straight: the 3D distance; street: along"
        " the maps' roads (centre lines, plus each UE's lateral offset), both UEs on a road",
    )
    line_of_sight: bool = Field(
        False, description="Only pairs whose TX–RX leg is clear of the environment's obstacles"
    )

    @model_validator(mode="after")
    def _check_separation(self) -> PairSample:
        if self.separation == "street" and self.max_separation_m is None:
            raise ValueError('separation "street" needs max_separation_m')
        return self


class PairList(DocumentModel):
    """Explicit TX–RX pairs (the pair model ``explicit``): the pairs a caller drew or chose
    itself – a city's pairs handed to the cell that owns them (docs/concepts/district.md,
    "A city"), measured links, a site survey. Each pair is a TX and an RX of the maps, given
    either by their **map indices** (``tx_index``, ``rx_index``: the points of the maps as the
    plan evaluates them, the indices of plan.json ``points``: every source in order – grid,
    points, roads, CSV –, zero-weight points and points inside an obstacle left out) or by
    their **positions** (``tx``, ``rx``: each a point of its map, matched within 1 mm). A pair
    weighs ``weights[k]`` (relative; default 1 each); no pair is redrawn or left out."""

    tx_index: list[Annotated[int, Field(ge=0)]] | None = Field(
        None, max_length=MAX_PAIRS_LIMIT, description="TX map index of each pair"
    )
    rx_index: list[Annotated[int, Field(ge=0)]] | None = Field(
        None, max_length=MAX_PAIRS_LIMIT, description="RX map index of each pair"
    )
    tx: list[Point3] | None = Field(
        None, max_length=MAX_PAIRS_LIMIT, description="TX position of each pair [m] (a map point)"
    )
    rx: list[Point3] | None = Field(
        None, max_length=MAX_PAIRS_LIMIT, description="RX position of each pair [m] (a map point)"
    )
    weights: list[float] | None = Field(
        None,
        max_length=MAX_MAP_POINTS,  # one limit for every list named weights (one per pair)
        description="Relative weight of each pair (default 1 each; finite, ≥ 0, one positive)",
    )

    @model_validator(mode="after")
    def _check_pairs(self) -> PairList:
        by_index = self.tx_index is not None or self.rx_index is not None
        by_position = self.tx is not None or self.rx is not None
        if by_index == by_position:
            raise ValueError(
                "explicit pairs need tx_index and rx_index (map indices) or tx and rx"
                " (positions), one of the two"
            )
        tx, rx = (self.tx_index, self.rx_index) if by_index else (self.tx, self.rx)
        names = "tx_index and rx_index" if by_index else "tx and rx"
        if tx is None or rx is None:
            raise ValueError(f"explicit pairs need both {names}")
        if len(tx) != len(rx) or not tx:
            raise ValueError(f"{names} must list the same number of pairs, at least one")
        if by_position:
            finite_point(np.asarray([*tx, *rx], dtype=float).ravel().tolist(), "a pair position")
        if self.weights is not None:
            if len(self.weights) != len(tx):
                raise ValueError("weights must hold one weight per pair")
            finite_weights(self.weights, "pair weights")
            if not any(w > 0 for w in self.weights):
                raise ValueError("pair weights: at least one must be positive")
        return self

    @property
    def size(self) -> int:
        """The number of pairs."""
        listed = self.tx_index if self.tx_index is not None else self.tx
        return len(listed or [])

    @property
    def by_index(self) -> bool:
        """Whether the pairs are given by map indices (else by positions)."""
        return self.tx_index is not None


PairsSpec = Literal["all", "unordered"] | PairSample | PairList


def pairs_given(spec: PairsSpec, tx_points: int, rx_points: int) -> int:
    """The pairs a ``pairs`` value gives over maps of ``tx_points`` and ``rx_points`` points,
    before any is built (``max_pairs`` not applied): every combination (``all``), every
    unordered pair of one map, the sample, or the listed pairs."""
    if spec == "unordered":
        return tx_points * (tx_points - 1) // 2
    if spec == "all":
        return tx_points * rx_points
    return spec.sample if isinstance(spec, PairSample) else spec.size


def local_pairs(spec: PairsSpec) -> bool:
    """Whether a ``pairs`` value keeps each pair's UEs near each other – sidelink pairs
    (``max_separation_m``) or the caller's own listed pairs –, so a plan's per-point fields come
    from its own pairs rather than from heatmap pairs (docs/concepts/planning.md, "Per-point
    results")."""
    near = isinstance(spec, PairSample) and spec.max_separation_m is not None
    return near or isinstance(spec, PairList)


class Candidate(DocumentModel):
    """An explicit candidate site: a RIS pose (docs/concepts/conventions.md; faces local +x)."""

    position: Point3
    orientation: Annotated[
        list[float],
        Field(min_length=3, max_length=3, description="Euler [yaw, pitch, roll] in radians"),
    ] = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    name: str | None = Field(None, max_length=200, description="Label used in reports")
    cost: float = Field(
        0.0, ge=0, allow_inf_nan=False, description="Cost of using this site (any unit)"
    )

    @model_validator(mode="after")
    def _check_pose(self) -> Candidate:
        # the scenario's RIS model owns the pose rules (finite, within range)
        RIS(position=self.position, orientation=self.orientation)
        return self


class WallSites(DocumentModel):
    """Mounting sites on a wall: a segment (``start``, ``end``) or a building footprint
    (``rectangle``, four walls facing outwards), sampled every ``spacing_m`` along the wall at
    every height and tilt. A RIS faces the wall's normal (yaw) and is tilted by ``tilt``
    (pitch; positive tilts the face downwards)."""

    start: Point2 | None = Field(None, description="Segment start [x, y] in metres")
    end: Point2 | None = Field(None, description="Segment end [x, y] in metres")
    side: Literal["left", "right"] = Field(
        "left",
        description="Segment only: the RIS faces the normal on this side of start→end",
    )
    rectangle: Annotated[list[float], Field(min_length=4, max_length=4)] | None = Field(
        None, description="Footprint [x_min, y_min, x_max, y_max] in metres (faces outward)"
    )
    heights_m: list[float] = Field(
        min_length=1, max_length=100, description="Mounting heights z of the RIS centre [m]"
    )
    spacing_m: float = Field(
        gt=0, le=10000, allow_inf_nan=False, description="Distance between sites along a wall [m]"
    )
    tilts_rad: list[float] = Field(
        default_factory=lambda: [0.0],
        min_length=1,
        max_length=100,
        description="Downward tilts (pitch) to try at each site [rad]",
    )
    cost: float = Field(
        0.0, ge=0, allow_inf_nan=False, description="Cost of using each site of this wall"
    )

    @model_validator(mode="after")
    def _check_shape(self) -> WallSites:
        seg = self.start is not None and self.end is not None
        if seg == (self.rectangle is not None) or (self.start is None) != (self.end is None):
            raise ValueError("a wall is either start + end (a segment) or a rectangle")
        pts = [*(self.rectangle or []), *(self.start or []), *(self.end or [])]
        finite_point(pts + list(self.heights_m), "wall coordinate")
        # an absolute length: a relative test calls a short facade far from the origin (a
        # 1.6 mm wall left between two corner clearances at 400 m) "coinciding"
        if seg and math.dist(self.start, self.end) < MIN_WALL_M:  # type: ignore[arg-type]
            raise ValueError(f"wall start and end coincide (closer than {MIN_WALL_M:g} m)")
        if self.rectangle is not None:
            x0, y0, x1, y1 = self.rectangle
            if not (x1 > x0 and y1 > y0):
                raise ValueError("rectangle must be [x_min, y_min, x_max, y_max] with max > min")
        check_tilts(self.tilts_rad)
        return self


def check_tilts(tilts: list[float]) -> None:
    """Tilts (pitch) of wall and facade sites lie within ±π/2."""
    if any(abs(t) > math.pi / 2 for t in tilts):
        raise ValueError("tilts_rad must lie within ±π/2")


class Facades(DocumentModel):
    """Mounting sites on every facade (footprint edge) of the named prisms of ``environment``.

    Each edge is a :class:`WallSites` segment facing outward (the normal is computed from the
    footprint, any winding), moved ``offset_m`` outward, sampled every ``spacing_m`` at every
    height and tilt. Heights are measured from the prism's base and clipped to its top (a RIS
    on the roof edge); heights that clip to the same z give one site."""

    of: list[str] = Field(
        min_length=1,
        max_length=MAX_FACADE_PRISMS,
        description="Names of prisms in environment.obstacles whose facades carry sites",
    )
    heights_m: list[float] = Field(
        min_length=1,
        max_length=100,
        description="Heights of the RIS centre above the prism's base [m] (≥ 0), clipped to"
        " its top",
    )
    spacing_m: float = Field(
        gt=0, le=10000, allow_inf_nan=False, description="Distance between sites along an edge [m]"
    )
    tilts_rad: list[float] = Field(
        default_factory=lambda: [0.0],
        min_length=1,
        max_length=100,
        description="Downward tilts (pitch) to try at each site [rad]",
    )
    offset_m: float = Field(
        0.0,
        ge=0,
        le=100,
        allow_inf_nan=False,
        description="Distance of the RIS centre in front of the facade [m] (0: on it)",
    )

    @model_validator(mode="after")
    def _check_values(self) -> Facades:
        finite_point(list(self.heights_m), "facades.heights_m")
        if any(h < 0 for h in self.heights_m):
            raise ValueError(f"facades.heights_m must be ≥ 0 (from the base), got {self.heights_m}")
        check_tilts(self.tilts_rad)
        return self


PlanCodebookKind = Literal["expected_random", "directional", "directional_derivative"]
"""The codebooks a plan scores layouts with (``codebook.kind``)."""

DEFAULT_GAMMA_P = 0.5
"""Default DER-to-DIR amplitude ratio γ_P of a designed DIR+DER codebook (eq.
opt_formulation_3; docs/concepts/district-physics.md, "Beams")."""


class PlanCodebook(DocumentModel):
    """The codebook layouts are scored with: ``expected_random`` (the closed-form expectation
    of the FIM over uniformly random phases, deterministic: the planning default), or a
    codebook designed per candidate site from the UE pairs it serves – ``directional`` (DIR
    beams, eq. DIR_codebook) or ``directional_derivative`` (DIR+DER, eq. DER_codebook, with the
    γ_P power split of eq. opt_formulation_3). Designed codebooks are scored by the district
    search (docs/concepts/district-physics.md); the enumerating searches score
    ``expected_random`` and design beams for their recommended layouts with ``beams``."""

    kind: PlanCodebookKind = Field(
        "expected_random",
        description="expected_random (random phases, the expected FIM); directional (DIR);"
        " directional_derivative (DIR+DER with the γ_P power split)",
    )
    gamma_p: float | None = Field(
        None,
        ge=0,
        le=100,
        allow_inf_nan=False,
        description="directional_derivative: γ_P, the DER beams' amplitude relative to the DIR"
        f" beams' (DIR power 3/(1+2γ_P²), DER 3γ_P²/(1+2γ_P²)); default {DEFAULT_GAMMA_P}",
    )
    blocks: int | None = Field(
        None,
        ge=2,
        le=4096,
        description="Γ, the time-orthogonal blocks of the G transmissions (a divisor of"
        " system.transmissions, at least one more than the profile colours a layout needs);"
        " default: the planner chooses the smallest that every reported layout fits",
    )
    seed: int | None = Field(
        None, ge=0, description="Designed codebooks: seed of the pairs each site's beams point at"
    )

    @model_validator(mode="after")
    def _check_kind(self) -> PlanCodebook:
        if self.gamma_p is not None and self.kind != "directional_derivative":
            raise ValueError(f"codebook.gamma_p applies to directional_derivative, not {self.kind}")
        if self.seed is not None and self.kind == "expected_random":
            raise ValueError("codebook.seed applies to designed codebooks, not expected_random")
        return self

    @property
    def gamma(self) -> float:
        """γ_P in force (:data:`DEFAULT_GAMMA_P` unless given)."""
        return DEFAULT_GAMMA_P if self.gamma_p is None else float(self.gamma_p)


class RISDefaults(RISGrid):
    """The element grid, field of view and pattern of every candidate RIS (the scenario
    document's per-RIS fields of the same names, :class:`~ris_planner.model.scenario.RISGrid`).

    Unlike a scenario's (the paper's isotropic q = 0, 90°), ``pattern_exponent`` and
    ``max_angle_deg`` default to a physical element: the unit-cell power pattern cos³ θ of
    Tang et al. (IEEE TWC 2021) as the amplitude exponent q = 1.5, and a field of view of
    84.26° (:mod:`ris_planner.model.plan_physics`, docs/concepts/planning-physics.md). A value
    the document gives always wins (``model_fields_set`` tells them apart)."""

    max_angle_deg: float = Field(
        PLAN_MAX_ANGLE_DEG,
        gt=0,
        le=180,
        allow_inf_nan=False,
        description="Field of view: a UE is served only when the angle between the RIS normal"
        " and the direction to the UE is strictly below this [deg]; default 84.26 (cos θ > 0.1:"
        " the cos³ θ unit-cell pattern 30 dB below boresight); 90 = the paper's open front"
        " half-space",
    )
    pattern_exponent: float = Field(
        PLAN_PATTERN_EXPONENT,
        ge=0,
        le=100,
        allow_inf_nan=False,
        description="q of the element pattern: the path gain |ρ| is multiplied by"
        " (cos θ_T · cos θ_R)^q, θ the angles to the normal; default 1.5 (the unit-cell power"
        " pattern cos³ θ of Tang et al., IEEE TWC 2021, as an amplitude exponent); 0 = the"
        " paper's isotropic model",
    )


# --- decisions: targets, constraints and cost ----------------------------------------------

SAME_SPOT_M = 0.01
"""Candidates whose centres lie within this horizontal (x, y) distance share one mounting point
(heights and tilts of one spot): 1 cm, far below any sensible site spacing and far above the
rounding of expanded wall coordinates."""


class Target(DocumentModel):
    """A requirement on the objective: ``min`` (coverage: the fraction must be ≥ it) or ``max``
    (mean_capped / quantile: the bound in metres must be ≤ it)."""

    min: float | None = Field(None, ge=0, allow_inf_nan=False, description="Lower limit")
    max: float | None = Field(None, gt=0, allow_inf_nan=False, description="Upper limit [m]")

    def met(self, value: float) -> bool:
        """Whether an objective value meets the target (``inf`` never meets a ``max``)."""
        if self.min is not None:
            return value >= self.min - GOAL_ATOL
        assert self.max is not None
        return value <= self.max


GOAL_ATOL = 1e-12
"""A weighted fraction meets a ``min`` within this (rounding of weight sums)."""


def target_goal(kind: str, target: Target, servable_weight: float) -> Target:
    """The objective value a target asks for: a share of the servable pairs' weight for a kind
    whose targets are shares of them (:attr:`~ris_planner.model.objectives.protocol.
    ObjectiveKind.share_of_servable`: coverage), else the target as written."""
    if objective_kind(kind).share_of_servable and target.min is not None:
        return Target(min=target.min * servable_weight)
    return target


class Constraints(DocumentModel):
    """Which layouts are allowed. Candidate indices are those of the plan's candidate list
    (explicit candidates first, then each wall's sites, as in plan.json ``candidates``)."""

    exclusive_mounts: bool = Field(
        True,
        description="Candidates sharing a mounting point (x, y within same_spot_m: heights or"
        " tilts of one spot) are mutually exclusive",
    )
    same_spot_m: float = Field(
        SAME_SPOT_M, ge=0, le=100, allow_inf_nan=False, description="Same-spot distance [m]"
    )
    min_separation_m: float = Field(
        0.0, ge=0, le=1e6, allow_inf_nan=False, description="Least 3-D distance between RISs [m]"
    )
    require: list[int] = Field(
        default_factory=list, max_length=16, description="Candidates every layout must use"
    )
    exclude: list[int] = Field(
        default_factory=list, max_length=MAX_SITES, description="Candidates never used"
    )
    budget: float | None = Field(
        None, ge=0, allow_inf_nan=False, description="Largest total cost of a layout"
    )

    @model_validator(mode="after")
    def _check_sets(self) -> Constraints:
        both = set(self.require) & set(self.exclude)
        if both:
            raise ValueError(f"constraints: candidates {sorted(both)} are required and excluded")
        if any(i < 0 for i in [*self.require, *self.exclude]):
            raise ValueError("constraints: candidate indices must be ≥ 0")
        if len(set(self.require)) != len(self.require):
            raise ValueError("constraints.require lists a candidate twice")
        return self


class CostSpec(DocumentModel):
    """Layout cost = Σ over its RISs of (site cost + per_ris + per_element · rows · cols)."""

    per_ris: float = Field(0.0, ge=0, allow_inf_nan=False, description="Cost of each RIS")
    per_element: float = Field(
        0.0, ge=0, allow_inf_nan=False, description="Cost per RIS element (per-size cost)"
    )


MAX_SWEEP_VALUES = 16
"""Sweep values per plan (each runs the whole plan once more)."""


class Sweep(DocumentModel):
    """One parameter varied over the same candidates and pairs; each value runs the plan once
    more with that value (the document's own value is the base run). Give exactly one list."""

    tx_power_dbm: list[float] | None = Field(
        None, min_length=1, max_length=MAX_SWEEP_VALUES, description="Transmit powers [dBm]"
    )
    noise_figure_db: list[float] | None = Field(
        None, min_length=1, max_length=MAX_SWEEP_VALUES, description="Noise figures [dB]"
    )
    ris_size: list[Annotated[list[int], Field(min_length=2, max_length=2)]] | None = Field(
        None,
        min_length=1,
        max_length=MAX_SWEEP_VALUES,
        description="RIS element grids [rows, cols] (each 1–512)",
    )

    @model_validator(mode="after")
    def _one(self) -> Sweep:
        given = [k for k in ("tx_power_dbm", "noise_figure_db", "ris_size") if getattr(self, k)]
        if len(given) != 1:
            raise ValueError(
                "sweep: give exactly one of tx_power_dbm, noise_figure_db, ris_size"
                f" (got {given or 'none'})"
            )
        for v in self.tx_power_dbm or []:
            if not (-100 <= v <= 100):
                raise ValueError(f"sweep.tx_power_dbm {v} is outside [-100, 100] dBm")
        for v in self.noise_figure_db or []:
            if not (0 <= v <= 100):
                raise ValueError(f"sweep.noise_figure_db {v} is outside [0, 100] dB")
        for rc in self.ris_size or []:
            if not all(1 <= x <= 512 for x in rc):
                raise ValueError(f"sweep.ris_size {rc}: rows and cols must be 1–512")
        return self

    @property
    def parameter(self) -> str:
        return next(k for k in ("tx_power_dbm", "noise_figure_db", "ris_size") if getattr(self, k))

    @property
    def values(self) -> list[Any]:
        return list(getattr(self, self.parameter))

    def apply(self, doc: dict[str, Any], value: Any) -> dict[str, Any]:
        """The plan document (a JSON dict, without ``sweep``) with this sweep value set."""
        out = {k: v for k, v in doc.items() if k != "sweep"}
        if self.parameter == "ris_size":
            out["ris"] = {**out.get("ris", {}), "rows": value[0], "cols": value[1]}
        else:
            out["system"] = {**out.get("system", {}), self.parameter: value}
        return out


DEFAULT_SIZING_LADDER = ((10, 10), (16, 16), (24, 24), (32, 32), (48, 48), (64, 64), (100, 100))
"""The RIS element grids [rows, cols] the sizing question tries by default
(docs/concepts/diagnosis.md): square grids from the import default (10 × 10) to 100 × 100."""

SIZING_COVERAGE_TARGET = 0.9
"""The default sizing target of a coverage objective without ``objective.target``: 90 % of the
pair weight with a bound ≤ threshold_m (docs/concepts/diagnosis.md)."""


def _method_schema(schema: dict[str, Any]) -> None:
    """``search.method``'s JSON schema: ``auto`` and the registered methods (as a Literal
    gives; methods may register after this module is imported)."""
    schema["enum"] = list(method_names())


class SizingTarget(DocumentModel):
    """The objective value the sizing question must reach: coverage ≥ it (a fraction), a
    bound in metres (mean_capped, quantile) ≤ it."""

    objective: float = Field(gt=0, allow_inf_nan=False, description="Objective value to reach")


class Sizing(DocumentModel):
    """The sizing question: the smallest RIS size × count that reaches the target
    (docs/concepts/diagnosis.md). Each size runs the plan once more over the same candidates
    and pairs (the ``sweep`` machinery over ``ris_size``)."""

    ris_sizes: list[Annotated[list[int], Field(min_length=2, max_length=2)]] = Field(
        default_factory=lambda: [list(s) for s in DEFAULT_SIZING_LADDER],
        min_length=1,
        max_length=MAX_SWEEP_VALUES,
        description="RIS element grids [rows, cols] to try (each 1–512); default 10×10, 16×16,"
        " 24×24, 32×32, 48×48, 64×64, 100×100",
    )
    counts: list[int] | None = Field(
        None,
        min_length=1,
        max_length=16,
        description="RIS counts to try (default: the document's ris_count, else 1 … max_ris"
        " stopping at the first count that reaches the target)",
    )
    target: SizingTarget | None = Field(
        None,
        description="What to reach (default: objective.target, else coverage ≥ 0.9 of the"
        " servable pairs; a mean_capped or quantile objective without objective.target needs"
        " it)",
    )
    method: MethodName = Field(
        AUTO,
        description="The search that answers it at each size: auto (the plan's own enumerating"
        " search where its runs fit the search limits, else the district search – the reason is"
        " in plan.json sizing.search_method) or a registered method",
        json_schema_extra=_method_schema,
    )

    @field_validator("ris_sizes")
    @classmethod
    def _check_sizes(cls, v: list[list[int]]) -> list[list[int]]:
        for rc in v:
            if not all(1 <= x <= 512 for x in rc):
                raise ValueError(f"sizing.ris_sizes {rc}: rows and cols must be 1–512")
        # ascending element count (then rows), duplicates dropped
        return [list(t) for t in sorted({tuple(rc) for rc in v}, key=lambda t: (t[0] * t[1], t))]

    @field_validator("counts")
    @classmethod
    def _check_counts(cls, v: list[int] | None) -> list[int] | None:
        if v is None:
            return v
        if any(not 1 <= c <= 16 for c in v) or len(set(v)) != len(v):
            raise ValueError(f"sizing.counts must be distinct counts 1–16, got {v}")
        return sorted(v)


# ---------------------------------------------------------------------------------------------


def _objective_kinds() -> tuple[str, ...]:
    """The registered objective kinds (when the schema is built: kinds may register later)."""
    return objective_names()


def _kind_schema(schema: dict[str, Any]) -> None:
    """``objective.kind``'s JSON schema: an enum of the registered kinds (as a Literal gives)."""
    schema["enum"] = list(_objective_kinds())


def _own_parameters() -> dict[str, list[str]]:
    """The parameters registered kinds name themselves (no field of :class:`Objective`), each
    with the kinds that take it."""
    own: dict[str, list[str]] = {}
    for name in _objective_kinds():
        param = objective_kind(name).parameter
        if param is not None and param not in Objective.model_fields:
            own.setdefault(param, []).append(name)
    return own


def _objective_schema(schema: dict[str, Any]) -> None:
    """``objective``'s JSON schema: its fields, the registered kinds' own parameters, nothing
    else (the block accepts a kind's own parameter and refuses any other unknown field)."""
    props = schema.setdefault("properties", {})
    for param, kinds in _own_parameters().items():
        props[param] = {
            "type": "number",
            "exclusiveMinimum": 0,
            "title": param,
            "description": " ".join(f"{k}: {objective_kind(k).parameter_label}" for k in kinds),
        }
    schema["additionalProperties"] = False


class Objective(DocumentModel):
    """What a layout is scored on, over the weighted pairs. ``metric``: ``rx`` (PEB_R), ``tx``
    (PEB_T) or ``max`` (max(PEB_T, PEB_R)), in metres. Blind spots (infinite bounds) fail:
    outside the coverage, at the cap, and at the top of the quantile. ``kind`` names a
    registered objective (:mod:`ris_planner.model.objectives`, docs/concepts/scoring.md); a
    kind whose parameter is none of the fields below names its own, which the block then
    accepts (docs/guides/adding-an-objective.md)."""

    model_config = ConfigDict(extra="allow", json_schema_extra=_objective_schema)

    kind: str = Field(
        description="coverage: weighted fraction with bound ≤ threshold_m (higher is better);"
        " mean_capped: weighted mean of min(bound, cap_m) [m]; quantile: weighted q-quantile [m]",
        json_schema_extra=_kind_schema,
    )
    metric: Literal["rx", "tx", "max"] = Field("rx", description="Which bound [m]")
    threshold_m: float | None = Field(
        None, gt=0, allow_inf_nan=False, description="coverage: bound threshold [m]"
    )
    cap_m: float | None = Field(
        None, gt=0, allow_inf_nan=False, description="mean_capped: cap on the bound [m]"
    )
    q: float | None = Field(
        None, gt=0, lt=1, allow_inf_nan=False, description="quantile: probability in (0, 1)"
    )
    target: Target | None = Field(
        None,
        description="A requirement on the objective's value: the plan answers the smallest RIS"
        " count that meets it (coverage: {'min': fraction}; mean_capped, quantile: {'max': m})",
    )

    @field_validator("kind")
    @classmethod
    def _known_kind(cls, kind: str) -> str:
        objective_kind(kind)  # a ValueError naming the known kinds
        return kind

    @model_validator(mode="after")
    def _check_params(self) -> Objective:
        spec = objective_kind(self.kind)
        need = spec.parameter
        for key, value in (self.__pydantic_extra__ or {}).items():
            if key != need:
                raise ValueError(
                    f"objective.{key}: extra inputs are not permitted (objective kind"
                    f" {self.kind!r} takes {need or 'no parameter'})"
                )
            spec.check_parameter(value)
        if need is not None and getattr(self, need, None) is None:
            raise ValueError(f"objective kind {self.kind!r} needs {need}")
        if self.target is not None:
            if spec.higher_is_better:
                if self.target.min is None or self.target.max is not None:
                    raise ValueError(f"a {self.kind} target is {{'min': value}}")
                if spec.max_value is not None and self.target.min > spec.max_value:
                    raise ValueError(
                        f"target.min {self.target.min} is a {self.kind} ≤ {spec.max_value:g}"
                    )
            elif self.target.max is None or self.target.min is not None:
                raise ValueError(f"a {self.kind} target is {{'max': bound in metres}}")
        return self


TIE_RTOL = 1e-3
"""Default tie tolerance (relative to the best objective): differences below 0.1 % are far
inside the spread a different pair sample or map resolution gives, so such layouts are listed
as ties rather than ranked apart."""


CERTIFICATE_ITERATIONS = 20
"""Default Frank–Wolfe iterations of the relaxation bound: on the hall benchmark the bound at
40 iterations is within 2 % of the one at 20 (fraction of pairs proven uncoverable 0.317 vs
0.311 at L = 2), at twice the time (≈ 0.3 s per iteration for 156 sites × 6400 pairs)."""


POOL_MIN_WORK = 2_000_000_000
"""Default ``search.pool_min_work``: below 2·10⁹ layout-pair evaluations (minutes of scoring on
2 cores) a local plan runs in-process. Measured on 2 cores, in-process against 2 workers in the
same run: the Kamppi block 5.1 s against 10.0 s (+1.2 s closing the pool), the hall 5.0 s
against 9.9 s (+1.0 s) – the compiled scorer already uses every core by threads, and a worker
pays its interpreter, imports and kernels before its first task."""


class SearchSpec(DocumentModel):
    """The placement search."""

    method: MethodName = Field(
        AUTO,
        description="auto: the planner chooses – exhaustive when a count's layouts are at most"
        " max_exhaustive, else greedy, and district where those cannot take the document (the"
        " reason is in plan.json search_method); exhaustive; greedy; district: tens of RISs"
        " from thousands of candidates by locality, each count with a certified coverage"
        " interval (coverage objectives; docs/concepts/district.md). GET /v1/search-methods"
        " lists each method's capabilities",
        json_schema_extra=_method_schema,
    )

    max_exhaustive: int = Field(
        100_000, ge=1, le=5_000_000, description="Largest layout count searched exhaustively"
    )
    top_k: int = Field(10, ge=1, le=1000, description="Number of ranked layouts reported per count")
    seed: int = Field(0, ge=0, description="Seed of the greedy search's random restarts")
    restarts: int = Field(
        3,
        ge=0,
        le=1000,
        description="Greedy: random starting layouts besides the greedy one (on random small"
        " instances 3 bring the search within 1 % of exhaustive search in 98 % of the counts,"
        " against 93 % with none, for ≈ 2.8× the layouts scored)",
    )
    max_rounds: int = Field(50, ge=1, le=10000, description="Greedy: maximum swap rounds per start")
    tie_rtol: float = Field(
        TIE_RTOL,
        ge=0,
        le=1,
        allow_inf_nan=False,
        description="Layouts whose objective lies within tie_rtol·|best| of the best tie",
    )
    pool_min_work: int = Field(
        POOL_MIN_WORK,
        ge=0,
        le=10**15,
        description="Layout × pair evaluations of the search (summed over the counts) below"
        " which a plan on a local executor runs in its own process, the compiled scorer on"
        " every core by threads, and starts no worker processes (their start-up costs more"
        " than they save: docs/validation/benchmarks.md); 0: workers whenever a batch splits",
    )
    certificate_iterations: int = Field(
        CERTIFICATE_ITERATIONS,
        ge=0,
        le=10_000,
        description="Frank–Wolfe iterations of the per-pair relaxation bound (0: no bound"
        " unless the search is exhaustive)",
    )


class BeamsSpec(DocumentModel):
    """Beams and power for the recommended layouts (``planning.beam_design``): DIR and DIR+DER
    codebooks designed from the UE maps, uniform power, the best γ_P and the SDP, each
    re-evaluated on the plan's pairs with its objective, next to ``expected_random`` and
    ``random`` codebooks."""

    design_positions: int = Field(
        64,
        ge=1,
        le=MAX_DESIGN_POSITIONS,
        description="Pairs (LMIs) the γ_P search and the SDP optimise over: a seeded weighted"
        " subsample of the pairs the layout resolves (district plans: the γ_P search's; each"
        " RIS's own SDP takes at most 8 of the pairs it serves)",
    )
    seed: int = Field(0, ge=0, description="Seed of the beam samples and the design positions")
    random_seeds: int = Field(
        3, ge=1, le=20, description="Random codebooks (seeds 0…n−1) the designs are compared with"
    )
    solver: Solver = Field("CLARABEL", description="SDP solver (CLARABEL or SCS)")
    layouts: list[list[int]] = Field(
        default_factory=list,
        max_length=20,
        description="Further layouts (candidate indices) to evaluate besides the best per count",
    )


MAX_VALIDATION_ESTIMATES = 20_000
"""Pairs × draws of a plan validation above this are refused (≈ 30–100 ms per estimate)."""


LonLatH = Annotated[
    list[float],
    Field(
        min_length=3,
        max_length=3,
        description="[lon, lat, h]: WGS84 degrees in GeoJSON order and a height in metres (as"
        " every 3-D point of a document with a frame)",
    ),
]


class SearchRegion(DocumentModel):
    """A box of TX candidates for the estimator's coarse stage (a prior a deployment knows):
    ``min_m``/``max_m`` in the plan's local metres, or – in a document with a ``frame`` –
    ``min_lonlat``/``max_lonlat`` as [lon, lat, h] (WGS84, GeoJSON order; converted at the
    document boundary by :func:`ris_planner.io.frames.to_local` into the local box that holds
    the lon/lat box, so the model here sees ``min_m``/``max_m``). Exactly one of the forms."""

    min_m: Point3 | None = Field(
        None, description="lower corner [x, y, z] of the TX box in local metres"
    )
    max_m: Point3 | None = Field(
        None, description="upper corner [x, y, z] of the TX box in local metres"
    )
    min_lonlat: LonLatH | None = Field(
        None,
        description="lower corner [lon, lat, h] (WGS84 degrees, metres; needs the document's"
        " frame): the local box holds the lon/lat box",
    )
    max_lonlat: LonLatH | None = Field(
        None,
        description="upper corner [lon, lat, h] (WGS84 degrees, metres; needs the document's"
        " frame)",
    )

    @model_validator(mode="after")
    def _check_box(self) -> SearchRegion:
        metric = self.min_m is not None or self.max_m is not None
        geo = self.min_lonlat is not None or self.max_lonlat is not None
        if metric and geo:
            raise ValueError(
                "search_region: give min_m/max_m (local metres) or min_lonlat/max_lonlat"
                " ([lon, lat, h] with the document's frame), not both"
            )
        if geo:
            raise ValueError(
                "search_region.min_lonlat/max_lonlat are [lon, lat, h] of a document with a"
                " 'frame' (its origin places them); this document has none: add"
                ' "frame": {"origin": [lon, lat, h]} or give min_m/max_m in local metres'
            )
        if self.min_m is None or self.max_m is None:
            raise ValueError(
                "search_region needs both min_m and max_m (or, with a frame,"
                " min_lonlat and max_lonlat)"
            )
        lo, hi = np.asarray(self.min_m, float), np.asarray(self.max_m, float)
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
            raise ValueError("search_region corners must be finite")
        if np.any(hi < lo):
            axis = int(np.argmax(hi < lo))
            raise ValueError(
                f"search_region is empty: max_m[{axis}] = {hi[axis]} < min_m[{axis}] = {lo[axis]}"
            )
        return self


class ValidationSpec(DocumentModel):
    """Validate the recommended layouts with the paper's two-stage estimator (Algorithms 1
    and 2) on the plan's own pairs, blockage and multipath (plan.json ``validation``;
    :mod:`ris_planner.planning.outputs.estimator_check`, docs/validation/estimator.md)."""

    pairs: int = Field(20, ge=1, le=1000, description="TX–RX pairs sampled ∝ the plan's weights")
    draws: int = Field(5, ge=1, le=1000, description="Noise and gain-phase draws per pair")
    seed: int = Field(0, ge=0, description="Seed of the pair sample, the codebook and the draws")
    reflections: bool = Field(
        False,
        description="Add first-order specular reflections off the environment's facades and"
        " walls to the simulated signal (ris_planner.environment.reflections)",
    )
    multipath: dict[str, Any] | None = Field(
        None,
        description="Diffuse scatterers/clusters as in the simulation document's 'multipath'",
    )
    search_region: SearchRegion | None = Field(
        None,
        description="Box of TX candidates of the coarse position search (a prior); default the"
        " TX map's extent",
    )
    codebook: Literal["plan", "random"] = Field(
        "plan",
        description="plan: the layout's designed beams and powers when the document has"
        " 'beams' (the design named by 'design'), else a random codebook of seed 'seed';"
        " random: always the seeded random codebook",
    )
    design: Literal["best", "directional", "dir_der_uniform", "dir_der_gamma_p", "dir_der_sdp"] = (
        Field(
            "best",
            description="The designed codebook simulated with codebook 'plan': best = the one"
            " with the best plan objective on all pairs (plan.json by_count[i].beams.objective)",
        )
    )
    step_m: float = Field(
        0.2, gt=0, le=100, allow_inf_nan=False, description="TX candidate grid step [m]"
    )
    max_candidates: int = Field(
        50_000,
        ge=1,
        le=2_000_000,
        description="Largest TX candidate count: the step grows until the region fits",
    )
    threshold_m: float | None = Field(
        None,
        gt=0,
        allow_inf_nan=False,
        description="Error threshold of the coverage [m]; default the objective kind's check"
        " level (its threshold or cap; an objective without one needs it)",
    )

    @model_validator(mode="after")
    def _check_spec(self) -> ValidationSpec:
        if self.pairs * self.draws > MAX_VALIDATION_ESTIMATES:
            raise ValueError(
                f"validation: {self.pairs} pairs × {self.draws} draws exceed the limit of"
                f" {MAX_VALIDATION_ESTIMATES} estimates"
            )
        if self.multipath is not None:
            try:
                Multipath.model_validate(self.multipath)
            except ValidationError as exc:
                first = exc.errors()[0]
                where = ".".join(str(p) for p in first["loc"])
                raise ValueError(f"validation.multipath.{where}: {first['msg']}") from None
        return self


class PlanDocument(DocumentModel):
    """A planning request: where UEs are, where RISs may go, what to optimise."""

    description: str | None = Field(None, max_length=2000, description="Free text")
    system: SystemParams = Field(
        default_factory=SystemParams, description="Radio parameters (Table I defaults)"
    )
    ris: RISDefaults = Field(
        default_factory=RISDefaults, description="Element grid of every candidate RIS"
    )
    candidates: list[Candidate] = Field(
        default_factory=list, max_length=MAX_CANDIDATES, description="Explicit candidate sites"
    )
    walls: list[WallSites] = Field(
        default_factory=list, max_length=MAX_WALLS, description="Walls expanded to candidate sites"
    )
    facades: list[Facades] = Field(
        default_factory=list,
        max_length=MAX_WALLS,
        description="Facades of named environment prisms expanded to candidate sites",
    )
    environment: Environment | None = Field(
        None,
        description="Obstacles (prisms, walls) that block legs; UE map points inside prisms are"
        " dropped; absent = free space",
    )
    tx_map: UEMap = Field(description="TX probability map (positions [m], relative weights)")
    rx_map: UEMap = Field(description="RX probability map (positions [m], relative weights)")
    pairs: PairsSpec = Field(
        "all",
        description="all: every TX×RX combination of distinct positions, weight w_T·w_R;"
        " unordered: every unordered pair of distinct points of one map (tx_map = rx_map,"
        " weight w_i·w_j), counted in both directions with half the weight each for the"
        " metrics rx and tx (max is symmetric); a seeded sample; or explicit pairs (map indices"
        " or positions, with weights)",
    )
    max_pairs: int = Field(
        DEFAULT_MAX_PAIRS,
        ge=1,
        le=MAX_PAIRS_LIMIT,
        description="Limit on the number of evaluated pairs (use pairs.sample beyond it)",
    )
    objective: Objective = Field(description="The objective scored over the weighted pairs")
    ris_count: list[int] | None = Field(
        None,
        min_length=1,
        max_length=16,
        description="RIS counts L to compare (e.g. [2, 3, 4]); may be omitted with a target",
    )
    mode: Literal["compare", "target"] | None = Field(
        None,
        description="compare: search the listed ris_count; target: search 1, 2, … up to"
        " max_ris and stop at the smallest count that meets objective.target (default: target"
        " when ris_count is omitted)",
    )
    max_ris: int = Field(
        6,
        ge=1,
        le=MAX_DISTRICT_RIS,
        description="target mode: the largest RIS count searched (above"
        f" {MAX_LAYOUT_RIS}: search.method 'district')",
    )
    constraints: Constraints = Field(
        default_factory=Constraints, description="Allowed layouts (mounting points, spacing …)"
    )
    cost: CostSpec = Field(default_factory=CostSpec, description="Layout cost model")
    sweep: Sweep | None = Field(
        None, description="Run the plan again for each value of one parameter (one table)"
    )
    sizing: Sizing | None = Field(
        None,
        description="Also answer the smallest RIS size × count that reaches a target"
        " (plan.json 'sizing'; docs/concepts/diagnosis.md)",
    )
    codebook: PlanCodebook = Field(
        default_factory=PlanCodebook,
        description="The codebook layouts are scored with (expected_random; designed per site"
        " by the district search)",
    )
    known: list[KnownPart] = Field(
        default_factory=list, description="Known state parts: clock, height, tx"
    )
    search: SearchSpec = Field(default_factory=SearchSpec, description="Placement search")
    rollout: Literal["free", "nested"] = Field(
        "free",
        description="free: every RIS count's best layout on its own; nested: a phased"
        " roll-out, each count's layout contains the previous count's (plan.json rollout:"
        " nested layouts and the price of nesting; docs/guides/rollout.md)",
    )
    beams: BeamsSpec | None = Field(
        None,
        description="Design beams from the UE maps and allocate power for the recommended"
        " layouts (absent: expected_random scoring only)",
    )
    heatmap_tx: Point3 | None = Field(
        None,
        description="Fixed TX position [m] for the heatmap; default: TX averaged over its map",
    )
    validation: ValidationSpec | None = Field(
        None,
        description="Run the two-stage estimator on each recommended layout at pairs sampled"
        " from the maps (plan.json 'validation'; docs/validation/estimator.md)",
    )

    @field_validator("heatmap_tx")
    @classmethod
    def _check_heatmap_tx(cls, v: list[float] | None) -> list[float] | None:
        return None if v is None else finite_point(v, "heatmap_tx")

    @field_validator("ris_count")
    @classmethod
    def _check_counts(cls, v: list[int] | None) -> list[int] | None:
        if v is None:
            return v
        if any(c < 1 for c in v):
            raise ValueError(f"ris_count entries must be ≥ 1, got {v}")
        if len(set(v)) != len(v):
            raise ValueError(f"ris_count lists a count twice: {v}")
        return sorted(v)

    @field_validator("known")
    @classmethod
    def _unique_known(cls, v: list[str]) -> list[str]:
        return Scenario._unique_known(v)  # the scenario document's rule

    @model_validator(mode="after")
    def _check_plan(self) -> PlanDocument:
        if not self.candidates and not self.walls and not self.facades:
            raise ValueError("no candidate sites: give candidates, walls and/or facades")
        self.facade_prisms()  # every named prism exists
        if "tx" in self.known and self.objective.metric != "rx":
            raise ValueError(
                f"objective metric {self.objective.metric!r} needs PEB_T, but 'tx' is known"
            )
        if self.pairs == "unordered" and self.tx_map != self.rx_map:
            raise ValueError("pairs 'unordered' needs tx_map and rx_map to be the same map")
        check_pair_indices(self.pairs, self.tx_map, self.rx_map)
        largest = max(self.max_counts)
        if largest > MAX_DISTRICT_RIS:
            raise ValueError(f"ris_count {largest} is above the limit of {MAX_DISTRICT_RIS}")
        if self.ris_count is None and self.objective.target is None:
            raise ValueError("give ris_count, or objective.target to search for the count")
        if self.target_mode and self.objective.target is None:
            raise ValueError("mode 'target' needs objective.target")
        if len(self.constraints.require) > self.max_counts[-1]:
            raise ValueError(
                f"constraints.require names {len(self.constraints.require)} candidates, more"
                f" than the largest RIS count {self.max_counts[-1]}"
            )
        if self.sizing is not None:
            self.sizing_target()  # a target exists
        blocks = self.codebook.blocks
        if blocks is not None and self.system.transmissions % blocks:
            raise ValueError(
                f"codebook.blocks {blocks} does not divide system.transmissions"
                f" {self.system.transmissions}"
            )
        sizing_counts = [] if self.sizing is None else list(self.sizing.counts or [])
        for c in self.max_counts + sizing_counts:
            if c + 1 > self.system.transmissions:
                raise ValueError(
                    f"ris_count {c} needs at least L+1 = {c + 1} transmissions (G ="
                    f" {self.system.transmissions})"
                )
        return self

    def sizing_ris_sizes(self) -> set[tuple[int, int]]:
        """The RIS sizes (rows, cols) the sizing question compares: the document's own and
        ``sizing.ris_sizes`` (the own size alone without ``sizing``)."""
        extra = self.sizing.ris_sizes if self.sizing is not None else []
        return {(self.ris.rows, self.ris.cols)} | {(int(r), int(c)) for r, c in extra}

    def sizing_target(self) -> Target:
        """The target of the sizing question: ``sizing.target``, else ``objective.target``,
        else coverage ≥ :data:`SIZING_COVERAGE_TARGET` (a ValueError naming ``sizing.target``
        for a mean_capped or quantile objective without one)."""
        obj = self.objective
        spec = objective_kind(obj.kind)
        given = None if self.sizing is None else self.sizing.target
        if given is not None:
            if spec.higher_is_better:
                if spec.max_value is not None and given.objective > spec.max_value:
                    raise ValueError(
                        f"sizing.target.objective {given.objective} is a {obj.kind}"
                        f" ≤ {spec.max_value:g}"
                    )
                return Target(min=given.objective)
            return Target(max=given.objective)
        if obj.target is not None:
            return obj.target
        if spec.higher_is_better and spec.max_value == 1.0:  # a fraction: coverage
            return Target(min=SIZING_COVERAGE_TARGET)
        raise ValueError(
            f"sizing.target: a {obj.kind} objective without objective.target needs"
            " sizing.target {'objective': bound in metres}"
        )

    @property
    def target_mode(self) -> bool:
        """Whether the plan stops at the smallest count meeting the target (``mode``; default:
        target when ``ris_count`` is omitted)."""
        return self.mode == "target" or (self.mode is None and self.ris_count is None)

    @property
    def max_counts(self) -> list[int]:
        """Every RIS count the plan may search: the listed ``ris_count``, else 1 … ``max_ris``
        (target mode stops at the first count that meets the target)."""
        if self.ris_count is not None:
            return list(self.ris_count)
        return list(range(1, self.max_ris + 1))

    def sizing_counts(self) -> list[int]:
        """The RIS counts the sizing question tries at each size: ``sizing.counts``, else the
        document's ``ris_count``, else 1 … ``max_ris`` (stopping at the first that reaches the
        target)."""
        if self.sizing is not None and self.sizing.counts is not None:
            return list(self.sizing.counts)
        return self.max_counts

    def facade_prisms(self) -> list[list[tuple[int, Prism]]]:
        """Per entry of ``facades``: (obstacle index, prism) of each name in ``of``; raises a
        ValueError naming the entry and the name when it is missing, ambiguous or a wall."""
        obstacles = [] if self.environment is None else self.environment.obstacles
        out = []
        for i, fac in enumerate(self.facades):
            found = []
            for name in fac.of:
                hits = [k for k, ob in enumerate(obstacles) if ob.name == name]
                if not hits:
                    known = [ob.name for ob in obstacles if isinstance(ob, Prism) and ob.name]
                    raise ValueError(
                        f"facades[{i}].of: no obstacle named {name!r} in environment.obstacles"
                        f" (named prisms: {', '.join(map(repr, known)) or 'none'})"
                    )
                if len(hits) > 1:
                    raise ValueError(
                        f"facades[{i}].of: the name {name!r} is used by obstacles {hits};"
                        " facades need unique names"
                    )
                ob = obstacles[hits[0]]
                if not isinstance(ob, Prism):
                    raise ValueError(
                        f"facades[{i}].of: obstacle {name!r} is a {ob.kind}; facades are"
                        " generated on prisms"
                    )
                found.append((hits[0], ob))
            out.append(found)
        return out


class LayoutBeamsDocument(DocumentModel):
    """A power-allocation request for a given layout and UE probability maps (instead of one
    scenario with a Gaussian prior): beams designed from the maps, uniform power, the best γ_P
    and the SDP, each re-evaluated on the maps' pairs with ``objective``
    (:func:`ris_planner.planning.beams.run_layout_beams`)."""

    description: str | None = Field(None, max_length=2000, description="Free text")
    system: SystemParams = Field(
        default_factory=SystemParams, description="Radio parameters (Table I defaults)"
    )
    ris: list[RIS] = Field(min_length=1, max_length=64, description="The layout's RISs")
    environment: Environment | None = Field(
        None, description="Obstacles (prisms, walls) that block legs; absent = free space"
    )
    tx_map: UEMap = Field(description="TX probability map (positions [m], relative weights)")
    rx_map: UEMap = Field(description="RX probability map (positions [m], relative weights)")
    pairs: PairsSpec = Field("all", description="As in the plan document")
    max_pairs: int = Field(
        DEFAULT_MAX_PAIRS, ge=1, le=MAX_PAIRS_LIMIT, description="Limit on evaluated pairs"
    )
    objective: Objective = Field(description="The objective the designs are compared on")
    known: list[KnownPart] = Field(
        default_factory=list, description="Known state parts: clock, height, tx"
    )
    beams: BeamsSpec = Field(
        default_factory=BeamsSpec, description="Design positions, seeds, solver"
    )

    @field_validator("known")
    @classmethod
    def _unique_known(cls, v: list[str]) -> list[str]:
        return Scenario._unique_known(v)

    @model_validator(mode="after")
    def _check_document(self) -> LayoutBeamsDocument:
        if "tx" in self.known and self.objective.metric != "rx":
            raise ValueError(
                f"objective metric {self.objective.metric!r} needs PEB_T, but 'tx' is known"
            )
        if self.pairs == "unordered" and self.tx_map != self.rx_map:
            raise ValueError("pairs 'unordered' needs tx_map and rx_map to be the same map")
        check_pair_indices(self.pairs, self.tx_map, self.rx_map)
        if self.beams.layouts:
            raise ValueError("beams.layouts is for plan documents; here 'ris' is the layout")
        if len(self.ris) + 1 > self.system.transmissions:
            raise ValueError(
                f"{len(self.ris)} RISs need at least L+1 = {len(self.ris) + 1} transmissions"
            )
        return self


def _road_points(road: Road) -> int:
    """Lattice points of one road, as :func:`ris_planner.planning.inputs.ue_maps.road_points`
    samples."""
    lateral = 2 * count(road.width_m / 2 / road.step_m + 1e-9) + 1
    total, any_segment = 0, False
    for a, b in zip(road.points, road.points[1:], strict=False):
        length = math.hypot(b[0] - a[0], b[1] - a[1])
        if length == 0:
            continue
        any_segment = True
        total += count(math.ceil(length / road.step_m - 1e-9)) * lateral
    return total + (lateral if any_segment else 1)


def map_points(spec: UEMap) -> int:
    """Points of a UE map before any is built (zero-weight points included)."""
    n = 0
    if spec.grid is not None:
        g = spec.grid
        n += range_count(g.x, "x") * range_count(g.y, "y") * range_count(g.z, "z")
    n += len(spec.points or [])
    n += sum(_road_points(r) for r in spec.roads or [])
    if spec.csv_text is not None:
        n += csv_rows(spec.csv_text)
    return n


def check_pair_indices(spec: PairsSpec, tx_map: UEMap, rx_map: UEMap) -> None:
    """Explicit pairs by map index: every index below its map's point count
    (:func:`map_points`, before the map is built; the built map's own count is checked when
    the pairs are built)."""
    if not isinstance(spec, PairList) or not spec.by_index:
        return
    for name, idx, m in (("tx_index", spec.tx_index, tx_map), ("rx_index", spec.rx_index, rx_map)):
        n, top = map_points(m), max(idx or [0])
        if top >= n:
            raise ValueError(f"pairs.{name}: index {top} is beyond the map's {n} points")


def physics_json(doc: PlanDocument) -> dict[str, Any]:
    """plan.json ``physics``: the element pattern exponent and field of view in force, where
    they come from (``from``: ``default`` when the document sets neither, else ``document``;
    ``set_in_document`` lists the fields it sets, a value equal to the default included),
    their ``source`` and the ``wavefront`` model (``system.wavefront``)."""
    ris = doc.ris
    given = [f for f in PHYSICS_FIELDS if f in ris.model_fields_set]
    if not given:
        source = PLAN_PHYSICS_SOURCE
    elif ris.pattern_exponent == 0.0 and ris.max_angle_deg == 90.0:
        source = ISOTROPIC_SOURCE
    elif len(given) == len(PHYSICS_FIELDS):
        source = "document"
    else:
        source = f"document ({', '.join(given)}); otherwise {PLAN_PHYSICS_SOURCE}"
    return {
        "pattern_exponent": ris.pattern_exponent,
        "max_angle_deg": ris.max_angle_deg,
        "from": "document" if given else "default",
        "set_in_document": given,
        "source": source,
        "wavefront": doc.system.wavefront,
    }
