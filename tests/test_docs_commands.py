"""Every shell command the documentation shows runs as shipped (README.md, docs/**/*.md).

The pages' commands are read from their fenced blocks (``bash``, ``console``, ``sh``, and
any block whose lines start with ``$`` or ``ris-planner``) and from inline ``ris-planner …``
code. Each is checked in one of these ways:

* **parsed**: every ``ris-planner`` command – in any block, and inline fragments option by
  option – goes through the real parser (:func:`ris_planner.cli.app.build_parser`), so an
  unknown subcommand or flag fails here; a ``python script.py --flag`` names a script that
  exists and a flag it defines; a ``make TARGET`` a target of the Makefile;
* **run**: a block without a marker is run, command by command, in a temporary folder that
  sees the repository's ``examples/`` and ``tests/`` (``ris-planner`` in this interpreter, with
  a timeout); where the page shows the output (``$ command`` then its lines), the output must
  be the same text with numbers compared by the one tolerance rule (tests/tolerance.py);
* **served**: ``curl`` commands of an unmarked block go to a real ``ris-planner serve`` on
  127.0.0.1 (started and stopped by its PID), and the fields a ``# {...}`` comment shows must
  be those of the answer;
* **skipped**: a block the suite cannot run (minutes of work, a cluster, the reader's own
  files) carries ``<!-- docs-check: skip (why) -->`` on the line before it, and the reason is
  required. Its commands are still parsed. ``<!-- docs-check: synopsis -->`` marks a usage
  synopsis (brackets for optional parts, ``a|b`` for alternatives, continuation lines that
  start with ``[`` or ``--``), which is parsed with each optional part given.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import re
import shlex
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from test_api_plans import small_plan_doc
from tolerance import assert_close

from ris_planner.cli.app import build_parser

ROOT = Path(__file__).resolve().parent.parent
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
SHELL = {"bash", "console", "sh", "shell"}
FENCE = re.compile(r"^(\s*)(`{3,}|~{3,})\s*([\w+-]*)")
MARK = re.compile(r"^<!--\s*docs-check:\s*(\S+)\s*(.*?)\s*-->$")
KINDS = {"skip", "synopsis"}
RUN_TIMEOUT_S = 90
PLACEHOLDERS = {"N": "2"}
"""Placeholder values a synopsis leaves to the reader, where the parser checks the type."""
SMALLER = {
    "ris-planner simulate --preset paper-table1 --noise-figure-db 0 --runs 200"
    " --powers-dbm 20,25,30 --out out/sim": ("--runs 200", "--runs 3"),
}
"""Commands run with a smaller option than the page shows: page command → (shown, run)."""
FILES = {"my-plan.json": small_plan_doc}
"""Files a runnable command names that the reader brings: made here from the tests' data."""
CURL_PORT = "127.0.0.1:8000"


@dataclass
class Command:
    """One shell command of a page: its text, the output shown after it, its block's marker."""

    page: Path
    line: int
    text: str
    mark: tuple[str, str] | None
    output: list[str] = field(default_factory=list)
    comment: str = ""

    @property
    def where(self) -> str:
        return f"{self.page.relative_to(ROOT)}:{self.line}"


@dataclass
class Block:
    page: Path
    line: int
    mark: tuple[str, str] | None
    commands: list[Command]


def split_comment(line: str) -> tuple[str, str]:
    """``code  # comment`` → (code, comment): the first ``#`` outside quotes after a blank."""
    quote = ""
    for i, ch in enumerate(line):
        if quote:
            quote = "" if ch == quote else quote
        elif ch in "'\"":
            quote = ch
        elif ch == "#" and (i == 0 or line[i - 1].isspace()):
            return line[:i].rstrip(), line[i + 1 :].strip()
    return line.rstrip(), ""


def _open_quote(text: str) -> bool:
    quote = ""
    for ch in text:
        if quote:
            quote = "" if ch == quote else quote
        elif ch in "'\"":
            quote = ch
    return bool(quote)


def _commands(
    page: Path, start: int, lang: str, body: list[str], mark: tuple[str, str] | None
) -> list[Command]:
    """The commands of one fenced block (``start``: the line of its first body line)."""
    shell = lang in SHELL
    prompted = any(line.startswith("$ ") for line in body)
    out: list[Command] = []
    i = 0
    while i < len(body):
        raw, number = body[i], start + i
        text = raw[2:] if raw.startswith("$ ") else raw
        is_command = raw.startswith("$ ") if prompted else (shell or raw.startswith("ris-planner"))
        if not is_command or not text.strip() or text.lstrip().startswith("#"):
            if out and text.strip():
                if text.lstrip().startswith("#"):
                    out[-1].comment = (out[-1].comment + " " + text.lstrip()[1:].strip()).strip()
                elif not shell or prompted:
                    out[-1].output.append(raw.rstrip())
            i += 1
            continue
        # continuation: a trailing backslash, an open quote, or (a synopsis) a line of options
        while i + 1 < len(body) and (
            text.rstrip().endswith("\\")
            or _open_quote(text)
            or (mark and mark[0] == "synopsis" and body[i + 1].lstrip()[:1] in ("[", "-"))
        ):
            i += 1
            joint = "\n" if _open_quote(text) else " "
            text = text.rstrip().removesuffix("\\").rstrip() + joint + body[i].strip()
        code, comment = split_comment(text)
        out.append(Command(page, number, code.strip(), mark, comment=comment))
        i += 1
    return out


def blocks(page: Path) -> list[Block]:
    """The fenced blocks of a page that hold commands, with the marker on the line before."""
    lines = page.read_text(encoding="utf-8").splitlines()
    found: list[Block] = []
    i = 0
    while i < len(lines):
        fence = FENCE.match(lines[i])
        if not fence:
            i += 1
            continue
        end = i + 1
        while end < len(lines) and not lines[end].strip().startswith(fence.group(2)):
            end += 1
        indent = len(fence.group(1))
        body = [line[indent:] for line in lines[i + 1 : end]]
        lang = fence.group(3)
        before = next((line.strip() for line in reversed(lines[:i]) if line.strip()), "")
        marker = MARK.match(before)
        mark = (marker.group(1), marker.group(2)) if marker else None
        holds = lang in SHELL or any(b.startswith(("$ ", "ris-planner")) for b in body)
        if holds and lang not in {"json", "python", "js", "javascript", "toml", "yaml"}:
            commands = _commands(page, i + 2, lang, body, mark)
            if commands:
                found.append(Block(page, i + 1, mark, commands))
        i = end + 1
    return found


ALL_BLOCKS = [block for page in PAGES for block in blocks(page)]
ALL_COMMANDS = [command for block in ALL_BLOCKS for command in block.commands]


def simple_commands(text: str) -> Iterator[list[str]]:
    """The simple commands of a line (split at ``;``, ``&&``, ``||``, ``|``), each without
    its leading ``VAR=value`` assignments."""
    lexer = shlex.shlex(text, posix=True, punctuation_chars=";&|")
    lexer.whitespace_split = True
    words: list[str] = []
    for token in [*lexer, ";"]:
        if token and set(token) <= set(";&|"):
            while words and re.match(r"^[A-Za-z_]\w*=", words[0]):
                words.pop(0)
            if words:
                yield words
            words = []
        else:
            words.append(token)


def program(words: list[str]) -> str:
    return Path(words[0]).name if words[0].endswith("ris-planner") else words[0]


ALTERNATIVES = re.compile(r"(?<=[^\s|])\|[^\s\]]+")
"""``rx|tx|sum`` in a synopsis: the alternatives after the first (a shell pipe has blanks)."""


def given(text: str) -> str:
    """A command line with its optional ``[parts]`` given and the first of each ``a|b``."""
    return ALTERNATIVES.sub("", re.sub(r"[\[\]]", " ", text))


def call_words(words: list[str]) -> list[str]:
    """The words of a call: no ``…``, placeholders with a value of their type, no redirect."""
    words = words[: words.index(">")] if ">" in words else words
    return [PLACEHOLDERS.get(w, w) for w in words if w not in ("…", "...")]


def parse_error(argv: list[str]) -> str | None:
    """What the real parser says about ``ris-planner argv`` (None when it parses)."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            build_parser(argv[0] if argv else None).parse_args(argv)
        except SystemExit as exc:
            return err.getvalue().strip().splitlines()[-1] if exc.code else None
    return None


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def _options(parser: argparse.ArgumentParser) -> set[str]:
    """Option strings of a parser and of every parser below it."""
    names = {s for a in parser._actions for s in a.option_strings}
    for child in _subparsers(parser).values():
        names |= _options(child)
    return names


def fragment_problems(words: list[str]) -> list[str]:
    """An inline fragment (``ris-planner plan DOC --sizing``): its subcommands exist and every
    flag belongs to the command it follows."""
    parser = build_parser()
    problems = []
    rest = words[1:]
    while rest and _subparsers(parser):
        head = rest[0]
        if head.startswith("-") or head in ("…", "...") or head.isupper():
            break
        if head not in _subparsers(parser):
            return [f"unknown subcommand {head!r}"]
        parser, rest = _subparsers(parser)[head], rest[1:]
    known = _options(parser)
    for word in rest:
        flag = word.split("=")[0]
        if flag.startswith("--") and flag not in known:
            problems.append(f"unknown option {flag}")
    return problems


def inline_fragments(page: Path) -> Iterator[tuple[int, str]]:
    """Inline ``ris-planner …`` code spans outside fenced blocks."""
    inside = False
    for number, line in enumerate(page.read_text(encoding="utf-8").splitlines(), 1):
        if FENCE.match(line):
            inside = not inside
            continue
        if not inside:
            for span in re.findall(r"`(ris-planner\b[^`]*)`", line):
                yield number, span


# --- every command is checked or says why not ---------------------------------------------


def test_every_command_block_runs_or_says_why() -> None:
    assert len(ALL_COMMANDS) >= 60, len(ALL_COMMANDS)
    problems = []
    for block in ALL_BLOCKS:
        where = f"{block.page.relative_to(ROOT)}:{block.line}"
        if block.mark is not None:
            kind, reason = block.mark
            if kind not in KINDS:
                problems.append(f"{where}: unknown docs-check kind {kind!r}")
            elif kind == "skip" and not re.fullmatch(r"\(.{10,}\)", reason):
                problems.append(f"{where}: docs-check: skip needs a reason in parentheses")
            continue
        for command in block.commands:
            for words in simple_commands(command.text):
                name = program(words)
                if name not in ("ris-planner", "curl") and words[:2] != ["python", "-c"]:
                    problems.append(
                        f"{where}: `{command.text[:60]}` cannot be run by the suite:"
                        " mark the block <!-- docs-check: skip (why) -->"
                    )
    assert not problems, "\n".join(problems)


def test_ris_planner_commands_parse() -> None:
    problems = []
    for command in ALL_COMMANDS:
        for words in simple_commands(given(command.text)):
            if program(words) != "ris-planner":
                continue
            if any(w in ("…", "...") for w in words):
                found = fragment_problems(words)
                problems += [f"{command.where}: {p}" for p in found]
                continue
            error = parse_error(call_words(words)[1:])
            if error:
                problems.append(f"{command.where}: `{' '.join(words)}`: {error}")
    for page in PAGES:
        for number, span in inline_fragments(page):
            found = fragment_problems(span.replace("[", " ").replace("]", " ").split())
            problems += [f"{page.relative_to(ROOT)}:{number}: `{span}`: {p}" for p in found]
    assert not problems, "\n".join(problems)


def test_scripts_and_make_targets_exist() -> None:
    makefile = (ROOT / "Makefile").read_text(encoding="utf-8")
    targets = set(re.findall(r"^([\w.-]+):", makefile, flags=re.M))
    problems = []
    for command in ALL_COMMANDS:
        for words in simple_commands(command.text):
            name = program(words)
            if name == "make":
                problems += [
                    f"{command.where}: make {t}: no such target"
                    for t in words[1:]
                    if t not in targets
                ]
            if name in ("python", "python3") and words[1:2] != ["-c"]:
                script = ROOT / words[1]
                if not script.is_file():
                    problems.append(f"{command.where}: {words[1]} does not exist")
                    continue
                source = script.read_text(encoding="utf-8")
                for flag in (w.split("=")[0] for w in words[2:] if w.startswith("--")):
                    if f'"{flag}"' not in source:
                        problems.append(f"{command.where}: {words[1]} has no option {flag}")
    assert not problems, "\n".join(problems)


# --- runnable commands --------------------------------------------------------------------

NUMBER = re.compile(r"-?\d+(?:\.\d+)?(?:e[-+]?\d+)?")


def assert_same_output(got: str, shown: list[str], where: str) -> None:
    """The output the page shows against the command's: the same text, the same integers,
    floats by the tolerance rule at the precision the page prints them."""
    lines = [line.rstrip() for line in got.strip("\n").splitlines()]
    assert len(lines) == len(shown), (
        f"{where}: output has {len(lines)} lines, page shows "
        + str(len(shown))
        + ":\n"
        + "\n".join(lines)
    )
    for number, (a, b) in enumerate(zip(lines, shown, strict=True), 1):
        context = f"{where}, output line {number}:\n  got   {a}\n  shown {b}"
        assert NUMBER.split(a) == NUMBER.split(b), context
        for x, y in zip(NUMBER.findall(a), NUMBER.findall(b), strict=True):
            if "." in y or "e" in y:
                digits = len(y.split(".")[1].split("e")[0]) if "." in y else 0
                scale = abs(float(y)) or 1.0
                assert_close(float(x), float(y), accuracy=10.0**-digits / scale, where=context)
            else:
                assert x == y, context


def _run_ris_planner(words: list[str], cwd: Path) -> tuple[int, str]:
    stdout_file = None
    if ">" in words:
        at = words.index(">")
        words, stdout_file = words[:at], cwd / words[at + 1]
    env = dict(os.environ, PYTHONPATH=str(ROOT), COLUMNS="200")
    run = subprocess.run(
        [sys.executable, "-m", "ris_planner.cli", *words[1:]],
        cwd=cwd,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT if stdout_file is None else subprocess.PIPE,
        text=True,
        timeout=RUN_TIMEOUT_S,
    )
    if stdout_file is not None:
        stdout_file.write_text(run.stdout, encoding="utf-8")
        return run.returncode, run.stderr
    return run.returncode, run.stdout


def runnable() -> list[Command]:
    """The commands of unmarked blocks but curl, each once (``.venv/bin/ris-planner`` is
    ``ris-planner``)."""
    seen: set[str] = set()
    out = []
    for command in ALL_COMMANDS:
        key = re.sub(r"\S*/ris-planner\b", "ris-planner", command.text)
        if command.mark or key in seen or command.text.split()[:1] == ["curl"]:
            continue
        seen.add(key)
        out.append(command)
    return out


@pytest.fixture(scope="module")
def workdir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder that sees examples/ and tests/ of the checkout, and the readers' files."""
    work = tmp_path_factory.mktemp("docs-commands")
    for name in ("examples", "tests"):
        (work / name).symlink_to(ROOT / name)
    for name, make in FILES.items():
        (work / name).write_text(json.dumps(make()), encoding="utf-8")
    return work


@pytest.mark.parametrize("command", runnable(), ids=lambda c: c.where)
def test_command_runs_as_shown(command: Command, workdir: Path) -> None:
    text = command.text
    if text in SMALLER:
        shown, smaller = SMALLER[text]
        text = text.replace(shown, smaller)
    for words in simple_commands(text):
        if words[:2] == ["python", "-c"]:
            run = subprocess.run(
                [sys.executable, *words[1:]], capture_output=True, text=True, timeout=30
            )
            status, output = run.returncode, run.stdout + run.stderr
        else:
            status, output = _run_ris_planner(words, workdir)
        assert status == 0, f"{command.where}: `{text}` exited {status}:\n{output[-2000:]}"
    if command.output:
        assert_same_output(output, command.output, command.where)


# --- curl against a real server -----------------------------------------------------------


def served_commands() -> list[Command]:
    return [c for c in ALL_COMMANDS if not c.mark and c.text.split()[:1] == ["curl"]]


SHOWN_FIELD = re.compile(r'"(\w+)": (null|"[^"…]*"|-?\d+(?:\.\d+)?(?:\.\.\.)?)')


def assert_shown_fields(answer: dict, comment: str, where: str) -> None:
    """Each ``"key": value`` the comment shows is the answer's; ``0.1445...`` is a value shown
    to four decimals."""
    for key, shown in SHOWN_FIELD.findall(comment):
        assert key in answer, f"{where}: the answer has no {key!r}"
        if shown == "null" or shown.startswith('"'):
            assert answer[key] == json.loads(shown), f"{where}: {key}"
            continue
        value = shown.removesuffix("...")
        digits = len(value.split(".")[1]) if "." in value else 0
        scale = abs(float(value)) or 1.0
        assert_close(
            answer[key], float(value), accuracy=10.0**-digits / scale, where=f"{where}: {key}"
        )


def test_curl_commands_against_a_live_server(workdir: Path) -> None:
    from api.launch import served

    commands = served_commands()
    assert len(commands) >= 3
    last_id = "ID"
    with served(workdir / "jobs.db", log=workdir / "server.log") as server:
        port = server.url.removeprefix("http://")
        for command in commands:
            text = command.text.replace(CURL_PORT, port).replace("/jobs/ID", f"/jobs/{last_id}")
            words = next(simple_commands(text))
            run = subprocess.run(
                [*words, "--write-out", "\n%{http_code}"],
                cwd=workdir,
                capture_output=True,
                text=True,
                timeout=60,
            )
            body, _, status = run.stdout.rpartition("\n")
            assert run.returncode == 0 and status.startswith("2"), (
                f"{command.where}: HTTP {status}: {body[:500]}"
            )
            answer = json.loads(body)
            shown_status = re.search(r"→ (\d{3})", command.comment)
            if shown_status:
                assert status == shown_status.group(1), command.where
            assert_shown_fields(answer, command.comment, command.where)
            last_id = answer.get("id", last_id)
    assert server.process.returncode == 0
