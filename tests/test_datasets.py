"""The example data shipped with skewpend (``skewpend.example_data``): found in the package, in the
wheel's package data, refused in one line naming what is there."""

from __future__ import annotations

import glob
import os
from pathlib import Path

import pytest

import skewpend
from skewpend.datasets import EXAMPLE_DATA, data_root

ROOT = Path(__file__).resolve().parents[1]


def test_every_data_set_is_a_folder_of_the_package_with_its_licence():
    assert data_root() == Path(skewpend.__file__).resolve().parent / "data"
    for name in EXAMPLE_DATA:
        path = skewpend.example_data(name)
        assert path.is_dir() and path == data_root() / name
        assert (path / "LICENSE").is_file(), f"{name}: its licence travels with it"
    assert (data_root() / "README.md").is_file()


def test_a_file_in_a_data_set_and_the_readers_take_it():
    path = skewpend.example_data("dfki-design-C.0/trajectory_00.csv")
    assert path.is_file() and path.name == "trajectory_00.csv"
    rig = skewpend.Measurements.from_dfki(path)
    assert len(rig) == 1 and rig[0].u is not None
    lab = skewpend.example_data("dfki-design-C.0/model_h1.0_parameters.yml")
    assert lab.is_file()


def test_the_repository_paths_are_links_to_the_same_files():
    """One copy: data/kaheman2023 and data/dfki-design-C.0 resolve to the package's folders."""
    for name in EXAMPLE_DATA:
        assert (ROOT / "data" / name).resolve() == data_root() / name


@pytest.mark.parametrize("name, words", [
    ("nowhere", ["no data set 'nowhere'", "available: kaheman2023", "dfki-design-C.0"]),
    ("dfki-design-C.0/trajectory_99.csv", ["dfki-design-C.0 has no trajectory_99.csv", "trajectory_00.csv"]),
    ("../kaheman2023", ["no data set", "available"]),
    ("kaheman2023/../../datasets.py", ["no data set", "available"]),
    ("", ["expected the name of a data set", "available"]),
    (3, ["expected the name of a data set"]),
])
def test_an_unknown_name_is_one_line_naming_what_is_available(name, words):
    with pytest.raises(skewpend.ParameterError) as info:
        skewpend.example_data(name)
    message = str(info.value)
    assert "\n" not in message
    for w in words:
        assert w in message


def test_the_wheel_ships_every_file_of_the_data():
    """pyproject's package-data globs (setuptools matches them with ``glob`` relative to the
    package) cover every file of src/skewpend/data: ``pip install .`` installs them all.  (Built and
    listed by hand: ``pip wheel --no-deps . -w /tmp/w``; see the changelog.)"""
    try:
        import tomllib
    except ImportError:  # Python 3.10
        import tomli as tomllib
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    patterns = config["tool"]["setuptools"]["package-data"]["skewpend"]
    package = data_root().parent
    covered = {os.path.normpath(f) for p in patterns for f in glob.glob(str(package / p)) if os.path.isfile(f)}
    files = {os.path.normpath(str(f)) for f in data_root().rglob("*") if f.is_file()}
    assert files and files <= covered, sorted(files - covered)
