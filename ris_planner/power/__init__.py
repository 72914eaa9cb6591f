"""RIS power control: the γ_P search (eq. opt_formulation_3) and the power-allocation SDP of
the appendix, on top of the bounds engine."""

from ris_planner.power.report import PowerResult, run_power

__all__ = ["PowerResult", "run_power"]
