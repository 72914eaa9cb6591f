"""The simulation document (``ris-planner simulate``, docs/guides/estimation.md): a scenario with
one TX–RX pair, its multipath and the estimator's settings (:mod:`ris_planner.model.simulation`),
checked against the paths that exist in the scenario's environment (as the bounds see them)."""

from __future__ import annotations

from typing import Any

import numpy as np
from pydantic import Field, model_validator

from ris_planner.bounds.compute import scenario_path_presence
from ris_planner.core.document import DocumentModel
from ris_planner.model.scenario import MIN_UE_RIS_DISTANCE_M, Scenario, load_scenario
from ris_planner.model.simulation import (
    MIN_SCATTERER_DISTANCE_M,
    EstimatorSettings,
    Multipath,
    describe_scatterer,
    scatterer_too_close,
)


class SimulationDocument(DocumentModel):
    """What ``ris-planner simulate`` reads: scenario, multipath and estimator settings."""

    scenario: Scenario
    multipath: Multipath = Field(default_factory=Multipath)
    estimator: EstimatorSettings = Field(default_factory=EstimatorSettings)

    @model_validator(mode="after")
    def _check(self) -> SimulationDocument:
        sc = self.scenario
        if sc.is_batch and len(sc.tx_array) > 1:
            raise ValueError("scenario: the simulator takes one TX–RX pair, not a batch")
        if sc.known:
            raise ValueError(
                f"scenario.known = {sc.known}: the estimator estimates all of p_T, p_R, B;"
                " leave 'known' empty"
            )
        n_ris = len(sc.ris)
        los, n_used, note = self._present_paths()
        if not los and n_used < 3:
            raise ValueError(
                f"without LOS the estimator needs at least 3 RISs (Remark, Alg. 2){note}"
            )
        if n_used < 2:
            raise ValueError(
                f"the estimator needs at least 2 RISs (bearing-line intersection){note}"
            )
        for i, r in enumerate(sc.ris):
            if r.spacing_m is not None and r.spacing_m > sc.system.wavelength / 2 * (1 + 1e-9):
                raise ValueError(
                    f"ris.{i}.spacing_m = {r.spacing_m} > λ/2: grating lobes make ξ, ζ"
                    " ambiguous for the estimator"
                )
        est = self.estimator
        if est.pair_weights is not None and len(est.pair_weights) != n_ris * (n_ris - 1) // 2:
            raise ValueError(
                f"estimator.pair_weights needs L(L−1)/2 = {n_ris * (n_ris - 1) // 2} values"
            )
        if est.path_weights is not None and len(est.path_weights) != n_ris:
            raise ValueError(f"estimator.path_weights needs L = {n_ris} values")
        if est.delay_fft_size < sc.system.subcarriers:
            raise ValueError(
                f"estimator.delay_fft_size = {est.delay_fft_size} must be ≥ K ="
                f" {sc.system.subcarriers}"
            )
        self._check_scatterers()
        return self

    def _present_paths(self) -> tuple[bool, int, str]:
        """(LOS present, RIS paths present, a note naming the missing ones) for the pair: in
        an environment the estimator works with the paths that exist (as the bounds do)."""
        sc = self.scenario
        presence = scenario_path_presence(sc, sc.tx_array[:1], sc.rx_array[:1])
        present = {name: bool(v[0]) for name, v in presence.items()}
        layout = (["los"] if sc.system.los else []) + [f"ris{i + 1}" for i in range(len(sc.ris))]
        missing = [name for name in layout if not present[name]]
        note = f" (missing paths: {', '.join(missing)} – blocked or out of view)" if missing else ""
        return present["los"], sum(present.values()) - present["los"], note

    def _check_scatterers(self) -> None:
        """No SP may come within :data:`MIN_SCATTERER_DISTANCE_M` of the TX or RX, nor within
        :data:`MIN_UE_RIS_DISTANCE_M` of a RIS centre (a cluster: the nearest point of its
        disk, :func:`scatterer_distances`)."""
        sc = self.scenario
        mp = self.multipath
        checks = [
            ("tx", sc.tx_array[:1], MIN_SCATTERER_DISTANCE_M),
            ("rx", sc.rx_array[:1], MIN_SCATTERER_DISTANCE_M),
            *(
                (f"ris {i}", np.asarray([r.position], dtype=float), MIN_UE_RIS_DISTANCE_M)
                for i, r in enumerate(sc.ris)
            ),
        ]
        for who, point, limit in checks:
            hit = scatterer_too_close(mp, point, limit)
            if hit is None:
                continue
            name, _, dist = hit
            at = f"the {who} {[float(v) for v in point[0]]}"
            fixed = name.startswith("scatterers")
            if dist < MIN_UE_RIS_DISTANCE_M:
                where = f"lies on {at}" if fixed else f"contains {at}"
            else:
                where = (
                    f"lies {dist:.3g} m from {at}"
                    if fixed
                    else f"comes within {dist:.3g} m of {at}"
                )
            raise ValueError(
                f"multipath.{name}: {describe_scatterer(mp, name)} {where}; an SP must stay"
                f" ≥ {limit:g} m from it (its path gain ∝ 1/d diverges, its delay and angles"
                " degenerate)"
            )


def load_simulation(source: dict[str, Any] | SimulationDocument | str) -> SimulationDocument:
    """A :class:`SimulationDocument` from a dict (simulation or plain scenario) or a preset."""
    if isinstance(source, SimulationDocument):
        return source
    if isinstance(source, str):
        return SimulationDocument(scenario=load_scenario(source))
    if "scenario" in source:
        return SimulationDocument.model_validate(source)
    return SimulationDocument.model_validate({"scenario": source})
