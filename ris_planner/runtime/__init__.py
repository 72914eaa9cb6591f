"""Layer 1, the runtime: process-level services the engine uses – BLAS threads, malloc tuning
(entry points only), progress reporting, provenance of results and the worker pools
(docs/reference/layers.md)."""
