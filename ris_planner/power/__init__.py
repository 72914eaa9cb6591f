"""RIS power control: the γ_P search (eq. opt_formulation_3) and the power-allocation SDP of
the appendix, on top of the bounds engine."""

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from ris_planner.power.report import PowerResult, run_power

__all__ = ["PowerResult", "run_power"]


def __getattr__(name: str) -> Any:
    """``run_power`` and ``PowerResult`` on first use: importing the package (e.g. for the
    command line's choices) does not load cvxpy."""
    if name in __all__:
        from ris_planner.power import report

        return getattr(report, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
