"""The choices of a power-allocation run (objective, SDP solver), importable without cvxpy so
the command line can offer them without loading the solver stack."""

from __future__ import annotations

from typing import Literal, get_args

Objective = Literal["rx", "tx", "sum"]
"""Minimise the mean PEB_R² (``rx``), PEB_T² (``tx``) or their sum over the design positions."""
OBJECTIVES: tuple[Objective, ...] = get_args(Objective)

Solver = Literal["CLARABEL", "SCS"]
"""SDP solvers (through cvxpy)."""
SOLVERS: tuple[Solver, ...] = get_args(Solver)
