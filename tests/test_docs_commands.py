"""Every shell command the documentation shows runs as shipped (README.md, docs/**/*.md), and
every output the pages quote is the output of that command.

The pages' commands are read from their fenced blocks (``bash``, ``console``, ``sh``, and
any block whose lines start with ``$`` or ``ris-planner``) and from inline ``ris-planner …``
code. Each is checked in one of these ways:

* **parsed**: every ``ris-planner`` command – in any block, and inline fragments option by
  option – goes through the real parser (:func:`ris_planner.cli.app.build_parser`), so an
  unknown subcommand or flag fails here; a ``python script.py --flag`` names a script that
  exists and a flag it defines; a ``make TARGET`` a target of the Makefile;
* **run**: a block without a marker is run, its commands in order, in a temporary folder of its
  own that sees the repository's ``examples/`` and ``tests/`` (``ris-planner`` and the scripts
  of ``examples/`` in this interpreter, ``python -c`` too); where the page shows the output
  (``$ command`` then its lines), the output must be the same text with numbers compared by the
  one tolerance rule (tests/tolerance.py) at the precision the page prints them. A line ``…``
  of the shown output stands for any number of lines, a ``…`` inside a line for any text;
* **Python examples**: a ``python`` block followed by a block marked
  ``<!-- docs-check: output -->`` is run as a script in such a folder, and what it prints is
  compared with that block by the same rule;
* **served**: a block with ``curl`` commands is run against a real ``ris-planner serve`` on
  127.0.0.1 (started and stopped by its PID), its other commands (``python -c`` making a body
  file) in order beside; the fields that a ``# {...}`` comment or the shown output gives – nested
  objects by their path – must be those of the answer, and ``→ NNN`` its HTTP status;
* **skipped**: a block the suite cannot run (a cluster, the reader's own files, a benchmark of
  minutes) carries ``<!-- docs-check: skip (why) -->`` on the line before it, and the reason is
  required. Its commands are still parsed. ``<!-- docs-check: synopsis -->`` marks a usage
  synopsis (brackets for optional parts, ``a|b`` for alternatives, continuation lines that
  start with ``[`` or ``--``), which is parsed with each optional part given.

Where a page quotes the figures of a run too long for the suite, the figures come from a file
that run wrote (tests/test_docs_figures.py compares them).
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import io
import itertools
import json
import os
import re
import shlex
import subprocess
import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
from test_api_plans import small_plan_doc
from tolerance import assert_close
from waits import HANG_S

from ris_planner.cli.app import build_parser

ROOT = Path(__file__).resolve().parent.parent
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
SHELL = {"bash", "console", "sh", "shell"}
FENCE = re.compile(r"^(\s*)(`{3,}|~{3,})\s*([\w+-]*)")
MARK = re.compile(r"^<!--\s*docs-check:\s*(\S+)\s*(.*?)\s*-->$")
KINDS = {"skip", "synopsis", "output"}
RUN_TIMEOUT_S = HANG_S
"""A command that has not ended after this long hangs (tests/waits.py): the guard of a hang,
not a speed limit."""
PLACEHOLDERS = {"N": "2"}
"""Placeholder values a synopsis leaves to the reader, where the parser checks the type."""
SMALLER = {
    "ris-planner simulate --preset paper-table1 --noise-figure-db 0 --runs 200"
    " --powers-dbm 20,25,30 --out out/sim": ("--runs 200", "--runs 3"),
}
"""Commands run with a smaller option than the page shows: page command → (shown, run)."""


def link_document() -> dict[str, Any]:
    """docs/concepts/diagnosis.md's tiny-RIS case: tests/test_diagnosis.py's LINK document
    with the sizing ladder the page gives."""
    from test_diagnosis import LINK

    ladder = [[8, 8], [16, 16], [32, 32], [64, 64]]
    return LINK | {"sizing": {"ris_sizes": ladder, "counts": [2, 3], "target": {"objective": 0.85}}}


def helsinki_10x10_document() -> dict[str, Any]:
    """docs/concepts/diagnosis.md's street case: examples/plan_helsinki.py's document with
    400 pairs, 10 × 10 RISs, coverage of PEB_R ≤ 1 m, 2 RISs and the sizing ladder the page
    gives."""
    spec = importlib.util.spec_from_file_location(
        "plan_helsinki", ROOT / "examples" / "plan_helsinki.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    doc, _ = module.helsinki_document(400)
    ladder = [[32, 32], [64, 64], [100, 100], [160, 160]]
    return doc | {
        "ris": {"rows": 10, "cols": 10},
        "objective": {"kind": "coverage", "metric": "rx", "threshold_m": 1.0},
        "ris_count": [2],
        "sizing": {"ris_sizes": ladder, "counts": [2, 3]},
    }


def preset_with(name: str, **fields: Any) -> Callable[[], dict[str, Any]]:
    """A shipped plan preset with some of its fields replaced, as a page describes it."""

    def make() -> dict[str, Any]:
        from ris_planner.planning import plan_preset

        return plan_preset(name) | fields

    return make


SAMPLE = {"sample": 1000, "seed": 1}
FILES: dict[str, Callable[[], dict[str, Any]]] = {
    "my-plan.json": small_plan_doc,
    "link.json": link_document,
    "helsinki_10x10.json": helsinki_10x10_document,
    "junction-phys.json": preset_with("junction", pairs=SAMPLE, ris={"rows": 20, "cols": 20}),
    "junction-iso.json": preset_with("junction", pairs=SAMPLE),
    "hall-sample.json": preset_with("hall", pairs={"sample": 2000, "seed": 1}),
}
"""Files a runnable command names that the reader brings: made here from the tests' data and
the examples, as the page describes them."""
EXIT_STATUS = "echo $?"
"""A page's ``$ echo $?`` shows the exit status of the command before it."""
CURL_PORT = "127.0.0.1:8000"
ELLIPSIS = ("…", "...")
"""A shown output line that is only this stands for any number of lines."""


@dataclass
class Fenced:
    """One fenced block of a page: its first body line, language, body and marker."""

    page: Path
    line: int
    lang: str
    body: list[str]
    mark: tuple[str, str] | None


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

    @property
    def where(self) -> str:
        return f"{self.page.relative_to(ROOT)}:{self.line}"

    @property
    def served(self) -> bool:
        return any(c.text.split()[:1] == ["curl"] for c in self.commands)


@dataclass
class Example:
    """A Python block whose printed output the page shows in the block after it."""

    page: Path
    line: int
    code: str
    output: list[str]

    @property
    def where(self) -> str:
        return f"{self.page.relative_to(ROOT)}:{self.line}"


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


def fenced(page: Path) -> list[Fenced]:
    """Every fenced block of a page, with the marker on the line before it."""
    lines = page.read_text(encoding="utf-8").splitlines()
    found: list[Fenced] = []
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
        before = next((line.strip() for line in reversed(lines[:i]) if line.strip()), "")
        marker = MARK.match(before)
        mark = (marker.group(1), marker.group(2)) if marker else None
        found.append(Fenced(page, i + 2, fence.group(3), body, mark))
        i = end + 1
    return found


def blocks(page: Path) -> list[Block]:
    """The fenced blocks of a page that hold commands."""
    found = []
    for b in fenced(page):
        holds = b.lang in SHELL or any(x.startswith(("$ ", "ris-planner")) for x in b.body)
        if holds and b.lang not in {"json", "python", "js", "javascript", "toml", "yaml"}:
            if b.mark is not None and b.mark[0] == "output":
                continue
            commands = _commands(page, b.line, b.lang, b.body, b.mark)
            if commands:
                found.append(Block(page, b.line - 1, b.mark, commands))
    return found


def examples(page: Path) -> list[Example]:
    """The Python blocks of a page that the next block, marked ``output``, shows the output
    of."""
    found = []
    every = fenced(page)
    for before, after in itertools.pairwise(every):
        if after.mark is not None and after.mark[0] == "output" and before.lang == "python":
            found.append(Example(page, before.line, "\n".join(before.body) + "\n", after.body))
    return found


ALL_BLOCKS = [block for page in PAGES for block in blocks(page)]
ALL_COMMANDS = [command for block in ALL_BLOCKS for command in block.commands]
ALL_EXAMPLES = [example for page in PAGES for example in examples(page)]


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
            if kind not in KINDS - {"output"}:
                problems.append(f"{where}: unknown docs-check kind {kind!r}")
            elif kind == "skip" and not re.fullmatch(r"\(.{10,}\)", reason):
                problems.append(f"{where}: docs-check: skip needs a reason in parentheses")
            continue
        for command in block.commands:
            for words in simple_commands(command.text):
                if program(words) != "curl" and not runnable_words(words):
                    problems.append(
                        f"{where}: `{command.text[:60]}` cannot be run by the suite:"
                        " mark the block <!-- docs-check: skip (why) -->"
                    )
    assert not problems, "\n".join(problems)


def test_every_marker_is_known_and_every_output_follows_a_python_block() -> None:
    problems = []
    for page in PAGES:
        every = fenced(page)
        for k, block in enumerate(every):
            where = f"{page.relative_to(ROOT)}:{block.line - 1}"
            if block.mark is None:
                continue
            if block.mark[0] not in KINDS:
                problems.append(f"{where}: unknown docs-check kind {block.mark[0]!r}")
            if block.mark[0] == "output" and (k == 0 or every[k - 1].lang != "python"):
                problems.append(f"{where}: docs-check: output follows no python block")
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
                if "add_tree_arguments(" in source:  # the A/B harness's own options
                    source += (ROOT / "benchmarks" / "harness.py").read_text(encoding="utf-8")
                for flag in (w.split("=")[0] for w in words[2:] if w.startswith("--")):
                    if f'"{flag}"' not in source:
                        problems.append(f"{command.where}: {words[1]} has no option {flag}")
    assert not problems, "\n".join(problems)


# --- runnable commands --------------------------------------------------------------------

NUMBER = re.compile(r"-?\d+(?:\.\d+)?(?:e[-+]?\d+)?")


def assert_same_line(got: str, shown: str, context: str) -> None:
    """One output line against the page's: the same text, the same integers, floats by the
    tolerance rule at the precision the page prints them; a ``…`` in the shown line stands
    for any text."""
    if "…" in shown:
        pattern = ".*?".join(re.escape(part) for part in shown.split("…"))
        assert re.fullmatch(pattern, got, flags=re.S), context
        return
    assert NUMBER.split(got) == NUMBER.split(shown), context
    for x, y in zip(NUMBER.findall(got), NUMBER.findall(shown), strict=True):
        if "." in y or "e" in y:
            digits = len(y.split(".")[1].split("e")[0]) if "." in y else 0
            scale = abs(float(y)) or 1.0
            assert_close(float(x), float(y), accuracy=10.0**-digits / scale, where=context)
        else:
            assert x == y, context


def _line_matches(got: str, shown: str) -> bool:
    try:
        assert_same_line(got, shown, "")
    except AssertionError:
        return False
    return True


def assert_same_output(got: str, shown: list[str], where: str) -> None:
    """The output the page shows against the command's: line by line
    (:func:`assert_same_line`); a shown line ``…`` stands for any number of lines, so the
    shown lines between two of them are found in order."""
    lines = [line.rstrip() for line in got.strip("\n").splitlines()]
    shown = [line.rstrip() for line in shown]
    listing = "\n".join(lines)
    if not any(line.strip() in ELLIPSIS for line in shown):
        assert len(lines) == len(shown), (
            f"{where}: output has {len(lines)} lines, page shows {len(shown)}:\n{listing}"
        )
        for number, (a, b) in enumerate(zip(lines, shown, strict=True), 1):
            assert_same_line(a, b, f"{where}, output line {number}:\n  got   {a}\n  shown {b}")
        return
    at = 0
    anchored = True  # the next shown line must be the next output line
    for b in shown:
        if b.strip() in ELLIPSIS:
            anchored = False
            continue
        if anchored:
            assert at < len(lines), f"{where}: the output ends before {b!r}:\n{listing}"
            assert_same_line(lines[at], b, f"{where}:\n  got   {lines[at]}\n  shown {b}")
        else:
            found = next((k for k in range(at, len(lines)) if _line_matches(lines[k], b)), None)
            assert found is not None, f"{where}: no output line is {b!r}:\n{listing}"
            at = found
        at += 1
        anchored = True
    if anchored:
        assert at == len(lines), f"{where}: more output after the shown lines:\n{listing}"


def _environment() -> dict[str, str]:
    """The environment of a page's command: the checkout importable, output unbuffered (stdout
    and stderr interleave as on a terminal), figures without a display."""
    return dict(
        os.environ, PYTHONPATH=str(ROOT), PYTHONUNBUFFERED="1", COLUMNS="200", MPLBACKEND="Agg"
    )


def run_command(words: list[str], cwd: Path) -> tuple[int, str]:
    """Run one simple command of a page in ``cwd``: ``ris-planner``, a script of
    ``examples/`` or ``python -c`` in this interpreter. Returns (status, output): stdout and
    stderr together, or stderr alone when stdout goes to a file (``> FILE``)."""
    stdout_file = None
    if ">" in words:
        at = words.index(">")
        words, stdout_file = words[:at], cwd / words[at + 1]
    if program(words) == "ris-planner":
        argv = [sys.executable, "-m", "ris_planner.cli", *words[1:]]
    else:
        assert words[0] in ("python", "python3"), words
        argv = [sys.executable, *words[1:]]
    run = subprocess.run(
        argv,
        cwd=cwd,
        env=_environment(),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT if stdout_file is None else subprocess.PIPE,
        text=True,
        timeout=RUN_TIMEOUT_S,
    )
    if stdout_file is not None:
        stdout_file.write_text(run.stdout, encoding="utf-8")
        return run.returncode, run.stderr
    return run.returncode, run.stdout


def runnable_words(words: list[str]) -> bool:
    """A simple command the suite runs: ``ris-planner``, ``python -c``, a script of
    ``examples/``, ``echo $?`` after one of them."""
    name = program(words)
    if name == "ris-planner" or words == EXIT_STATUS.split():
        return True
    if name in ("python", "python3") and len(words) > 1:
        return words[1] == "-c" or words[1].startswith("examples/")
    return False


def _key(block: Block) -> tuple[str, ...]:
    return tuple(re.sub(r"\S*/ris-planner\b", "ris-planner", c.text) for c in block.commands)


def runnable() -> list[Block]:
    """The unmarked blocks without curl, each once (``.venv/bin/ris-planner`` is
    ``ris-planner``)."""
    seen: set[tuple[str, ...]] = set()
    out = []
    for block in ALL_BLOCKS:
        if block.mark or block.served or _key(block) in seen:
            continue
        seen.add(_key(block))
        out.append(block)
    return out


def make_workdir(work: Path) -> Path:
    """A folder that sees examples/ and tests/ of the checkout, and the readers' files."""
    for name in ("examples", "tests"):
        (work / name).symlink_to(ROOT / name)
    for name, make in FILES.items():
        (work / name).write_text(json.dumps(make()), encoding="utf-8")
    return work


def run_shown(command: Command, cwd: Path, status_shown: bool = False) -> int:
    """Run a command of a page as it shows it (a smaller run where SMALLER says so), compare
    the output it shows and return its exit status: 0 unless ``status_shown`` (the page shows
    the status next, ``$ echo $?``)."""
    text = command.text
    if text in SMALLER:
        shown, smaller = SMALLER[text]
        text = text.replace(shown, smaller)
    status, output = 0, ""
    for words in simple_commands(text):
        status, output = run_command(words, cwd)
        assert status == 0 or status_shown, (
            f"{command.where}: `{text}` exited {status}:\n{output[-2000:]}"
        )
    if command.output:
        assert_same_output(output, command.output, command.where)
    return status


def run_block(block: Block, cwd: Path) -> None:
    """Run a block's commands in order; ``echo $?`` compares the status it shows."""
    status = 0
    for k, command in enumerate(block.commands):
        if command.text == EXIT_STATUS:
            assert [str(status)] == command.output, f"{command.where}: exit status {status}"
            continue
        following = block.commands[k + 1].text if k + 1 < len(block.commands) else ""
        status = run_shown(command, cwd, status_shown=following == EXIT_STATUS)


@pytest.mark.parametrize("block", runnable(), ids=lambda b: b.where)
def test_block_runs_as_shown(block: Block, tmp_path: Path) -> None:
    run_block(block, make_workdir(tmp_path))


@pytest.mark.parametrize("example", ALL_EXAMPLES, ids=lambda e: e.where)
def test_python_example_prints_what_the_page_shows(example: Example, tmp_path: Path) -> None:
    cwd = make_workdir(tmp_path)
    run = subprocess.run(
        [sys.executable, "-c", example.code],
        cwd=cwd,
        env=_environment(),
        capture_output=True,
        text=True,
        timeout=RUN_TIMEOUT_S,
    )
    assert run.returncode == 0, f"{example.where}: exited {run.returncode}:\n{run.stderr[-3000:]}"
    assert_same_output(run.stdout, example.output, example.where)


def test_python_examples_are_found() -> None:
    """The pages' Python examples with a shown output are found (a broken marker would leave
    them unchecked)."""
    pages = {e.page.relative_to(ROOT).as_posix() for e in ALL_EXAMPLES}
    assert "docs/guides/candidates.md" in pages, pages


# --- curl against a real server -----------------------------------------------------------


def served_blocks() -> list[Block]:
    seen: set[tuple[str, ...]] = set()
    out = []
    for block in ALL_BLOCKS:
        if not block.mark and block.served and _key(block) not in seen:
            seen.add(_key(block))
            out.append(block)
    return out


SHOWN_TOKEN = re.compile(
    r'"(\w+)":\s*(\{|null|"[^"…]*"|-?\d+(?:\.\d+)?(?:\.\.\.)?)|(\{)|(\})|(\[)|(\])'
)


def shown_fields(text: str) -> list[tuple[tuple[str, ...], str]]:
    """(path, value) of every ``"key": value`` a comment or shown output gives, nested objects
    by their path (``{"summary": {"by_kind": {"pole": 14}}}`` → (summary, by_kind, pole));
    what a list holds is not read."""
    path: list[str | None] = []
    lists = 0
    out = []
    for key, value, open_brace, close_brace, open_list, close_list in SHOWN_TOKEN.findall(text):
        if open_list:
            lists += 1
        elif close_list:
            lists = max(0, lists - 1)
        elif lists:
            continue
        elif open_brace:
            path.append(None)
        elif close_brace:
            if path:
                path.pop()
        elif value == "{":
            path.append(key)
        else:
            out.append(((*(p for p in path if p is not None), key), value))
    return out


def assert_shown_fields(answer: dict, shown: str, where: str) -> None:
    """Each ``"key": value`` the page shows is the answer's at that path; ``0.1445...`` is a
    value shown to four decimals."""
    for path, value in shown_fields(shown):
        name = ".".join(path)
        got: Any = answer
        for key in path:
            assert isinstance(got, dict) and key in got, f"{where}: the answer has no {name!r}"
            got = got[key]
        if value == "null" or value.startswith('"'):
            assert got == json.loads(value), f"{where}: {name}: {got!r}"
            continue
        number = value.removesuffix("...")
        if "." not in number:
            assert got == int(number), f"{where}: {name}: {got!r} != {number}"
            continue
        digits = len(number.split(".")[1])
        scale = abs(float(number)) or 1.0
        assert_close(got, float(number), accuracy=10.0**-digits / scale, where=f"{where}: {name}")


def test_shown_fields_follow_the_nesting() -> None:
    shown = (
        '→ 200 {"type": "FeatureCollection", "features": [{"a": 1}, …], "summary":'
        ' {"candidates": 100, "by_kind": {"facade": 86}, "roads": 65, …}, "x": 0.12...}'
    )
    assert shown_fields(shown) == [
        (("type",), '"FeatureCollection"'),
        (("summary", "candidates"), "100"),
        (("summary", "by_kind", "facade"), "86"),
        (("summary", "roads"), "65"),
        (("x",), "0.12..."),
    ]


def test_curl_commands_against_a_live_server(tmp_path: Path) -> None:
    from api.launch import served

    blocks = served_blocks()
    assert sum(c.text.split()[:1] == ["curl"] for b in blocks for c in b.commands) >= 4
    workdir = make_workdir(tmp_path)
    last_id = "ID"
    with served(workdir / "jobs.db", log=workdir / "server.log") as server:
        port = server.url.removeprefix("http://")
        for block in blocks:
            for command in block.commands:
                if command.text.split()[:1] != ["curl"]:
                    run_shown(command, workdir)
                    continue
                text = command.text.replace(CURL_PORT, port).replace("/jobs/ID", f"/jobs/{last_id}")
                words = next(simple_commands(text))
                run = subprocess.run(
                    [*words, "--write-out", "\n%{http_code}"],
                    cwd=workdir,
                    capture_output=True,
                    text=True,
                    timeout=RUN_TIMEOUT_S,
                )
                body, _, status = run.stdout.rpartition("\n")
                shown = " ".join([command.comment, *command.output])
                shown_status = re.search(r"→ (\d{3})", shown)
                expected = shown_status.group(1) if shown_status else "2"
                assert run.returncode == 0 and status.startswith(expected), (
                    f"{command.where}: HTTP {status}: {body[:500]}"
                )
                answer = json.loads(body)
                assert_shown_fields(answer, shown, command.where)
                last_id = answer.get("id", last_id)
    assert server.process.returncode == 0
