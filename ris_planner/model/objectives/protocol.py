"""The objective protocol and its registry (docs/concepts/scoring.md, "Objectives").

An objective kind is one class deriving from :class:`ObjectiveKind`, registered under its JSON
name with :func:`register`. Every other module of the planner reaches it through
:func:`objective_kind` (the plan document's ``objective.kind``) instead of testing the name:

* :meth:`ObjectiveKind.value` – the objective of per-pair metric bounds [B, P] (metres; ``inf``
  for a blind pair) under the pair weights [P] (summing to 1), and its direction
  (:attr:`ObjectiveKind.higher_is_better`); the search minimises :meth:`ObjectiveKind.loss`;
* :meth:`ObjectiveKind.relaxation_loss` – a lower bound on the best loss from per-pair lower
  bounds of the metric (the certificates' Frank–Wolfe relaxation and branch-and-bound,
  docs/concepts/decisions.md), valid for objectives monotone in every pair's metric, and
  :meth:`ObjectiveKind.settle_limits`, where a pair's bound stops moving it;
* :meth:`ObjectiveKind.reference_level` – the bound a pair must reach to count (threshold or cap)
  and :meth:`ObjectiveKind.screen_level`, the level of the scorer's coverage screen (a pair
  proven above it is settled without its full bound; ``None``: no screen);
* :meth:`ObjectiveKind.check_level` – the bound a pair must reach to count as covered in the
  estimator check (``validation``; ``None``: the document gives ``validation.threshold_m``);
* :attr:`ObjectiveKind.better` and :attr:`ObjectiveKind.bound_side` – the direction words of
  plan.json (``objective_better``, a certificate's ``bound_side``);
* :meth:`ObjectiveKind.search_tiebreak` – how the search orders layouts whose losses are all
  infinite (default: more pairs with a finite bound first).

The document's parameters (``threshold_m``, ``cap_m``, ``q``, ``target``) are read from the
validated :class:`ris_planner.model.plan.Objective` passed as ``spec``; a kind may also name a
parameter of its own (:attr:`ObjectiveKind.parameter`), which the ``objective`` block then
accepts and :meth:`ObjectiveKind.parameter_value` reads (checked by
:meth:`ObjectiveKind.check_parameter`).
"""

from __future__ import annotations

from typing import Any, ClassVar, Protocol

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


class Objective(Protocol):
    """What a kind reads from the document's ``objective`` block
    (:class:`ris_planner.model.plan.Objective` satisfies it)."""

    @property
    def kind(self) -> str: ...
    @property
    def metric(self) -> str: ...
    @property
    def threshold_m(self) -> float | None: ...
    @property
    def cap_m(self) -> float | None: ...
    @property
    def q(self) -> float | None: ...
    @property
    def target(self) -> Any: ...


class ObjectiveKind:
    """One objective kind. Subclasses set the class attributes and implement :meth:`value`;
    the other methods have defaults that hold for objectives monotone in every pair's bound."""

    name: ClassVar[str]
    """JSON name (``objective.kind``)."""
    label: ClassVar[str]
    """Short human name (the web page's list)."""
    parameter: ClassVar[str | None] = None
    """The document field the objective needs (``threshold_m``, ``cap_m``, ``q``), or None."""
    parameter_label: ClassVar[str] = ""
    """The parameter's human label with its unit (the web page's form)."""
    higher_is_better: ClassVar[bool] = False
    """Direction: True when a larger value is better (the loss is then the negated value)."""
    unit: ClassVar[str] = "m"
    """Unit of the value (``""`` for a fraction)."""
    max_value: ClassVar[float | None] = None
    """Largest value the objective can take (a target above it is refused), or None."""
    share_of_servable: ClassVar[bool] = False
    """A target (``objective.target.min``, ``sizing.target``) is a share of the *servable*
    pairs – those some layout of the candidates can locate at all – rather than of every pair
    (coverage: a pair no RIS placement can serve does not count against a layout;
    docs/concepts/scoring.md, "One denominator")."""

    @property
    def better(self) -> str:
        """``"higher"`` or ``"lower"`` (plan.json's ``objective_better``)."""
        return "higher" if self.higher_is_better else "lower"

    @property
    def bound_side(self) -> str:
        """Which side of the best objective a certificate's ``objective_bound`` lies on:
        ``"upper"`` (no layout does better than it, higher is better) or ``"lower"``."""
        return "upper" if self.higher_is_better else "lower"

    def parameter_value(self, spec: Objective) -> float | None:
        """The document's value of :attr:`parameter` (None without one): a field of the
        ``objective`` block, a shipped one or the kind's own."""
        if self.parameter is None:
            return None
        value = getattr(spec, self.parameter, None)
        return None if value is None else float(value)

    def check_parameter(self, value: Any) -> float:
        """Validate the value of a parameter the kind names itself (one that is no field of
        :class:`ris_planner.model.plan.Objective`): default, a finite number > 0."""
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ValueError(f"{self.parameter} must be a number, got {value!r}")
        if not (np.isfinite(value) and value > 0):
            raise ValueError(f"{self.parameter} must be a finite number > 0, got {value!r}")
        return float(value)

    @property
    def unit_suffix(self) -> str:
        """`` [m]`` (the unit for an axis label), or ``""`` for a fraction."""
        return f" [{self.unit}]" if self.unit else ""

    def value(self, spec: Objective, metric: FloatArray, weights: FloatArray) -> FloatArray:
        """[B] objective of metric bounds [B, P] (m, ``inf`` blind) with weights [P] (sum 1)."""
        raise NotImplementedError

    def loss(self, spec: Objective, metric: FloatArray, weights: FloatArray) -> FloatArray:
        """[B] lower-is-better form of :meth:`value`."""
        val = self.value(spec, metric, weights)
        return -val if self.higher_is_better else val

    def from_loss(self, loss: float) -> float:
        """The objective's value from a loss of :meth:`loss` (the inverse map)."""
        return -loss if self.higher_is_better else loss

    def relaxation_loss(
        self, spec: Objective, lower: FloatArray, weights: FloatArray
    ) -> FloatArray:
        """[B] a lower bound on the loss of every layout whose per-pair metric is ≥ ``lower``
        [B, P]: the loss of the lower bounds themselves, valid because the objective is
        monotone in every pair's bound (override for one that is not)."""
        return self.loss(spec, lower, weights)

    def settle_limits(self, spec: Objective, safety: float) -> tuple[float, float]:
        """(lo, hi) on a pair's relaxed trace (PEB²) beyond which its bound no longer moves
        the objective of the bounds (a relaxed value ≤ lo, or a bound whose √·(1 − safety)
        exceeds √hi, is final); (−inf, inf): every value counts."""
        return -np.inf, np.inf

    def reference_level(self, spec: Objective) -> float:
        """The bound [m] a pair must reach to count as served (``inf``: any finite bound)."""
        target = spec.target
        if not self.higher_is_better and target is not None and target.max is not None:
            return float(target.max)
        return np.inf

    def screen_level(self, spec: Objective) -> float | None:
        """The bound [m] above which a pair's exact value no longer changes the loss (the
        scorer's coverage screen proves pairs above it and skips their full bound); None:
        every value counts, no screen."""
        return None

    def check_level(self, spec: Objective) -> float | None:
        """The bound [m] a pair must reach to count as covered in the estimator check
        (``validation``): default the screen level (the threshold or the cap); None: the
        objective has no such level and the document must give ``validation.threshold_m``."""
        return self.screen_level(spec)

    def level_label(self, spec: Objective) -> tuple[float | None, str]:
        """(the bound level drawn on the per-point maps, or None for the best layout's value
        itself; its label)."""
        level = self.screen_level(spec)
        return level, (f"{self.parameter} {level:g} m" if level is not None else self.name)

    def search_tiebreak(
        self, spec: Objective, metric: FloatArray, weights: FloatArray
    ) -> FloatArray:
        """[B] secondary loss ordering layouts whose losses are equal and infinite (the search
        never settles for such a layout while one with a finite loss, or more finite pairs, is
        in reach): minus the weight of the pairs with a finite bound."""
        return -np.asarray((np.isfinite(metric) * weights).sum(axis=1))

    def describe(self) -> dict[str, Any]:
        """The kind as the service lists it (``GET /v1/objectives``)."""
        return {
            "name": self.name,
            "label": self.label,
            "parameter": self.parameter,
            "parameter_label": self.parameter_label,
            "higher_is_better": self.higher_is_better,
            "unit": self.unit,
        }


_REGISTRY: dict[str, ObjectiveKind] = {}


def register(kind: ObjectiveKind) -> ObjectiveKind:
    """Register an objective kind under ``kind.name`` (a name may be registered once)."""
    if kind.name in _REGISTRY and type(_REGISTRY[kind.name]) is not type(kind):
        raise ValueError(f"objective kind {kind.name!r} is already registered")
    _REGISTRY[kind.name] = kind
    return kind


def unregister(name: str) -> None:
    """Remove a registered kind (tests that add a toy objective)."""
    _REGISTRY.pop(name, None)


def objective_names() -> tuple[str, ...]:
    """The registered kinds' names, in registration order."""
    return tuple(_REGISTRY)


def objective_kind(name: str) -> ObjectiveKind:
    """The registered kind called ``name``; a ValueError naming the known ones otherwise."""
    try:
        return _REGISTRY[name]
    except KeyError:
        known = ", ".join(repr(n) for n in _REGISTRY)
        raise ValueError(f"unknown objective kind {name!r}; known kinds: {known}") from None
