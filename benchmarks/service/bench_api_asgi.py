"""The application's own time per ``POST /v1/bounds`` without an HTTP server or a client: the
ASGI application of this checkout and of the base (the A/B harness, ``benchmarks/harness.py``:
``--base REF``, a ``git worktree`` of that commit with its own numba cache, or ``--old-tree
PATH``), each in a fresh process, alternating ``--rounds`` times; per process ``--repeats``
sequential Table I requests after 30 warm-up requests, each driven through ``app(scope,
receive, send)`` on one event loop (the lifespan run first: the store, the limiters), and the
same request's engine work in-process (``bounds_answer``: parse, validate, compute, render) for
reference.

Times are the process's CPU time (all its threads: ``time.process_time``), which a machine
shared with other work disturbs much less than the wall clock. Reported per tree: the minimum
and median CPU time per request and per engine call, and their difference – what the
middlewares, routing, dependency solving, response machinery and the thread hand-off cost per
request (the HTTP server's parsing and socket I/O are not included:
``bench_api.py`` measures those). Every answer must be 200; the two trees' answers agree
(``tests/tolerance.py``'s ``BOUND_ACCURACY``).

    python benchmarks/service/bench_api_asgi.py --base REF [--rounds 3] [--repeats 300]
    python benchmarks/service/bench_api_asgi.py --quick   # this checkout against itself
"""

from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: fixtures, harness
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tests"))

from harness import Tree, add_tree_arguments, alternate, compare, conditions, run_in_tree, trees
from tolerance import BOUND_ACCURACY, assert_close

WORKER = r"""
import asyncio, json, sys, tempfile, time
from pathlib import Path
from threadpoolctl import threadpool_limits
from api.main import create_app
from api.settings import Settings
from ris_planner import preset_document

repeats = int(sys.argv[1])
body = json.dumps(preset_document("paper-table1")).encode()
headers = [(b"host", b"127.0.0.1"), (b"content-type", b"application/json"),
           (b"content-length", str(len(body)).encode())]


async def request(app):
    scope = {"type": "http", "asgi": {"version": "3.0"}, "http_version": "1.1",
             "method": "POST", "scheme": "http", "path": "/v1/bounds", "raw_path": b"/v1/bounds",
             "root_path": "", "query_string": b"", "headers": headers,
             "client": ("127.0.0.1", 5000), "server": ("127.0.0.1", 8000), "state": {}}
    sent = False
    out = []

    async def receive():
        nonlocal sent
        if not sent:
            sent = True
            return {"type": "http.request", "body": body, "more_body": False}
        await asyncio.sleep(3600)

    async def send(message):
        out.append(message)

    await app(scope, receive, send)
    assert out[0]["status"] == 200, out
    return b"".join(m.get("body", b"") for m in out[1:])


async def main(app):
    for _ in range(30):
        await request(app)
    times = []
    for _ in range(repeats):
        t0 = time.process_time()
        answer = await request(app)
        times.append(time.process_time() - t0)
    return times, answer


def engine(settings):
    try:
        from api.routes.bounds import bounds_answer
    except ImportError:
        from api.routes.bounds import _bounds_answer as bounds_answer
    for _ in range(30):
        bounds_answer(body, settings)
    times = []
    for _ in range(repeats):
        t0 = time.process_time()
        bounds_answer(body, settings)
        times.append(time.process_time() - t0)
    return times


with tempfile.TemporaryDirectory() as tmp, threadpool_limits(1):
    settings = Settings(db=Path(tmp) / "j.db", workers=1, blas_threads=1)
    app = create_app(settings)

    async def run():
        async with app.router.lifespan_context(app):
            return await main(app)

    times, answer = asyncio.run(run())
    res = {"app": times, "engine": engine(settings), "answer": json.loads(answer)}
print(json.dumps(res))
"""


def run(tree: Tree, repeats: int) -> dict[str, Any]:
    return run_in_tree(tree, WORKER, str(repeats))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_tree_arguments(parser)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--repeats", type=int, default=300)
    args = parser.parse_args()
    if args.quick:
        args.rounds, args.repeats = 1, 20
    sides = trees(args)

    def show(i: int, tree: Tree, r: dict[str, Any]) -> None:
        print(
            f"{i + 1} {tree.name}: CPU per request {statistics.median(r['app']) * 1e3:.3f} ms,"
            f" per engine call {statistics.median(r['engine']) * 1e3:.3f} ms (medians)",
            flush=True,
        )

    print(f"{conditions()}; old {sides['old'].commit}, new {sides['new'].commit}")
    runs = alternate(sides, lambda tree, _: run(tree, args.repeats), args.rounds, on_result=show)
    answers = {
        name: {k: v for k, v in rs[0]["answer"].items() if k != "provenance"}
        for name, rs in runs.items()
    }
    assert_close(answers["new"], answers["old"], accuracy=BOUND_ACCURACY, where="answer")
    print("CPU   request min / median [ms]  engine min / median [ms]  request − engine (medians)")
    for name, rs in runs.items():
        a = [x for r in rs for x in r["app"]]
        e = [x for r in rs for x in r["engine"]]
        print(
            f"{name:4s}  {min(a) * 1e3:7.3f} / {statistics.median(a) * 1e3:7.3f}"
            f"            {min(e) * 1e3:7.3f} / {statistics.median(e) * 1e3:7.3f}"
            f"          {(statistics.median(a) - statistics.median(e)) * 1e3:7.3f}"
        )
    c = compare(
        [statistics.median(r["app"]) for r in runs["old"]],
        [statistics.median(r["app"]) for r in runs["new"]],
    )
    print(f"CPU per request, {c.text('s')}")


if __name__ == "__main__":
    main()
