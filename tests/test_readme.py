"""The examples of README.md and of every page of the docs run as a reader would run them: each
document's python blocks (one shared namespace) and the ``skewpend`` lines of its shell blocks, in
the order they appear, in one working directory per document; ``$ skewpend ...`` transcripts
print what they show. (The tutorials are notebooks that Sphinx executes when the docs are built.)

``python tests/readme_runner.py`` lists what is collected. An example must be cheap (the budget is
120 s, reported as a warning when exceeded, not failed); a long run belongs in the docs with small durations.
"""

from __future__ import annotations

import re
import sys
import traceback
import warnings
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
import readme_runner as rr  # noqa: E402

DOCUMENTS = [rr.load(path) for path in rr.documents()]
README = DOCUMENTS[0]
STEPS = [(doc, k, step) for doc in DOCUMENTS for k, step in enumerate(rr.steps(doc))]


def _slug(text: str, n: int = 50) -> str:
    return re.sub(r"[^\w.,=:+/-]+", "_", text.strip())[:n].strip("_")


_READERS: dict[Path, rr.Reader] = {}


@pytest.fixture(scope="module")
def reader(tmp_path_factory):
    """One reader per document: its own working directory, its steps in order."""

    def get(doc: rr.Readme) -> rr.Reader:
        if doc.path not in _READERS:
            workdir = rr.make_workdir(tmp_path_factory.mktemp(_slug(doc.path.stem, 20)))
            _READERS[doc.path] = rr.Reader(doc, workdir, shared=lambda example: _shared(example, tmp_path_factory))
        return _READERS[doc.path]

    yield get
    _READERS.clear()


def _shared(example: rr.CliExample, tmp_path_factory):
    """The run of a documented report command that the report tests read too (helpers.SHARED_COMMANDS):
    run once per session, exactly as written, whichever test asks first; None for every other command."""
    from helpers import SHARED_COMMANDS, shared_cli_run

    return shared_cli_run(tmp_path_factory, example.command) if example.command in SHARED_COMMANDS else None


def _python_failure(where: str, step: rr.Step, error: BaseException, earlier: list[str], path: Path) -> str:
    tb = error.__traceback__  # from the document's own lines on (the harness's frames dropped)
    while tb is not None and tb.tb_next is not None and tb.tb_frame.f_code.co_filename != str(path):
        tb = tb.tb_next
    trace = "".join(traceback.format_exception(type(error), error, tb))
    note = f"\n(earlier example(s) at {', '.join(earlier)} failed too)" if earlier else ""
    return (f"{where}: python block ({step.title!r}) failed: {type(error).__name__}: {error}{note}\n"
            f"{trace[-4000:]}")


@pytest.mark.parametrize(
    "doc, k, step", STEPS,
    ids=[f"{rr.relative(d.path)}:L{s.line}-{_slug(s.title)}" for d, _, s in STEPS],
)
def test_example(doc: rr.Readme, k: int, step: rr.Step, reader) -> None:
    """Every example of README.md and the docs' pages, in reading order per document."""
    r = reader(doc)
    result = r.run(k)
    where = f"{rr.relative(doc.path)}:{step.line}"
    earlier = r.failed_before(k)
    if step.python is not None:
        if result is not None:
            pytest.fail(_python_failure(where, step, result, earlier, doc.path), pytrace=False)
        return
    example, outcome = step.cli, result
    kind = "transcript" if example.transcript else "CLI line"
    where = f"{where}: {kind} `{example.command}`"
    tail = "\n".join(outcome.output.splitlines()[-30:])
    if outcome.returncode is None:
        pytest.fail(f"{where} timed out after {rr.TIMEOUT:.0f} s (examples should take < "
                    f"{rr.MAX_SECONDS:.0f} s)\n{tail}", pytrace=False)
    problems = []
    if example.transcript:
        actual = rr.output_lines(outcome.output)
        if actual != example.expected:
            problems.append("output differs from the document:\n  it shows:\n"
                            + "\n".join(f"    {l}" for l in example.expected)
                            + "\n  actual output:\n" + "\n".join(f"    {l}" for l in actual))
    if outcome.returncode != example.expected_status:
        problems.append(f"exit status {outcome.returncode}, expected {example.expected_status}")
    note = rr.over_budget(where, outcome)  # reported, not failed: no test asserts an absolute time (issue 36)
    if note:
        warnings.warn(note, stacklevel=1)
    if problems and earlier:
        problems.append(f"(earlier example(s) at {', '.join(earlier)} failed too)")
    if problems:
        body = "\n".join(problems)
        output = "" if example.transcript else f"\noutput (last 30 lines):\n{tail}"
        pytest.fail(f"{where}: {body}{output}", pytrace=False)


def test_documents_have_examples() -> None:
    for doc in DOCUMENTS:
        print(rr.summary(doc))
    assert README.python, "no ```python blocks found in README.md"
    assert README.cli, "no skewpend command lines found in README.md"
    assert len(DOCUMENTS) > 10, "the docs' pages were not found"


def test_reading_order(tmp_path: Path) -> None:
    """A later CLI line sees the files an earlier one made (one working directory per document)."""
    path = tmp_path / "page.md"
    path.write_text("```bash\nskewpend derive --format json > eq.json\n```\n\n```python\n"
                    "import json\nassert 'mass_matrix' in json.load(open('eq.json'))\n```\n", encoding="utf-8")
    r = rr.Reader(rr.load(path), tmp_path)
    assert [s.line for s in r.steps] == [2, 6]
    assert r.run(1) is None and r.outcomes[0].returncode == 0


# ----------------------------------------------------------------------------------------------
# the harness itself


def test_readme_has_examples() -> None:
    print(rr.summary(README))
    assert README.python, "no ```python blocks found in README.md"
    assert README.cli, "no skewpend command lines found in README.md"


SAMPLE = """\
Text `skewpend not-a-command`.

```bash
pip install . && skewpend derive
skewpend derive                    # a comment
skewpend derive --x "a # b" 'c#d' e#f   # comment
  skewpend modes --a 1 \\
      --b 2
skewpend derive | head -n 1
cd somewhere
```

```python
x = 1
```

    ```python
    y = x + 1
    ```

```
M11 = m1 a²/3
```

```
$ skewpend derive --m1 -1
skewpend: error: m1 must be > 0, got -1
$ skewpend derive --alpha 0.1   # fine
output line   

$ pip list
whatever
```

```console
$ skewpend modes
```
````python
```
z = 3
````
"""


def test_harness_parses_sample(tmp_path: Path) -> None:
    path = tmp_path / "README.md"
    path.write_text(SAMPLE, encoding="utf-8")
    readme = rr.load(path)
    assert [(b.number, b.fence_line, b.source) for b in readme.python] == [
        (1, 13, "x = 1\n"), (2, 17, "y = x + 1\n"), (3, 38, "```\nz = 3\n")]
    got = [(e.line, e.command, e.expected, e.expected_status, e.shell) for e in readme.cli]
    assert got == [
        (5, "skewpend derive", None, 0, False),
        (6, "skewpend derive --x \"a # b\" 'c#d' e#f", None, 0, False),
        (7, "skewpend modes --a 1 --b 2", None, 0, False),
        (9, "skewpend derive | head -n 1", None, 0, True),
        (26, "skewpend derive --m1 -1", ["skewpend: error: m1 must be > 0, got -1"], 2, False),
        (28, "skewpend derive --alpha 0.1", ["output line"], 0, False),
        (36, "skewpend modes", [], 0, False),
    ]
    assert [(s.line, s.command) for s in readme.skipped] == [
        (4, "pip install . && skewpend derive"), (10, "cd somewhere"), (31, "pip list")]
    assert readme.cli[1].argv()[3:] == ["derive", "--x", "a # b", "c#d", "e#f"]
    shell = readme.cli[3].argv()
    assert shell.endswith(" -m skewpend derive | head -n 1") and sys.executable in shell
    # the shared namespace runs earlier blocks first and reports tracebacks at README lines
    ns = rr.Namespace(path, readme.python, tmp_path)
    ns.run(2)
    assert ns.globals["y"] == 2
    bad = rr.PythonBlock(4, 50, 51, "\n1 / 0\n")
    ns.blocks.append(bad)
    with pytest.raises(ZeroDivisionError) as info:
        ns.run(4)
    assert info.traceback[-1].path == path and info.traceback[-1].lineno + 1 == 52


def test_harness_timeout_and_shell(tmp_path: Path) -> None:
    slow = rr.CliExample(1, "skewpend --help > help.txt && sleep 600", 0, shell=True)
    outcome = rr.run_cli(slow, tmp_path, timeout=2)
    assert outcome.returncode is None and outcome.seconds < 60  # a hang guard: killed, not waited out (600 s)
    quick = rr.CliExample(1, "skewpend --help | head -n 3 > head.txt", 0, shell=True)
    assert rr.run_cli(quick, tmp_path).returncode == 0
    assert len((tmp_path / "head.txt").read_text().splitlines()) == 3


def test_the_warm_interpreter_is_a_process_per_example(tmp_path: Path) -> None:
    """Plain commands run in children of one warm interpreter (readme_runner.Warm): each has its own
    exit status, output, working directory and files, as a reader's process; one that outlives the
    timeout is killed (its whole session) and the next example runs as before."""
    slow = rr.CliExample(1, "skewpend simulate --t-end 1e5 --max-steps 1e12 --method gauss --dt 1e-4 --dt-out 1 "
                            "--out long.nc", 0)  # 1e9 steps: half an hour or more
    outcome = rr.run_cli(slow, tmp_path, timeout=2)
    assert outcome.returncode is None and outcome.seconds < 60  # a hang guard: killed, not waited out
    refused = rr.run_cli(rr.CliExample(2, "skewpend modes --about 1e17,0", 0), tmp_path)
    assert refused.returncode == 2 and refused.output.startswith("skewpend: error: --about")
    (tmp_path / "sub").mkdir()
    ran = rr.run_cli(rr.CliExample(3, "skewpend simulate --t-end 0.5 --out run.csv", 0), tmp_path / "sub")
    assert ran.returncode == 0 and "reached t_end" in ran.output and (tmp_path / "sub" / "run.csv").is_file()
    assert rr.run_cli(rr.CliExample(4, "skewpend --version", 0), tmp_path).output.startswith("skewpend ")


@pytest.mark.parametrize(
    "line, stripped",
    [
        ("skewpend a # c", "skewpend a"),
        ("skewpend a#b", "skewpend a#b"),
        ("skewpend '#x' # c", "skewpend '#x'"),
        ('skewpend "it\'s # not" #c', 'skewpend "it\'s # not"'),
        (r"skewpend a\ #b", r"skewpend a\ #b"),
        ("# only a comment", ""),
    ],
)
def test_strip_comment(line: str, stripped: str) -> None:
    assert rr.strip_comment(line) == stripped
