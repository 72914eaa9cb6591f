"""The inputs of a plan: the document checked and expanded, UE maps, sidelink pairs, candidate
sites, constraints and presets (docs/concepts/planning.md, "Pipeline")."""
