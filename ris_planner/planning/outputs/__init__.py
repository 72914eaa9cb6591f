"""What a plan returns: the frozen result and plan.json, per-point fields, the diagnosis and the
figures (docs/concepts/planning.md, "Pipeline")."""
