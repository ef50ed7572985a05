"""Parse README.md and the docs' pages into runnable examples (used by ``tests/test_readme.py``).

Each document is read as a reader would: its examples -- python blocks and CLI lines -- run in
the order they appear, in one working directory per document (so a line that resumes a store
finds the store the line before it made).

* ```` ```python ```` blocks are executed in order in one shared namespace.
* In ```` ```bash ````/``sh``/``console``/``shell`` blocks every line starting with ``skewpend``
  is a CLI example that must exit with status 0.
* Interactive transcripts -- a ``$ skewpend ...`` line followed by the output it prints -- are
  run and their output compared with the README's (in any fenced block, including untagged ones,
  since transcripts are usually shown in plain blocks).

``python tests/readme_runner.py`` prints what would be collected.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
EXAMPLES = ROOT / "examples"
DOCS = ROOT / "docs"
# executed by Sphinx (MyST-NB) when the docs are built, not here; generated pages
DOCS_SKIP = ("_build", "tutorials", "reference/generated", "auto_gallery")

PYTHON_LANGS = {"python", "py", "python3"}
SHELL_LANGS = {"bash", "sh", "console", "shell", "shell-session"}
# Lines in shell blocks that are not skewpend examples (reported as skipped, never run).
SKIP_PREFIXES = ("pip ", "python -m pytest", "python benchmarks/", "bash ", "cd ")
ERROR_PREFIX = "skewpend: error:"
TIMEOUT = 300.0  # a hang guard per command: a command still running then is killed and its example fails
#: The documents' budget for one example, for their writers: an example should cost well under this on the
#: development machine (small durations; a long run is described, not run).  It is a guideline, not a test
#: (issue 36: no test asserts an absolute time): a slower or loaded machine may take longer, so an example
#: over it is reported (:func:`over_budget`, a warning in the test run), never failed.
MAX_SECONDS = 120.0
_SHELL_META = set("|><;&`$")
_FENCE = re.compile(r"^(?P<indent> *)(?P<fence>`{3,}|~{3,})(?P<info>.*)$")


# ----------------------------------------------------------------------------------------------
# Markdown fences


@dataclass
class Block:
    index: int  # 0-based, among all fenced blocks
    lang: str  # first word of the info string, lower case ('' if none)
    fence_line: int  # 1-based line of the opening fence
    lines: list[str]  # content lines (fence indentation removed)

    @property
    def first_line(self) -> int:
        """1-based README line of the first content line."""
        return self.fence_line + 1


def parse_fences(text: str) -> list[Block]:
    """Fenced code blocks (CommonMark: ``` or ~~~, closing fence of the same character and at
    least the same length; an unclosed fence runs to the end of the document)."""
    blocks: list[Block] = []
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        m = _FENCE.match(lines[i])
        if m is None or (m.group("fence")[0] == "`" and "`" in m.group("info")):
            i += 1
            continue
        indent, fence = len(m.group("indent")), m.group("fence")
        info = m.group("info").strip()
        lang = info.split()[0].lower() if info else ""
        start = i + 1  # 1-based fence line
        body: list[str] = []
        i += 1
        while i < len(lines):
            close = re.match(r"^ *(`{3,}|~{3,})\s*$", lines[i])
            if close and close.group(1)[0] == fence[0] and len(close.group(1)) >= len(fence):
                break
            line = lines[i]
            # remove up to `indent` spaces of the fence's indentation
            strip = len(line) - len(line.lstrip(" "))
            body.append(line[min(indent, strip):])
            i += 1
        blocks.append(Block(len(blocks), lang, start, body))
        i += 1  # skip the closing fence
    return blocks


# ----------------------------------------------------------------------------------------------
# Shell lines


def strip_comment(line: str) -> str:
    """Drop a trailing shell comment: a ``#`` outside quotes that starts the line or follows
    whitespace (``a#b`` and ``"# x"`` are kept, as in the shell)."""
    quote = None
    word_start = True  # at the start of the line or after unquoted, unescaped whitespace
    i = 0
    while i < len(line):
        ch = line[i]
        blank = False
        if quote == "'":
            if ch == "'":
                quote = None
        elif quote == '"':
            if ch == "\\":
                i += 1
            elif ch == '"':
                quote = None
        elif ch == "\\":
            i += 1
        elif ch in "'\"":
            quote = ch
        elif ch == "#" and word_start:
            return line[:i].rstrip()
        elif ch.isspace():
            blank = True
        word_start = blank
        i += 1
    return line.rstrip()


def needs_shell(command: str) -> bool:
    """True if the command has an unquoted pipe, redirection, list operator or expansion."""
    quote = None
    i = 0
    while i < len(command):
        ch = command[i]
        if quote == "'":
            if ch == "'":
                quote = None
        elif quote == '"':
            if ch == "\\":
                i += 1
            elif ch == '"':
                quote = None
            elif ch in "$`":
                return True
        elif ch == "\\":
            i += 1
        elif ch in "'\"":
            quote = ch
        elif ch in _SHELL_META:
            return True
        i += 1
    return False


def is_skewpend(command: str) -> bool:
    return command == "skewpend" or command.startswith("skewpend ")


@dataclass
class CliExample:
    line: int  # 1-based README line of the command
    command: str  # without the leading '$ ' and without a trailing comment
    block: int  # index of the fenced block
    expected: list[str] | None = None  # transcript output (None: only the exit status is checked)
    shell: bool = False

    @property
    def transcript(self) -> bool:
        return self.expected is not None

    @property
    def expected_status(self) -> int:
        if self.expected is not None and any(l.startswith(ERROR_PREFIX) for l in self.expected):
            return 2
        return 0

    def argv(self) -> list[str] | str:
        """The command to run: an argument list, or a shell string for shell syntax."""
        if self.shell:
            python = shlex.quote(sys.executable)
            return re.sub(r"(^|[|;&(]\s*)skewpend(?=\s|$)", rf"\g<1>{python} -m skewpend", self.command)
        args = shlex.split(self.command)
        return [sys.executable, "-m", "skewpend", *args[1:]]


@dataclass
class Skipped:
    line: int
    command: str
    reason: str


def _join_continuations(lines: list[str], first: int) -> list[tuple[int, str]]:
    """(README line, logical line): a line ending in an unquoted backslash continues."""
    out: list[tuple[int, str]] = []
    pending: tuple[int, str] | None = None
    for k, raw in enumerate(lines):
        if pending is not None:
            start, text = pending
            text = text[:-1].rstrip() + " " + raw.strip()
        else:
            start, text = first + k, raw
        if strip_comment(text).endswith("\\"):
            pending = (start, strip_comment(text))
        else:
            pending = None
            out.append((start, text))
    if pending is not None:
        out.append((pending[0], pending[1][:-1]))
    return out


def cli_examples(blocks: list[Block]) -> tuple[list[CliExample], list[Skipped]]:
    examples: list[CliExample] = []
    skipped: list[Skipped] = []
    for block in blocks:
        if block.lang not in SHELL_LANGS and block.lang != "":
            continue
        logical = _join_continuations(block.lines, block.first_line)
        transcript = any(text.lstrip().startswith("$ ") or text.strip() == "$" for _, text in logical)
        if not transcript:
            if block.lang == "":  # untagged blocks only hold transcripts (or plain text)
                continue
            for lineno, text in logical:
                command = strip_comment(text.strip())
                if is_skewpend(command):
                    examples.append(CliExample(lineno, command, block.index, shell=needs_shell(command)))
                elif command.startswith(SKIP_PREFIXES):
                    skipped.append(Skipped(lineno, command, "not a skewpend example"))
            continue
        # transcript: '$ command' lines, each followed by its output up to the next '$' line
        current: CliExample | None = None
        for lineno, text in logical:
            stripped = text.lstrip()
            if stripped.startswith("$ ") or stripped.rstrip() == "$":
                command = strip_comment(stripped[1:].strip())
                if is_skewpend(command):
                    current = CliExample(lineno, command, block.index, expected=[], shell=needs_shell(command))
                    examples.append(current)
                else:
                    current = None
                    if command:
                        skipped.append(Skipped(lineno, command, "transcript of a non-skewpend command"))
            elif current is not None:
                current.expected.append(text.rstrip())
    for ex in examples:
        if ex.expected is not None:
            while ex.expected and not ex.expected[-1]:
                ex.expected.pop()
    return examples, skipped


# ----------------------------------------------------------------------------------------------
# Python blocks


@dataclass
class PythonBlock:
    number: int  # 1-based among the python blocks
    fence_line: int
    first_line: int
    source: str

    @property
    def title(self) -> str:
        for line in self.source.splitlines():
            if line.strip():
                return line.strip()
        return ""


def python_blocks(blocks: list[Block]) -> list[PythonBlock]:
    out = []
    for block in blocks:
        if block.lang in PYTHON_LANGS and any(l.strip() for l in block.lines):
            out.append(PythonBlock(len(out) + 1, block.fence_line, block.first_line, "\n".join(block.lines) + "\n"))
    return out


@dataclass
class Readme:
    path: Path
    python: list[PythonBlock]
    cli: list[CliExample]
    skipped: list[Skipped]


def load(path: Path = README) -> Readme:
    blocks = parse_fences(path.read_text(encoding="utf-8"))
    cli, skipped = cli_examples(blocks)
    return Readme(path, python_blocks(blocks), cli, skipped)


def make_workdir(directory: Path) -> Path:
    """A working directory holding a copy of the project's examples/."""
    directory.mkdir(parents=True, exist_ok=True)
    if EXAMPLES.is_dir():
        shutil.copytree(EXAMPLES, directory / "examples", dirs_exist_ok=True)
    return directory


@dataclass
class Namespace:
    """The shared namespace of the README's python blocks, run top to bottom."""

    path: Path
    blocks: list[PythonBlock]
    workdir: Path
    globals: dict = field(default_factory=lambda: {"__name__": "__readme__"})
    results: dict[int, BaseException | None] = field(default_factory=dict)

    def _exec(self, block: PythonBlock) -> None:
        # pad so that line numbers in tracebacks are the README's
        code = compile("\n" * (block.first_line - 1) + block.source, str(self.path), "exec")
        cwd = os.getcwd()
        os.chdir(self.workdir)
        try:
            exec(code, self.globals)
            self.results[block.number] = None
        except BaseException as exc:  # noqa: BLE001 -- recorded and re-raised
            self.results[block.number] = exc
            raise
        finally:
            os.chdir(cwd)

    def run(self, number: int) -> None:
        """Run block `number`, first running any earlier block not yet run (so a selection of
        blocks, or a different test order, still sees the names defined above it)."""
        for block in self.blocks:
            if block.number >= number:
                break
            if block.number not in self.results:
                try:
                    self._exec(block)
                except Exception:
                    pass  # recorded; reported by that block's own test
        self._exec(self.blocks[number - 1])

    def failed_before(self, number: int) -> list[int]:
        return [n for n, exc in sorted(self.results.items()) if n < number and exc is not None]


# ----------------------------------------------------------------------------------------------
# Running CLI lines


@dataclass
class Outcome:
    returncode: int | None  # None: timed out
    output: str  # stdout + stderr, interleaved
    seconds: float


#: The warm interpreter (see :class:`Warm`): it imports skewpend's command line and the scientific stack once,
#: then forks one child per example, which runs ``python -m skewpend ARGS`` (``runpy``) in the document's
#: directory with its output to a file.  Single-threaded, so forking is safe; each child is a process of its
#: own (exit status, signals, files) that skips the 0.4-1 s of imports a fresh interpreter pays.
_SERVER = r"""
import json, os, runpy, sys, traceback
import numpy, scipy, sympy, matplotlib, skewpend, skewpend.cli, skewpend.numeric.kernels, skewpend.symbolic.derivation
for line in sys.stdin:
    job = json.loads(line)
    pid = os.fork()
    if pid == 0:
        os.setsid()
        os.chdir(job["cwd"])
        os.environ.clear(); os.environ.update(job["env"])
        null = os.open(os.devnull, os.O_RDONLY); os.dup2(null, 0)
        out = os.open(job["out"], os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644); os.dup2(out, 1); os.dup2(out, 2)
        sys.argv = [sys.executable, *job["argv"]]
        code = 0
        try:
            runpy.run_module("skewpend", run_name="__main__", alter_sys=True)
        except SystemExit as exit:
            code = exit.code if isinstance(exit.code, int) else (0 if exit.code is None else 1)
            if exit.code is not None and not isinstance(exit.code, int):
                print(exit.code, file=sys.stderr)
        except BaseException:
            traceback.print_exc()
            code = 1
        try:
            sys.stdout.flush(); sys.stderr.flush()
        finally:
            os._exit(code)
    sys.stdout.write(json.dumps({"pid": pid}) + "\n"); sys.stdout.flush()
    _, status = os.waitpid(pid, 0)
    code = os.waitstatus_to_exitcode(status)
    sys.stdout.write(json.dumps({"code": code}) + "\n"); sys.stdout.flush()
"""


class Warm:
    """The warm interpreter of this process (started on first use, ended at exit)."""

    proc: subprocess.Popen | None = None

    @classmethod
    def run(cls, argv: list[str], workdir: Path, timeout: float) -> Outcome:
        import json
        import select
        import tempfile

        if cls.proc is None or cls.proc.poll() is not None:
            cls.proc = subprocess.Popen([sys.executable, "-c", _SERVER], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                        text=True, start_new_session=True)
        proc = cls.proc
        fd, out = tempfile.mkstemp(prefix=".example-", suffix=".out")
        os.close(fd)
        try:
            start = time.perf_counter()
            proc.stdin.write(json.dumps({"argv": argv, "cwd": str(workdir), "env": dict(os.environ), "out": out}) + "\n")
            proc.stdin.flush()
            pid = json.loads(proc.stdout.readline())["pid"]
            ready, _, _ = select.select([proc.stdout], [], [], timeout)
            if not ready:  # timed out: the child's whole session is killed, then its status read
                try:
                    os.killpg(pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
            code = json.loads(proc.stdout.readline())["code"]
            output = Path(out).read_text(encoding="utf-8", errors="replace")
            return Outcome(None if not ready else code, output, time.perf_counter() - start)
        finally:
            os.unlink(out)

    @classmethod
    def close(cls) -> None:
        if cls.proc is not None and cls.proc.poll() is None:
            cls.proc.stdin.close()
            cls.proc.wait(timeout=30)
        cls.proc = None


import atexit  # noqa: E402

atexit.register(Warm.close)


def run_cli(example: CliExample, workdir: Path, timeout: float = TIMEOUT) -> Outcome:
    """Run an example in `workdir` with this environment: a shell line by the shell, a plain command by a
    child of the warm interpreter (:class:`Warm`); on timeout kill its whole process group (a shell
    pipeline included)."""
    if not example.shell and hasattr(os, "fork"):
        return Warm.run(shlex.split(example.command)[1:], workdir, timeout)
    cmd = example.argv()
    kwargs: dict = dict(cwd=workdir, env=dict(os.environ), stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                        stderr=subprocess.STDOUT, start_new_session=True)
    if example.shell:
        kwargs.update(shell=True, executable=shutil.which("bash") or "/bin/sh")
    start = time.perf_counter()
    with subprocess.Popen(cmd, **kwargs) as proc:
        try:
            out, _ = proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            try:
                os.killpg(proc.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
            out, _ = proc.communicate()
            return Outcome(None, (out or b"").decode("utf-8", "replace"), time.perf_counter() - start)
    return Outcome(proc.returncode, out.decode("utf-8", "replace"), time.perf_counter() - start)


def over_budget(where: str, outcome: Outcome) -> str | None:
    """A note when ``outcome`` took longer than the documents' budget :data:`MAX_SECONDS` (to report,
    not to fail on: the time depends on the machine and its load), else None."""
    if outcome.seconds <= MAX_SECONDS:
        return None
    return (f"{where} took {outcome.seconds:.1f} s, over the documents' budget of {MAX_SECONDS:.0f} s for an "
            f"example (on this machine, now): consider smaller durations")


def output_lines(text: str) -> list[str]:
    """The lines a transcript shows: on a terminal a command's stages are one live line that goes when
    it ends, so the stage lines it writes to a pipe (skewpend.progress.STAGE_LINE) are not shown."""
    from skewpend.progress import STAGE_LINE

    lines = [line.rstrip() for line in text.splitlines() if not STAGE_LINE.match(line.rstrip())]
    while lines and not lines[-1]:
        lines.pop()
    return lines


def summary(readme: Readme) -> str:
    rel = readme.path.name
    out = [f"{rel}: {len(readme.python)} python blocks, {len(readme.cli)} CLI lines "
           f"({sum(e.transcript for e in readme.cli)} transcripts, {sum(e.shell for e in readme.cli)} via the shell), "
           f"{len(readme.skipped)} skipped lines"]
    for b in readme.python:
        out.append(f"  python     {rel}:{b.fence_line:<4} block {b.number}: {b.title}")
    for e in readme.cli:
        kind = "transcript" if e.transcript else ("shell" if e.shell else "cli")
        extra = f" -> {len(e.expected)} output line(s), exit {e.expected_status}" if e.transcript else ""
        out.append(f"  {kind:<11}{rel}:{e.line:<4} {e.command}{extra}")
    for s in readme.skipped:
        out.append(f"  skipped    {rel}:{s.line:<4} {s.command}  ({s.reason})")
    return "\n".join(out)


def documents() -> list[Path]:
    """README.md, then every Markdown page of the docs (the executed tutorials excepted)."""
    pages = sorted(p for p in DOCS.rglob("*.md")
                   if not any(str(p.relative_to(DOCS)).startswith(skip) for skip in DOCS_SKIP))
    return [README, *pages]


def relative(path: Path) -> str:
    try:
        return str(path.relative_to(ROOT))
    except ValueError:
        return str(path)


@dataclass
class Step:
    """One example of a document: a python block or a CLI line, at its place in the text."""

    line: int
    python: PythonBlock | None = None
    cli: CliExample | None = None

    @property
    def title(self) -> str:
        return self.python.title if self.python is not None else self.cli.command


def steps(readme: Readme) -> list[Step]:
    """The document's examples in reading order."""
    out = [Step(b.first_line, python=b) for b in readme.python] + [Step(e.line, cli=e) for e in readme.cli]
    return sorted(out, key=lambda s: s.line)


@dataclass
class Reader:
    """Runs a document's steps in order in one working directory (earlier steps first, once)."""

    readme: Readme
    workdir: Path
    outcomes: dict[int, object] = field(default_factory=dict)  # step index -> exception | Outcome
    #: ``shared(example)``: the outcome and output folder of a run shared with other tests (tests/helpers.py's
    #: ``shared_cli_run``: the command run once per session, exactly as written), or None to run it here
    shared: object = None

    def __post_init__(self) -> None:
        self.steps = steps(self.readme)
        self.namespace = Namespace(self.readme.path, self.readme.python, self.workdir)

    def _run_one(self, k: int) -> object:
        step = self.steps[k]
        if step.python is not None:
            try:
                self.namespace._exec(step.python)
                result: object = None
            except Exception as exc:  # noqa: BLE001 -- reported by that step's test
                result = exc
        else:
            made = self.shared(step.cli) if self.shared is not None and not step.cli.shell else None
            if made is None:
                result = run_cli(step.cli, self.workdir)
            else:  # its files are copied here, for the examples after it
                shutil.copytree(made["dir"], self.workdir, dirs_exist_ok=True)
                result = Outcome(made["returncode"], made["output"], made["seconds"])
        self.outcomes[k] = result
        return result

    def run(self, k: int) -> object:
        """Run step `k` after every earlier step not yet run; its exception or CLI outcome."""
        for j in range(k):
            if j not in self.outcomes:
                self._run_one(j)
        return self.outcomes[k] if k in self.outcomes else self._run_one(k)

    def failed_before(self, k: int) -> list[str]:
        bad = []
        for j in range(k):
            out = self.outcomes.get(j)
            step = self.steps[j]
            if isinstance(out, BaseException) or (isinstance(out, Outcome) and out.returncode != step.cli.expected_status):
                bad.append(f"line {step.line}")
        return bad


if __name__ == "__main__":
    for doc in ([Path(a) for a in sys.argv[1:]] or documents()):
        print(summary(load(doc)))
