"""Provenance of a JSON result: the package version that computed it and a hash of its input.

Every JSON result (``ris-planner bounds``/``power``/``simulate``/``blind-area``, the REST
answers and jobs, ``plan.json``) carries ``"provenance": {"package": "ris_planner",
"version": …, "input_sha256": …}``. The hash is SHA-256 of the input document in canonical
JSON – the validated document with its defaults filled in (:class:`pydantic.BaseModel`), or
the document as given (a mapping) – with sorted keys, no whitespace and numbers in Python's
shortest round-trip form, so the same input gives the same hash on every machine and through
every route (docs/concepts/conventions.md, "Provenance").
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from functools import cache
from typing import Any

from pydantic import BaseModel

PACKAGE = "ris_planner"


@cache
def package_version() -> str:
    """The installed package's version (``"unknown"`` when not installed as a distribution)."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(PACKAGE)
    except PackageNotFoundError:
        return "unknown"


def canonical_json(document: BaseModel | Mapping[str, Any]) -> str:
    """The document as canonical JSON (sorted keys, compact separators)."""
    data = document.model_dump(mode="json") if isinstance(document, BaseModel) else document
    return json.dumps(data, sort_keys=True, separators=(",", ":"), ensure_ascii=False)


def input_sha256(document: BaseModel | Mapping[str, Any]) -> str:
    """SHA-256 (hex) of :func:`canonical_json`."""
    return hashlib.sha256(canonical_json(document).encode()).hexdigest()


def provenance(document: BaseModel | Mapping[str, Any]) -> dict[str, str]:
    """``{"package", "version", "input_sha256"}`` of a result computed from ``document``."""
    return {
        "package": PACKAGE,
        "version": package_version(),
        "input_sha256": input_sha256(document),
    }
