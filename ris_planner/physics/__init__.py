"""Layer 4, the physics of section II: geometry and channel parameters, per-path Fisher
information, the spherical-wave response, codebooks and beams (docs/reference/layers.md,
docs/concepts/model.md)."""
