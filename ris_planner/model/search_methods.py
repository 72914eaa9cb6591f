"""Search methods – part of the plan document's contract: each ``search.method`` name, what it
takes and what it honours (docs/concepts/planning.md, "Search methods").

A method is a :class:`SearchMethod` registered under its JSON name (:func:`register`), with
its :class:`Capabilities`: the objectives, pair models and wavefronts it plans, the most RISs
in a layout, the document options (:data:`PLAN_OPTIONS`: beams, validation, roll-out, sweep,
sizing, cost budget …) and the ``search`` fields it reads. Every other module reaches a method
through :func:`search_method` instead of testing its name, and a document that asks a method
for what it cannot honour is refused before any work by :func:`method_refusals`, naming the
method, the option and the command-line flag that set it – never planned with the option
silently ignored. The planning engine binds each name to the code that runs it
(:mod:`ris_planner.planning.methods`); ``auto`` is not a method but the rule that picks one
(:func:`ris_planner.planning.resources.admission.resolve_search`, whose reason plan.json
keeps), and within the enumerating search the per-count rule of :func:`count_method`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal

from ris_planner.model.objectives import objective_kind

PlanDocument = Any
"""A validated :class:`ris_planner.model.plan.PlanDocument` (named here, not imported: the plan
document's model validates ``search.method`` against this registry)."""

MAX_LAYOUT_RIS = 16
"""The most RISs in a layout of the exhaustive and greedy searches."""

MAX_DISTRICT_RIS = 200
"""The most RISs in a layout of the district search."""

AUTO = "auto"
"""``search.method`` that lets the planner choose (:func:`count_method` per RIS count, and the
district search where the enumerating ones cannot take the document)."""

Scoring = Literal["site_cache", "sparse"]
"""How a method holds the information: a dense per-site cache over every pair (the enumerating
searches) or sparse (pair, serving site) entries (the district search)."""


@dataclass(frozen=True)
class PlanOption:
    """A document option a search method may or may not honour."""

    name: str
    """Short name (the capability table's column)."""
    field: str
    """The document field that sets it (dotted path: the 422's ``fields`` entry)."""
    flag: str | None
    """The ``ris-planner plan`` flag that sets it, if any."""
    what: str
    """What it asks for, in words (the refusal's message)."""
    used: Callable[[PlanDocument], bool]
    """Whether a document asks for it."""


PLAN_OPTIONS: tuple[PlanOption, ...] = (
    PlanOption(
        "beams",
        "beams",
        "--beams",
        "beam designs and the power allocation of each recommended layout",
        lambda d: d.beams is not None,
    ),
    PlanOption(
        "validation",
        "validation",
        "--validate",
        "the two-stage estimator on each recommended layout",
        lambda d: d.validation is not None,
    ),
    PlanOption(
        "nested",
        "rollout",
        "--nested",
        "a phased roll-out (each count's layout contains the previous count's)",
        lambda d: d.rollout == "nested",
    ),
    PlanOption("sweep", "sweep", None, "a parameter sweep", lambda d: d.sweep is not None),
    PlanOption(
        "sizing",
        "sizing",
        "--sizing",
        "the sizing question (the smallest RIS size × count)",
        lambda d: d.sizing is not None,
    ),
    PlanOption(
        "budget",
        "constraints.budget",
        None,
        "a cost budget on each layout",
        lambda d: d.constraints.budget is not None,
    ),
    PlanOption(
        "heatmap_tx",
        "heatmap_tx",
        None,
        "per-point bounds against one fixed TX position",
        lambda d: d.heatmap_tx is not None,
    ),
)
"""Every option of :class:`Capabilities.options`, in the capability table's order."""

ENUMERATING_FIELDS = frozenset(
    {
        "max_exhaustive",
        "top_k",
        "seed",
        "restarts",
        "max_rounds",
        "tie_rtol",
        "pool_min_work",
        "certificate_iterations",
    }
)
"""``search`` fields the enumerating searches read (``auto`` picks exhaustive or greedy per RIS
count from ``max_exhaustive``: each reads all of them)."""


@dataclass(frozen=True)
class Capabilities:
    """What a search method plans and honours."""

    objectives: Literal["any", "coverage"]
    """``any`` registered objective kind, or ``coverage`` objectives only (a higher-is-better
    fraction of pairs within a level: the kind has a screen level)."""
    pair_models: frozenset[str]
    """Pair models it takes: ``all``, ``unordered``, ``sample``, ``explicit``."""
    wavefronts: frozenset[str]
    """``system.wavefront`` values it takes."""
    codebooks: frozenset[str]
    """``codebook.kind`` values it scores layouts with."""
    options: frozenset[str]
    """Names of :data:`PLAN_OPTIONS` it honours."""
    search_fields: frozenset[str]
    """``search`` fields it reads (another given explicitly is refused)."""
    max_ris: int
    """The most RISs in a layout."""
    scoring: Scoring
    """How it holds the information (its memory and time estimates follow)."""
    unread: frozenset[str] = frozenset()
    """Dotted paths of other document fields it does not read (refused when given
    explicitly), e.g. ``beams.random_seeds``."""

    def to_json(self) -> dict[str, Any]:
        return {
            "objectives": self.objectives,
            "pair_models": sorted(self.pair_models),
            "wavefronts": sorted(self.wavefronts),
            "codebooks": sorted(self.codebooks),
            "options": [o.name for o in PLAN_OPTIONS if o.name in self.options],
            "search_fields": sorted(self.search_fields),
            "unread": sorted(self.unread),
            "max_ris": self.max_ris,
            "scoring": self.scoring,
        }


@dataclass(frozen=True)
class SearchMethod:
    """A registered search method (:func:`register`)."""

    name: str
    label: str
    """Short human name (the web page's list)."""
    description: str
    """One sentence: what it does and when to use it."""
    capabilities: Capabilities
    docs: str = field(default="docs/concepts/planning.md")
    """The documentation page that explains it."""

    def to_json(self) -> dict[str, Any]:
        """``GET /v1/search-methods`` entry."""
        return {
            "name": self.name,
            "label": self.label,
            "description": self.description,
            "capabilities": self.capabilities.to_json(),
            "docs": self.docs,
        }


_REGISTRY: dict[str, SearchMethod] = {}


def register(method: SearchMethod) -> SearchMethod:
    """Register a search method under ``method.name`` (once; ``auto`` is reserved)."""
    if method.name == AUTO:
        raise ValueError(f"{AUTO!r} is the planner's choice, not a method")
    old = _REGISTRY.get(method.name)
    if old is not None and old != method:
        raise ValueError(f"search method {method.name!r} is already registered")
    _REGISTRY[method.name] = method
    return method


def unregister(name: str) -> None:
    """Remove a registered method (tests that add a toy method)."""
    _REGISTRY.pop(name, None)


def method_names() -> tuple[str, ...]:
    """``auto`` and the registered methods' names, in registration order (the schema's enum)."""
    return (AUTO, *_REGISTRY)


def search_method(name: str) -> SearchMethod:
    """The registered method called ``name``; a ValueError naming the known ones otherwise."""
    try:
        return _REGISTRY[name]
    except KeyError:
        known = ", ".join(repr(n) for n in method_names())
        raise ValueError(f"unknown search method {name!r}; known: {known}") from None


def registered_methods() -> tuple[SearchMethod, ...]:
    return tuple(_REGISTRY.values())


def count_method(method: str, layouts: int, max_exhaustive: int) -> str:
    """The search one RIS count runs under an enumerating ``method``: ``auto`` is exhaustive
    when the count's (feasible) layouts are at most ``max_exhaustive``, else greedy – the one
    copy of that rule (the search, the preview, the estimates read it)."""
    if method != AUTO:
        return method
    return "exhaustive" if layouts <= max_exhaustive else "greedy"


def scoring_of(method: str) -> Scoring:
    """How the search ``method`` (``auto``: the enumerating rule) holds the information."""
    return "site_cache" if method == AUTO else search_method(method).capabilities.scoring


def sparse_search(doc: PlanDocument) -> bool:
    """Whether the document's search holds sparse (pair, serving site) information (the
    district search): no site cache, no layout enumeration."""
    return scoring_of(doc.search.method) == "sparse"


def pair_model(doc: PlanDocument) -> str:
    """The document's pair model: ``all``, ``unordered``, ``sample`` or ``explicit``."""
    return pair_model_of(doc.pairs)


def pair_model_of(spec: Any) -> str:
    """The pair model of a ``pairs`` value (:data:`ris_planner.model.plan.PairsSpec`): its name
    (``all``, ``unordered``), ``sample`` for a sample, ``explicit`` for a list of pairs."""
    if isinstance(spec, str):
        return spec
    return "sample" if hasattr(spec, "sample") else "explicit"


def plans_objective(method: SearchMethod, doc: PlanDocument) -> bool:
    """Whether ``method`` plans the document's objective kind."""
    if method.capabilities.objectives == "any":
        return True
    kind = objective_kind(doc.objective.kind)
    return kind.higher_is_better and kind.screen_level(doc.objective) is not None


def method_refusals(method: SearchMethod, doc: PlanDocument) -> list[tuple[str, str]]:
    """(field, message) for everything ``doc`` asks that ``method`` cannot plan or honour:
    its objective, pair model, wavefront, RIS counts, options and explicit ``search`` fields;
    empty when it can plan the document as written."""
    cap = method.capabilities
    who = f"search method {method.name!r}"
    out: list[tuple[str, str]] = []
    if not plans_objective(method, doc):
        out.append(
            (
                "objective.kind",
                f"{who} plans coverage objectives (a fraction of pairs within a threshold),"
                f" not {doc.objective.kind!r}",
            )
        )
    model = pair_model(doc)
    if model not in cap.pair_models:
        out.append(
            (
                "pairs",
                f"{who} takes the pair models {', '.join(sorted(cap.pair_models))}, not {model!r}",
            )
        )
    wave = doc.system.wavefront
    if wave not in cap.wavefronts:
        out.append(("system.wavefront", f"{who} does not take the {wave!r} wavefront"))
    kind = doc.codebook.kind
    if kind not in cap.codebooks:
        out.append(
            (
                "codebook.kind",
                f"{who} scores layouts with the codebooks {', '.join(sorted(cap.codebooks))},"
                f" not {kind!r} (designed per-site codebooks: search.method 'district'; beams"
                " for the recommended layouts: beams / --beams)",
            )
        )
    largest = max(doc.max_counts)
    if largest > cap.max_ris:
        out.append(("ris_count", f"{who} places at most {cap.max_ris} RISs, not {largest}"))
    for opt in PLAN_OPTIONS:
        if opt.name not in cap.options and opt.used(doc):
            flag = f" ({opt.flag})" if opt.flag else ""
            out.append((opt.field, f"{who} does not give {opt.what}{flag}"))
    given = doc.search.model_fields_set - {"method"}
    for name in sorted(given - cap.search_fields):
        out.append((f"search.{name}", f"{who} does not read search.{name}"))
    for path in sorted(cap.unread):
        if _given(doc, path):
            out.append((path, f"{who} does not read {path}"))
    return out


def _given(doc: Any, path: str) -> bool:
    """Whether the dotted field ``path`` is set explicitly in the document."""
    *parents, name = path.split(".")
    node = doc
    for part in parents:
        node = getattr(node, part, None)
        if node is None:
            return False
    return name in getattr(node, "model_fields_set", set())


ENUMERATING = Capabilities(
    objectives="any",
    pair_models=frozenset({"all", "unordered", "sample", "explicit"}),
    wavefronts=frozenset({"planar", "spherical"}),
    codebooks=frozenset({"expected_random"}),
    options=frozenset(o.name for o in PLAN_OPTIONS),
    search_fields=ENUMERATING_FIELDS,
    max_ris=MAX_LAYOUT_RIS,
    scoring="site_cache",
)
"""The enumerating searches' capabilities (exhaustive and greedy: every option)."""


def _builtin() -> None:
    register(
        SearchMethod(
            "exhaustive",
            "exhaustive",
            "every layout of each RIS count scored: the optimum, exactly (up to"
            " search.max_exhaustive layouts)",
            ENUMERATING,
        )
    )
    register(
        SearchMethod(
            "greedy",
            "greedy",
            "forward selection with swaps and random restarts, certified by a relaxation"
            " bound (and branch-and-bound under auto)",
            ENUMERATING,
        )
    )
    register(
        SearchMethod(
            "district",
            "district (many RISs)",
            "tens to hundreds of RISs from thousands of candidates by locality, each count"
            " with a certified coverage interval (coverage objectives)",
            Capabilities(
                objectives="coverage",
                pair_models=frozenset({"all", "sample", "explicit"}),
                wavefronts=frozenset({"planar", "spherical"}),
                codebooks=frozenset({"expected_random", "directional", "directional_derivative"}),
                options=frozenset({"sizing", "nested", "validation", "beams"}),
                search_fields=frozenset(),
                unread=frozenset({"beams.random_seeds"}),
                max_ris=MAX_DISTRICT_RIS,
                scoring="sparse",
            ),
            docs="docs/concepts/district.md",
        )
    )


_builtin()


@dataclass(frozen=True)
class MethodChoice:
    """The search a plan runs and why (plan.json ``search_method``): ``requested`` as the
    document says, ``used`` after ``auto`` is resolved (a registered method, or ``auto`` when
    the enumerating rule picks exhaustive or greedy per count: :func:`count_method`)."""

    requested: str
    used: str
    why: str

    def to_json(self) -> dict[str, str]:
        return {"requested": self.requested, "used": self.used, "why": self.why}
