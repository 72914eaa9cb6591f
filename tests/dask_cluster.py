"""The test suite's Dask cluster: a LocalCluster of 2 worker processes on 127.0.0.1 (no
dashboard port fixed), closed with its workers when the block ends."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import pytest


@contextmanager
def local_cluster() -> Iterator[Any]:
    """A ``distributed.LocalCluster`` for one test (skipped without ``distributed``)."""
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address="127.0.0.1:0",
    ) as cluster:
        yield cluster
