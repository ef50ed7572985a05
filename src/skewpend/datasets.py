"""The example data shipped with skewpend: measured motion of two real double pendulums and a triple.

The files are package data (``src/skewpend/data/``; its README gives their sources and
licences), installed by ``pip install .`` like the code, so the guide's examples run from any
installed copy.  :func:`example_data` is the one way to find them.
"""

from __future__ import annotations

from pathlib import Path
from typing import Dict

__all__ = ["EXAMPLE_DATA", "example_data", "data_root", "example_run_file", "example_run_files"]

#: The shipped data sets: name -> what it holds (the names are folders of ``skewpend/data``).
EXAMPLE_DATA: Dict[str, str] = {
    "kaheman2023": "free swing of Kaheman et al. 2023, 1 kHz, 26 pieces to fit and 4 held out (MIT)",
    "kaheman2023-triple": "free swing of their triple pendulum (the same rig, a third arm), 1 kHz, 22 pieces to fit "
                          "and 4 held out (MIT)",
    "dfki-design-C.0": "the DFKI lab's acrobot/pendubot driven by measured torques, trajectory_00-06, 12, 13 "
                       "and the lab's model_*_parameters.yml (BSD-3-Clause)",
    "dfki-design-C.1": "the DFKI lab's model 1.1 of its design C.1, the RealAIGym leaderboard's plant (BSD-3-Clause)",
}


def data_root() -> Path:
    """The folder of the shipped data sets (``skewpend/data`` beside this module)."""
    return Path(__file__).resolve().parent / "data"


def _available() -> str:
    return "; ".join(f"{name} ({what})" for name, what in EXAMPLE_DATA.items())


def example_data(name: str) -> Path:
    """The path of a shipped data set, or of one file in it.

    ``name`` is a data set (``"kaheman2023"``, ``"dfki-design-C.0"``: a folder, which the readers
    take whole) or a file in one (``"dfki-design-C.0/trajectory_00.csv"``).  Raises
    :class:`~skewpend.errors.ParameterError` in one line naming what is available when there is
    no such data set or file.

    >>> import skewpend
    >>> skewpend.example_data("kaheman2023").name
    'kaheman2023'
    >>> skewpend.example_data("dfki-design-C.0/model_h1.0_parameters.yml").is_file()
    True
    """
    from .errors import ParameterError

    if not isinstance(name, str) or not name.strip():
        raise ParameterError(f"example data: expected the name of a data set, got {name!r}; available: {_available()}")
    parts = Path(name.strip().strip("/")).parts
    if parts[0] not in EXAMPLE_DATA or ".." in parts:
        raise ParameterError(f"example data: no data set {name!r}; available: {_available()}")
    root = data_root()
    path = root.joinpath(*parts)
    if not (root / parts[0]).is_dir():
        raise ParameterError(
            f"example data: {parts[0]} is not installed with this copy of skewpend (no {root / parts[0]}); "
            "install skewpend with its package data (pip install . from the repository)")
    if not path.exists():
        files = sorted(p.name for p in (root / parts[0]).iterdir() if p.is_file())
        raise ParameterError(f"example data: {parts[0]} has no {'/'.join(parts[1:])}; its files: {', '.join(files)}")
    return path


def example_run_files() -> Dict[str, Path]:
    """The shipped run files (``--config``): name (the file's stem, e.g. ``"skewed_triple"``) -> path.

    They are package data (``skewpend/data/examples``; the repository's ``examples/`` links there),
    so an installed copy has them too: ``skewpend simulate --config "$(python -c 'import skewpend;
    print(skewpend.example_run_file("skewed_triple"))')"`` works from any folder."""
    folder = data_root() / "examples"
    return {p.stem: p for p in sorted(folder.glob("*.toml"))} if folder.is_dir() else {}


def example_run_file(name: str) -> Path:
    """The path of a shipped run file by its name (``"skewed_triple"`` or ``"skewed_triple.toml"``);
    :class:`~skewpend.errors.ParameterError` in one line naming the ones there are.

    >>> import skewpend
    >>> skewpend.example_run_file("skewed_triple").name
    'skewed_triple.toml'
    """
    from .errors import ParameterError

    files = example_run_files()
    stem = name[: -len(".toml")] if isinstance(name, str) and name.endswith(".toml") else name
    if not isinstance(stem, str) or stem not in files:
        raise ParameterError(f"example run file: no {name!r}; available: {', '.join(files) or 'none installed'}")
    return files[stem]
