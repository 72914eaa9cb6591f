"""The package's own error types (the service maps them to 4xx responses)."""

from __future__ import annotations


class RisPlannerError(ValueError):
    """Base class: an input the engine cannot work with; the message says the rule, the value
    that arrived and how to fix it."""


class LimitExceededError(RisPlannerError):
    """A request is larger than a configured limit (pairs, layouts, runs); ``limit`` is the
    limit's value where the raiser states it (the service reports it in its 413 body)."""

    def __init__(self, message: str, limit: int | None = None) -> None:
        super().__init__(message)
        self.limit = limit


class DocumentFieldError(RisPlannerError):
    """A rule of the document that names one field (``field`` is its dotted path, e.g.
    ``codebook.kind``; the service lists it in the 422 body's ``fields``)."""

    def __init__(self, field: str, message: str) -> None:
        super().__init__(f"{field}: {message}")
        self.field = field
        self.reason = message

    def __reduce__(self) -> tuple[type, tuple[object, ...]]:
        """Pickled with its two arguments (a job process's error reaches the service whole)."""
        return type(self), (self.field, self.reason)
