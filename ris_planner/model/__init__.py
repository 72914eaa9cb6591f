"""Layer 3, the model: the JSON contract – scenario and plan documents, power options, UE priors,
the paper's reference data, planning physics defaults and the limits every run is checked
against (docs/reference/layers.md, docs/concepts/conventions.md)."""
