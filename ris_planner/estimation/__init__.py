"""Signal simulation and the two-stage estimator of the paper (Algorithms 1 and 2).

``signal`` simulates the received OFDM signal with multipath (section II-B) and separates the
paths (eq. ytilde); ``channel_estimation`` is Algorithm 1, ``position_estimation``
Algorithm 2, ``pipeline`` runs both, ``montecarlo`` sweeps power against the CRB and
``blind_area`` maps the noise-free coarse cost.
"""

from ris_planner.estimation.document import SimulationDocument, load_simulation
from ris_planner.model.simulation import (
    EstimatorSettings,
    Multipath,
    Scatterer,
    ScattererCluster,
    SearchArea,
    paper_clusters,
)

__all__ = [
    "EstimatorSettings",
    "Multipath",
    "Scatterer",
    "ScattererCluster",
    "SearchArea",
    "SimulationDocument",
    "load_simulation",
    "paper_clusters",
]
