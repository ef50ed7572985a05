"""The README's examples run: every python block (in order, one shared namespace) and every
``skewpend`` line of its shell blocks, and its ``$ skewpend ...`` transcripts print what they show.

``python tests/readme_runner.py`` lists what is collected. A README example must be cheap (under
120 s); a long run belongs in the README with small durations.
"""

from __future__ import annotations

import re
import sys
import traceback
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
import readme_runner as rr  # noqa: E402

README_PATH = Path(__file__).resolve().parents[1] / "README.md"
README = rr.load(README_PATH)


def _slug(text: str, n: int = 50) -> str:
    return re.sub(r"[^\w.,=:+/-]+", "_", text.strip())[:n].strip("_")


# ----------------------------------------------------------------------------------------------
# python blocks


@pytest.fixture(scope="module")
def namespace(tmp_path_factory) -> rr.Namespace:
    workdir = rr.make_workdir(tmp_path_factory.mktemp("readme-python"))
    return rr.Namespace(README_PATH, README.python, workdir)


@pytest.mark.parametrize(
    "block", README.python, ids=[f"py{b.number}-L{b.fence_line}-{_slug(b.title)}" for b in README.python]
)
def test_python_block(block: rr.PythonBlock, namespace: rr.Namespace) -> None:
    try:
        namespace.run(block.number)
        return
    except Exception as exc:
        error = exc
    # the traceback from the README's own lines on (the harness's frames dropped)
    tb = error.__traceback__
    while tb is not None and tb.tb_frame.f_code.co_filename != str(README_PATH):
        tb = tb.tb_next
    trace = "".join(traceback.format_exception(type(error), error, tb or error.__traceback__))
    earlier = namespace.failed_before(block.number)
    note = f"\n(earlier python block(s) {earlier} failed too)" if earlier else ""
    pytest.fail(
        f"README.md:{block.fence_line}: python block {block.number} ({block.title!r}) failed: "
        f"{type(error).__name__}: {error}{note}\n{trace}",
        pytrace=False,
    )


# ----------------------------------------------------------------------------------------------
# CLI lines and transcripts


def _describe(ex: rr.CliExample) -> str:
    kind = "transcript" if ex.transcript else "CLI line"
    return f"README.md:{ex.line}: {kind} `{ex.command}`"


@pytest.mark.parametrize("example", README.cli, ids=[f"L{e.line}-{_slug(e.command)}" for e in README.cli])
def test_cli_line(example: rr.CliExample, tmp_path: Path) -> None:
    workdir = rr.make_workdir(tmp_path)
    outcome = rr.run_cli(example, workdir)
    where = _describe(example)
    tail = "\n".join(outcome.output.splitlines()[-30:])
    if outcome.returncode is None:
        pytest.fail(f"{where} timed out after {rr.TIMEOUT:.0f} s (README examples must take < "
                    f"{rr.MAX_SECONDS:.0f} s)\n{tail}", pytrace=False)
    problems = []
    if example.transcript:
        actual = rr.output_lines(outcome.output)
        if actual != example.expected:
            problems.append("output differs from the README:\n  README shows:\n"
                            + "\n".join(f"    {l}" for l in example.expected)
                            + "\n  actual output:\n" + "\n".join(f"    {l}" for l in actual))
    if outcome.returncode != example.expected_status:
        problems.append(f"exit status {outcome.returncode}, expected {example.expected_status}")
    if outcome.seconds > rr.MAX_SECONDS:
        problems.append(f"took {outcome.seconds:.1f} s (> {rr.MAX_SECONDS:.0f} s): the README should use "
                        f"smaller durations")
    if problems:
        body = "\n".join(problems)
        output = "" if example.transcript else f"\noutput (last 30 lines):\n{tail}"
        pytest.fail(f"{where}: {body}{output}", pytrace=False)


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
    slow = rr.CliExample(1, "skewpend --help > help.txt && sleep 30", 0, shell=True)
    outcome = rr.run_cli(slow, tmp_path, timeout=2)
    assert outcome.returncode is None and outcome.seconds < 10
    quick = rr.CliExample(1, "skewpend --help | head -n 3 > head.txt", 0, shell=True)
    assert rr.run_cli(quick, tmp_path).returncode == 0
    assert len((tmp_path / "head.txt").read_text().splitlines()) == 3


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
