"""The guides docs/guides/adding-a-job-type.md and docs/guides/adding-a-cli-option.md stay
true: every path they cite exists, every function, class and constant they name is defined in
the files they cite, and the toy example of each runs here as the page shows it (the page's
Python block is executed: a toy job kind through a real job, a toy option on a copy of the
real parser)."""

from __future__ import annotations

import argparse
import contextlib
import io
import re
import time
from pathlib import Path
from typing import Annotated, Any  # noqa: F401  (names of the job guide's block)

import pytest
from fastapi import APIRouter, Depends  # noqa: F401
from fastapi.responses import Response  # noqa: F401
from fastapi.testclient import TestClient
from pydantic import BaseModel, ConfigDict, Field  # noqa: F401
from waits import HANG_S

from api.auth import Principal  # noqa: F401
from api.deps import get_principal, get_runner, get_store  # noqa: F401
from api.kinds import JOB_KINDS
from api.main import create_app
from api.routes.jobs import submit_job  # noqa: F401
from api.settings import Settings
from api.store import JobStore  # noqa: F401
from api.worker import JobOutput, JobRunner  # noqa: F401
from ris_planner.cli.app import build_parser, int_in
from ris_planner.model.plan import PlanDocument
from ris_planner.planning.inputs.presets import plan_preset
from ris_planner.runtime.progress import ProgressCallback  # noqa: F401

ROOT = Path(__file__).resolve().parent.parent
JOB_GUIDE = ROOT / "docs/guides/adding-a-job-type.md"
CLI_GUIDE = ROOT / "docs/guides/adding-a-cli-option.md"


def python_block(page: Path) -> str:
    """The page's one ```python block."""
    (block,) = re.findall(r"^```python\n(.*?)^```", page.read_text(encoding="utf-8"), re.M | re.S)
    return str(block)


# the job guide's block at import time: the worker process imports this module by name and
# finds the toy job function here, as it finds api.kinds' functions
exec(compile(python_block(JOB_GUIDE), str(JOB_GUIDE), "exec"), globals())


def cited(page: Path) -> tuple[set[str], set[str]]:
    """(repository paths, code names) a guide cites in backticks."""
    text = page.read_text(encoding="utf-8")
    spans = re.findall(r"`([^`\n]+)`", text)
    paths = {s for s in spans if re.fullmatch(r"(?:api|ris_planner|tests|docs)/[\w/.-]+", s)}
    names = set()
    for span in spans:
        name = re.fullmatch(r"([A-Za-z_]\w*)(?:\(.*\))?", span)
        if name and ("_" in name.group(1).strip("_") or re.search(r"[a-z][A-Z]", name.group(1))):
            names.add(name.group(1))
    return paths, names


@pytest.mark.parametrize("page", [JOB_GUIDE, CLI_GUIDE], ids=lambda p: p.name)
def test_the_guide_cites_what_exists(page: Path) -> None:
    paths, names = cited(page)
    assert len(paths) >= 6 and len(names) >= 8, (paths, names)
    missing = sorted(p for p in paths if not (ROOT / p).exists())
    assert not missing, f"{page.name} cites missing files: {missing}"
    sources = "\n".join(
        (ROOT / p).read_text(encoding="utf-8") for p in paths if p.endswith(".py")
    ) + python_block(page)
    unknown = sorted(
        n
        for n in names
        if not re.search(rf"^\s*(?:async def|def|class) {n}\b|^\s*{n}\b[^=\n]*=", sources, re.M)
    )
    assert not unknown, f"{page.name} names what its cited files do not define: {unknown}"


def test_the_toy_job_kind_runs_as_a_real_job(tmp_path: Path) -> None:
    kinds = {**JOB_KINDS, "word_count": globals()["word_count_job"]}
    app = create_app(Settings(db=tmp_path / "jobs.db", workers=1), kinds=kinds)
    app.include_router(globals()["router"], prefix="/v1")
    with TestClient(app, raise_server_exceptions=False) as client:
        assert client.post("/v1/word-counts", json={"text": ""}).status_code == 422
        answer = client.post("/v1/word-counts", json={"text": "three small words"})
        assert answer.status_code == 202, answer.text
        url = answer.json()["url"]
        deadline = time.monotonic() + HANG_S
        while (view := client.get(url).json())["status"] not in ("succeeded", "failed"):
            assert time.monotonic() < deadline, view
            time.sleep(0.05)
        assert view["status"] == "succeeded", view
        assert view["result"] == {"words": 3}
        assert [job["kind"] for job in client.get("/v1/jobs").json()["items"]] == ["word_count"]


def test_the_toy_option_reaches_the_document() -> None:
    namespace: dict[str, Any] = {
        "argparse": argparse,
        "build_parser": build_parser,
        "int_in": int_in,
        "plan_preset": plan_preset,
        "PlanDocument": PlanDocument,
    }
    exec(compile(python_block(CLI_GUIDE), str(CLI_GUIDE), "exec"), namespace)
    assert namespace["doc"]["search"]["top_k"] == 3
    assert PlanDocument.model_validate(namespace["doc"]).search.top_k == 3
    err = io.StringIO()
    with contextlib.redirect_stderr(err), pytest.raises(SystemExit) as stop:
        namespace["parser"].parse_args(["plan", "--preset", "hall", "--top-k", "0"])
    assert stop.value.code == 2
    assert "--top-k" in err.getvalue().strip().splitlines()[-1]
    with contextlib.redirect_stderr(io.StringIO()), pytest.raises(SystemExit):
        build_parser("plan").parse_args(["plan", "--preset", "hall", "--top-k", "3"])
