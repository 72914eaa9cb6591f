"""Scoring layouts: what each site can serve (visibility), the per-site information cache and the
batched layout score (docs/concepts/scoring.md)."""
