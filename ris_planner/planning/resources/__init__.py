"""A plan's resources: sizes, memory and admission, the time estimate, and compiling the kernels
ahead of use (docs/validation/resources.md)."""
