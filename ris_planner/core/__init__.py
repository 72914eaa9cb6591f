"""Layer 0, the core: units, the package's error types, the base of every JSON document model
and the reading of JSON documents (docs/reference/layers.md). Imports nothing else of the
package."""
