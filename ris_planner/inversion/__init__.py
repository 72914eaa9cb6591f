"""Layer 5, inversion: the one numerically sound route from Fisher information to bounds –
the batched scaled LDLᵀ, the CRB with per-parameter identifiability and their compiled kernels
(docs/reference/layers.md, docs/concepts/numerics.md)."""
