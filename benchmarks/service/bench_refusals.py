"""Benchmark: limit cases across the entry points – how the command line and the service answer
plan documents at or beyond the limits, and how fast (docs/validation/resources.md,
"Refusals across the three entry points"; the page shows the service's answer, see
tests/test_web_refusals.py).

The cases are held out from the tests (only the first is also a test's document):

* ``hall 512×512`` – the factory hall with 512 × 512 RISs (the schema's largest);
* ``hall 256×512`` – the hall with 256 × 512 RISs (half of it);
* ``sample > max_pairs`` – the hall with ``pairs.sample`` 30 000 above ``max_pairs`` 20 000;
* ``60 RISs, greedy`` – the street site of the district tests asking for 60 RISs with
  ``search.method: greedy`` (refused by the document's validation);
* ``sizing ladder, large site`` – the hall with mounting points every metre at four heights and
  two tilts (1 040 sites), 20 000 sampled pairs and the sizing ladder 64 × 64 … 512 × 512
  (``--sizing``).

For each: ``ris-planner plan FILE`` in a fresh process – its exit status and first line (a
refusal is one line ``error: …`` and exit status 2; an accepted run prints its ``estimate:``
line first and is then stopped by its PID with SIGINT: the answer is the estimate) – and
``POST /v1/plans/validate`` to a real server (``ris-planner serve`` on 127.0.0.1 with its own
database, one job worker, stopped by its PID at the end) – status code and message. The times
are wall seconds to the answer: the CLI's include the interpreter's start and imports; the
service's are one request to a warm server. Everything is bounded: ``--timeout`` per answer,
the server's start-up 60 s.

    python benchmarks/service/bench_refusals.py                  # the table (Markdown)
    python benchmarks/service/bench_refusals.py --json out.json  # and the rows as JSON
    python benchmarks/service/bench_refusals.py --quick          # the first three cases
"""

from __future__ import annotations

import argparse
import copy
import datetime as dt
import json
import os
import platform
import selectors
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import httpx

from api.launch import served
from ris_planner.model.limits import job_memory_mb
from ris_planner.planning import plan_preset

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: fixtures, harness

from fixtures import ROOT, street_document

MESSAGE_CHARS = 300
"""Messages longer than this are cut (with …) in the table."""


def large_site_ladder() -> dict[str, Any]:
    """The hall with a mounting point every metre along its walls at 3, 4, 5 and 6 m and tilts
    0 and 0.3 rad (1 040 sites), 20 000 sampled pairs, 4 RISs, the sizing ladder up to the
    schema's largest RIS."""
    doc = plan_preset("hall")
    for wall in doc["walls"]:
        wall |= {"spacing_m": 1, "heights_m": [3.0, 4.0, 5.0, 6.0], "tilts_rad": [0.0, 0.3]}
    return doc | {
        "pairs": {"sample": 20_000, "seed": 1},
        "ris_count": [4],
        "sizing": {
            "ris_sizes": [[64, 64], [128, 128], [256, 256], [512, 512]],
            "target": {"objective": 0.9},
        },
    }


def cases() -> list[tuple[str, dict[str, Any], list[str]]]:
    """(name, plan document, extra command-line arguments) of each limit case."""
    hall = plan_preset("hall")

    def ris(rows: int, cols: int) -> dict[str, Any]:
        return copy.deepcopy(hall) | {"ris": hall["ris"] | {"rows": rows, "cols": cols}}

    return [
        ("hall 512×512", ris(512, 512), []),
        ("hall 256×512", ris(256, 512), []),
        (
            "sample > max_pairs",
            copy.deepcopy(hall) | {"pairs": {"sample": 30_000, "seed": 0}, "max_pairs": 20_000},
            [],
        ),
        ("60 RISs, greedy", street_document(counts=(60,), method="greedy"), []),
        ("sizing ladder, large site", large_site_ladder(), ["--sizing"]),
    ]


def cut(text: str) -> str:
    text = " ".join(text.split())
    return text if len(text) <= MESSAGE_CHARS else text[: MESSAGE_CHARS - 1] + "…"


def cli_answer(doc_file: Path, extra: list[str], out: Path, timeout_s: float) -> dict[str, Any]:
    """The command line's answer: exit status (None: accepted and stopped after its first
    line), its first line on stderr (or stdout; a heading ending in ':' with its first item),
    the lines on stderr of a run that ended, wall seconds to the first line."""
    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH", "")) if p)
    cmd = [sys.executable, "-m", "ris_planner.cli", "plan", str(doc_file), "--out", str(out)]
    t0 = time.perf_counter()
    proc = subprocess.Popen(
        [*cmd, *extra],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        env=dict(os.environ, PYTHONPATH=path),
    )
    assert proc.stdout is not None and proc.stderr is not None
    buffers = {proc.stdout: b"", proc.stderr: b""}
    sel = selectors.DefaultSelector()
    for stream in buffers:
        sel.register(stream, selectors.EVENT_READ)
    first: str | None = None
    seconds = None
    open_streams = 2
    while first is None and open_streams:
        left = timeout_s - (time.perf_counter() - t0)
        if left <= 0:
            break
        for key, _ in sel.select(timeout=left):
            chunk = os.read(key.fd, 65536)
            if not chunk:
                sel.unregister(key.fileobj)
                open_streams -= 1
                continue
            buffers[key.fileobj] += chunk  # type: ignore[index]
            if b"\n" in buffers[key.fileobj]:  # type: ignore[index]
                line = buffers[key.fileobj].split(b"\n", 1)[0]  # type: ignore[index]
                first = line.decode(errors="replace").split("\r")[-1].strip()
                seconds = time.perf_counter() - t0
                break
    sel.close()
    stopped = False
    if proc.poll() is None:
        try:
            proc.wait(timeout=2)  # a refusal exits right after its line
        except subprocess.TimeoutExpired:
            stopped = True
            proc.send_signal(signal.SIGINT)  # accepted: stop the run by its PID
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
    err = buffers[proc.stderr] + (b"" if stopped else proc.stderr.read())
    proc.stdout.close()
    proc.stderr.close()
    lines = [ln for ln in err.decode(errors="replace").split("\n") if ln.strip()]
    if first is not None and first.endswith(":") and len(lines) > 1:
        first += " " + lines[1].strip()  # a heading line: its first item too
    return {
        "exit": None if stopped else proc.returncode,
        "first_line": cut(first) if first is not None else f"(no line within {timeout_s:.0f} s)",
        "stderr_lines": None if stopped else len(lines),
        "seconds": seconds if seconds is not None else time.perf_counter() - t0,
        "stopped": stopped,
    }


def rest_answer(client: httpx.Client, doc: dict[str, Any]) -> dict[str, Any]:
    """``POST /v1/plans/validate``: status code, message (a 200's summary), wall seconds."""
    t0 = time.perf_counter()
    r = client.post("/v1/plans/validate", json=doc)
    seconds = time.perf_counter() - t0
    body = r.json() if "json" in r.headers.get("content-type", "") else {}
    if r.status_code == 200:
        methods = ", ".join(f"{c}: {m}" for c, m in body.get("methods", {}).items())
        message = f"valid: {body['sites']} sites, {body['pairs']} pairs; search {methods}"
    else:
        message = body.get("message") or r.text
        fields = body.get("fields") or []
        if fields and not body.get("message"):
            message = "; ".join(f"{f.get('field')}: {f.get('message')}" for f in fields)
    return {"status": r.status_code, "message": cut(str(message)), "seconds": seconds}


def conditions() -> dict[str, Any]:
    commit = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, cwd=ROOT
    ).stdout.strip()
    return {
        "date": dt.datetime.now(dt.UTC).strftime("%Y-%m-%d %H:%M UTC"),
        "commit": commit,
        "python": platform.python_version(),
        "cpus": os.cpu_count(),
        "load_1min": round(os.getloadavg()[0], 2),
        "job_memory_mb": job_memory_mb(),
    }


def table(rows: list[dict[str, Any]]) -> str:
    out = [
        "| case | CLI exit | CLI first line (stderr lines) | CLI s | REST | REST message"
        " | REST s |",
        "|---|---|---|---:|---|---|---:|",
    ]
    for r in rows:
        c, s = r["cli"], r["rest"]
        exit_ = "(accepted; stopped)" if c["stopped"] else str(c["exit"])
        lines = "" if c["stderr_lines"] is None else f" ({c['stderr_lines']})"
        out.append(
            f"| {r['case']} | {exit_} | {c['first_line']}{lines} | {c['seconds']:.2f}"
            f" | {s['status']} | {s['message']} | {s['seconds']:.2f} |"
        )
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--timeout", type=float, default=120.0, help="seconds per answer")
    ap.add_argument("--json", type=Path, help="write the rows and conditions here")
    ap.add_argument("--quick", action="store_true", help="the first three cases")
    args = ap.parse_args(argv)
    chosen = cases()[:3] if args.quick else cases()
    cond = conditions()
    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        for k, (name, doc, extra) in enumerate(chosen):
            src = tmp / f"case{k}.json"
            src.write_text(json.dumps(doc))
            cli = cli_answer(src, extra, tmp / f"out{k}", args.timeout)
            rows.append({"case": name, "cli": cli})
        with (
            served(tmp / "jobs.db", workers=1, log=tmp / "server.log") as srv,
            httpx.Client(base_url=srv.url, timeout=args.timeout) as client,
        ):
            client.post("/v1/plans/validate", json=plan_preset("fig10-anchors"))  # warm
            for row, (_, doc, _) in zip(rows, chosen, strict=True):
                row["rest"] = rest_answer(client, doc)
            queued = client.get("/v1/jobs").json()["total"]
            pid = srv.process.pid
        stopped = srv.process.poll() is not None
    print(
        f"{cond['date']}, commit {cond['commit']}, Python {cond['python']}, {cond['cpus']} CPUs,"
        f" load {cond['load_1min']} at the start, job memory budget {cond['job_memory_mb']} MiB;"
        f" jobs queued by the service: {queued}; server (PID {pid}) stopped: {stopped}"
    )
    print(table(rows))
    if args.json is not None:
        args.json.write_text(json.dumps({"conditions": cond, "rows": rows}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
