"""Searching layouts: exhaustive, greedy and swaps, the district search, phased roll-outs,
decisions over ranked layouts and sizing (docs/concepts/planning.md, docs/concepts/district.md)."""
