"""Certifying and checking a plan: bounds on the best objective (relaxation, branch-and-bound), the
checks stage and the two-stage estimator on the recommended layouts (docs/concepts/planning.md,
"Pipeline")."""
