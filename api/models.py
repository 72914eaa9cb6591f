"""Response models of the service (OpenAPI documentation; request bodies are the engine's own
pydantic documents: :class:`ris_planner.model.scenario.Scenario` and friends)."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from api.store import FaultKind, Job, JobHead, JobStatus
from ris_planner.model.scenario import KnownPart, preset_document

Bound = float | None


def scenario_examples() -> dict[str, Any]:
    """OpenAPI examples of a scenario body: Table I (one pair) and a two-pair batch."""
    batch = preset_document("2-ris-L") | {
        "tx": [[-2.0, -4.0, 0.0], [0.0, 0.0, 0.0]],
        "rx": [[2.0, 3.0, 0.0], [1.0, 1.0, 0.5]],
    }
    return {
        "table1": {"summary": "Table I (one TX–RX pair)", "value": preset_document("paper-table1")},
        "batch": {"summary": "Two pairs, RISs tilted 30° down", "value": batch},
    }


def power_examples() -> dict[str, Any]:
    """OpenAPI example of a power-allocation body: Table I with a small DIR+DER codebook."""
    doc = preset_document("paper-table1")
    doc["codebook"] = {
        "kind": "directional_derivative",
        "prior": {"sigma_m": 0.1, "samples": 4, "seed": 0},
    }
    layout = {
        "system": {"tx_power_dbm": 30},
        "ris": preset_document("paper-table1")["ris"],
        "tx_map": {"grid": {"x": [-2.2, -1.8, 0.2], "y": [-4.2, -3.8, 0.2], "z": [0, 0, 1]}},
        "rx_map": {"grid": {"x": [1.8, 2.2, 0.2], "y": [2.8, 3.2, 0.2], "z": [0, 0, 1]}},
        "objective": {"kind": "mean_capped", "cap_m": 1.0},
        "beams": {"design_positions": 16},
    }
    return {
        "dir_der": {"summary": "Table I, DIR+DER codebook from a 0.1 m prior", "value": doc},
        "layout_maps": {
            "summary": "Table I's RISs, beams designed from two UE maps",
            "value": layout,
        },
    }


def plan_examples() -> dict[str, Any]:
    """OpenAPI example of a plan body: the Fig. 10 anchor sites (2–4 RISs)."""
    from ris_planner.planning import plan_preset

    return {"fig10": {"summary": "Fig. 10 anchor sites", "value": plan_preset("fig10-anchors")}}


def site_geojson() -> dict[str, Any]:
    """A small site as GeoJSON (WGS84): one building with a height and one residential street,
    in central Helsinki – the example body of the import and of the candidate-site generator."""
    return {
        "type": "FeatureCollection",
        "features": [
            {
                "type": "Feature",
                "properties": {"building": "yes", "height": 12, "name": "Talo"},
                "geometry": {
                    "type": "Polygon",
                    "coordinates": [
                        [
                            [24.9380, 60.1700],
                            [24.9383, 60.1700],
                            [24.9383, 60.17015],
                            [24.9380, 60.17015],
                            [24.9380, 60.1700],
                        ]
                    ],
                },
            },
            {
                "type": "Feature",
                "properties": {"highway": "residential", "name": "Katu"},
                "geometry": {
                    "type": "LineString",
                    "coordinates": [[24.9376, 60.16985], [24.9388, 60.16985]],
                },
            },
        ],
    }


SITE_OSM_XML = """<?xml version="1.0"?>
<osm version="0.6">
  <node id="1" lon="24.9380" lat="60.1700"/><node id="2" lon="24.9382" lat="60.1700"/>
  <node id="3" lon="24.9382" lat="60.1701"/><node id="4" lon="24.9380" lat="60.1701"/>
  <node id="5" lon="24.9375" lat="60.1698"/><node id="6" lon="24.9390" lat="60.1698"/>
  <way id="10"><nd ref="1"/><nd ref="2"/><nd ref="3"/><nd ref="4"/><nd ref="1"/>
    <tag k="building" v="yes"/><tag k="building:levels" v="4"/></way>
  <way id="11"><nd ref="5"/><nd ref="6"/><tag k="highway" v="residential"/></way>
</osm>
"""
"""The same kind of site as OSM XML: a four-storey building and a residential street."""


class ChannelBounds(BaseModel):
    """Channel-parameter bounds of one path (eqs. DEB, SEB1, SEB2)."""

    path: str = Field(description="'los' or 'ris1', 'ris2', … in the document's RIS order")
    deb_m: Bound | list[Bound] = Field(
        description="Delay error bound c·sqrt(CRB_τ) [m], ≥ 0; null = infinite"
    )
    seb_xi: Bound | list[Bound] | None = Field(
        None, description="Spatial-frequency error bound on ξ (unitless, ≥ 0); RIS paths only"
    )
    seb_zeta: Bound | list[Bound] | None = Field(
        None, description="Spatial-frequency error bound on ζ (unitless, ≥ 0); RIS paths only"
    )


class Provenance(BaseModel):
    """Which package version computed a result, from which input
    (ris_planner.runtime.provenance)."""

    package: Literal["ris_planner"] = Field(description="The package name")
    version: str = Field(description="Its version")
    input_sha256: str = Field(
        pattern="^[0-9a-f]{64}$",
        description="SHA-256 of the validated input document as canonical JSON (sorted keys,"
        " compact separators, defaults filled in)",
    )


class BoundsResponse(BaseModel):
    """The answer of ``POST /v1/bounds`` (the same document as ``ris-planner bounds``).

    For a single pair every per-pair value is a scalar; for a batch (``tx``/``rx`` given as lists
    of points) it is a list in pair order.
    """

    peb_tx_m: Bound | list[Bound] = Field(
        description="PEB_T = sqrt(tr CRB[p_T]) [m], ≥ 0 (over x, y with 'height' known); null ="
        " infinite (blind spot, see reason) or TX known"
    )
    peb_rx_m: Bound | list[Bound] = Field(
        description="PEB_R = sqrt(tr CRB[p_R]) [m], ≥ 0; null = infinite (see reason)"
    )
    ceb_m: Bound | list[Bound] = Field(
        description="CEB = sqrt(CRB[B, B]) [m], ≥ 0; null = infinite or clock known"
    )
    reason: str | list[str | None] | None = Field(
        description="Why the bounds of a pair are infinite (singular FIM; 'underdetermined…'"
        " naming the missing paths), else null"
    )
    channel: list[ChannelBounds] = Field(
        description="Per-path DEB/SEB, LOS first; null for a path missing for the pair"
    )
    paths_present: dict[str, bool] | dict[str, list[bool]] = Field(
        description="Per path ('los', 'ris1', …) whether it exists for the pair: LOS iff"
        " system.los and the TX–RX leg is clear; a RIS path iff both legs are clear and both"
        " UEs are in its field of view (max_angle_deg; no leg is blocked without environment)"
    )
    far_field: bool | list[bool] = Field(
        description="Whether every RIS is in the far field of the pair (footnote 3)"
    )
    far_field_ris: list[bool] | list[list[bool]] = Field(
        description="Per RIS: d_T·d_R/(d_T + d_R) ≥ 2D²/λ (D = aperture diagonal)"
    )
    known: list[KnownPart] = Field(description="State parts treated as known")
    peb_tx_reason: str | None = Field(None, description="Why peb_tx_m is null (TX known)")
    ceb_reason: str | None = Field(None, description="Why ceb_m is null (clock known)")
    channel_reason: str | None = Field(
        None, description="Why the channel bounds are null (defined for the planar model only)"
    )
    warnings: list[str] = Field(
        default_factory=list,
        description="Modelling assumptions that may mislead: expected-random optimism at small"
        " G/Γ, element spacing above λ/2 (grating lobes), far-field pairs a minority (advice:"
        " system.wavefront = 'spherical')",
    )
    provenance: Provenance = Field(description="Package version and hash of the input")


class ResourceEstimate(BaseModel):
    """A plan's resources estimated from its document before any work
    (:func:`ris_planner.planning.resources.time_estimate.plan_estimate`;
    docs/validation/resources.md)."""

    time_s: float = Field(ge=0, description="Estimated wall time of the run [s]")
    memory_mib: float = Field(ge=0, description="Estimated peak resident memory [MiB]")
    budget_mib: int = Field(ge=0, description="The job memory budget it was checked against [MiB]")


class JobSummary(BaseModel):
    """A job without its result (listings)."""

    id: str = Field(description="Job id (32 hex digits)")
    kind: str = Field(description="Job kind: 'plan' or 'power'")
    status: JobStatus = Field(
        description="queued → running → succeeded | failed; queued/running → cancelled"
    )
    progress: float = Field(ge=0, le=1, description="Fraction done, 0–1 (1 when succeeded)")
    message: str = Field(description="Last progress message")
    error: str | None = Field(description="Why the job failed (failed jobs only)")
    created_at: str = Field(description="Submission time, ISO 8601 UTC")
    started_at: str | None = Field(description="Start time in a worker, ISO 8601 UTC")
    finished_at: str | None = Field(description="End time (any end state), ISO 8601 UTC")
    url: str = Field(description="Path of this job's resource")
    estimate: ResourceEstimate | None = Field(
        None,
        description="A plan job's resources estimated from its document at submission, before"
        " any work (the result's 'resources' sets it beside what the run measured); null for"
        " other kinds",
    )

    @classmethod
    def of_head(cls, job: JobHead) -> JobSummary:
        return cls(**_summary_fields(job))


class JobView(JobSummary):
    """A job with its request, result and figure links."""

    request: dict[str, Any] = Field(description="The validated request document")
    result: dict[str, Any] | None = Field(
        description="The result document (succeeded jobs only); same as the CLI's JSON output"
    )
    figures: dict[str, str] = Field(
        description="Figure name → path of the PNG (GET it); succeeded jobs with figures only"
    )

    @classmethod
    def of(cls, job: Job) -> JobView:
        return cls(
            **_summary_fields(job),
            request=job.request,
            result=job.result,
            figures={name: f"/v1/jobs/{job.id}/figures/{name}" for name in job.figures},
        )


def _summary_fields(job: JobHead) -> dict[str, Any]:
    return {
        "id": job.id,
        "kind": job.kind,
        "status": job.status,
        "progress": job.progress,
        "message": job.message,
        "error": job.error,
        "created_at": job.created_at,
        "started_at": job.started_at,
        "finished_at": job.finished_at,
        "url": f"/v1/jobs/{job.id}",
        "estimate": job.estimate_json,
    }


class JobPage(BaseModel):
    """One page of jobs, newest first."""

    items: list[JobSummary] = Field(description="The jobs of this page")
    total: int = Field(ge=0, description="Jobs matching the filters, all pages")
    limit: int = Field(ge=1, description="Page size asked for")
    offset: int = Field(ge=0, description="Index of the first item of this page")
    next_offset: int | None = Field(description="Offset of the next page; null on the last page")


class Preset(BaseModel):
    """A shipped document."""

    name: str = Field(description="Preset name (also accepted by the CLI's --preset)")
    document: dict[str, Any] = Field(description="The full JSON document")


class ObjectiveInfo(BaseModel):
    """A registered objective kind (``objective.kind`` of a plan document)."""

    name: str = Field(description="The kind's JSON name")
    label: str = Field(description="Short human name")
    parameter: str | None = Field(description="The objective field it needs (e.g. threshold_m)")
    parameter_label: str = Field(description="The parameter's label with its unit")
    higher_is_better: bool = Field(description="Direction of the objective")
    unit: str = Field(description="Unit of the objective's value ('' for a fraction)")


class ObjectiveList(BaseModel):
    """The objective kinds this service plans with."""

    objectives: list[ObjectiveInfo] = Field(description="Registered kinds, in order")


class PresetList(BaseModel):
    """Shipped presets by document type."""

    model_config = ConfigDict(extra="forbid")

    scenarios: list[Preset] = Field(description="Scenario documents (POST /v1/bounds)")
    plans: list[Preset] = Field(description="Plan documents (POST /v1/plans)")


class Health(BaseModel):
    """Liveness and queue state."""

    status: Literal["ok", "degraded", "unavailable"] = Field(
        description="ok; degraded: a fault now, the service still answers (see reason), e.g. a"
        " write lock the store is retrying; unavailable (503): the job database does not"
        " answer or takes no writes (read-only, full, corrupt). Back to ok as soon as the"
        " fault is over"
    )
    reason: str | None = Field(None, description="Why the service is degraded or unavailable")
    fault: FaultKind | None = Field(
        None,
        description="The class of the job database's fault now: locked, read-only, full,"
        " corrupt, io, missing, gone (removed or replaced), error; null when none",
    )
    last_fault: str | None = Field(
        None, description="The last fault within 5 minutes, also after recovery (for the record)"
    )
    version: str = Field(description="Package version")
    workers: int = Field(ge=1, description="Configured job worker processes")
    running: int = Field(ge=0, description="Worker processes running a job now")
    jobs: dict[str, int] = Field(description="Number of jobs per status")
