"""The identification's figure and report (issue 27): the figure's panels with labelled axes (their
Axes' titles and labels, not pixels), saved as PNG atomically; the report one self-contained HTML
file holding the base parameters and the held-out RMS, referencing nothing outside itself, written
atomically.  One linear identification of the real free swing (Kaheman et al. 2023) per module; the
correlation matrix and the skew-angle profile are set on a copy of it (their drawing, not their
computation, is under test here)."""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path

import numpy as np
import pytest

import skewpend
from skewpend import Measurements
from skewpend.errors import ParameterError
from skewpend.views.figures.identification import plot_identification
from skewpend.views.report import identification as RI
from skewpend.views.report.identification import write_identification_report

KAHEMAN = Path(__file__).resolve().parent.parent / "data" / "kaheman2023"


def kaheman_parameters(**changes) -> skewpend.Parameters:
    """The authors' model in skewpend's terms (as tests/test_identify.py)."""
    from scipy.io import loadmat

    m1, m2, a1, a2, L1, I1, I2, k1, k2, g = (float(x) for x in loadmat(
        str(KAHEMAN / "EstimatedParameters_DoublePendulum.mat"))["EstimatedParameters"].ravel())
    p = skewpend.Parameters(a=L1, b=2 * a2, m1=m1, m2=m2, alpha=0, g=g, c1=k1, c2=k2, com1=(0, a1, 0),
                            com2=(0, a2, 0), inertia1=((I1, 0, 0), (0, 0, 0), (0, 0, I1)),
                            inertia2=((I2, 0, 0), (0, 0, 0), (0, 0, I2)))
    return p.replace(**changes) if changes else p


@pytest.fixture(scope="module")
def data():
    fit = Measurements.from_kaheman(KAHEMAN, which="fit")
    val = Measurements.from_kaheman(KAHEMAN, which="validation")
    return fit, val


@pytest.fixture(scope="module")
def linear(data):
    fit, val = data
    r = skewpend.identify(fit, kaheman_parameters(), validation=val, method="linear")
    assert r.ok, r.message
    return r


@pytest.fixture(scope="module")
def with_extras(linear):
    """The linear result with a correlation matrix of its free parameters and a skew-angle profile."""
    free = [n for n in linear.free if n != linear.reference]
    k = len(free)
    C = np.eye(k) + 0.3 * (np.ones((k, k)) - np.eye(k))
    C[0, 1] = C[1, 0] = -0.8
    alpha = np.radians([-4.0, -2.0, -1.0, 0.0, 1.0, 2.0, 4.0])
    settings = dict(linear.settings, free=free)
    return dataclasses.replace(linear, correlation=C, settings=settings, profile_alpha=alpha,
                               profile_cost=0.02 + 0.5 * alpha**2, alpha=0.0,
                               alpha_interval=(-math.radians(2.0), math.radians(2.0)),
                               alpha_note="a note on the skew angle")


def _visible(fig):
    return [ax for ax in fig.get_axes() if ax.get_visible() and ax.get_label() != "<colorbar>"]


def _titles(fig):
    return [ax.get_title(loc="left") or ax.get_title() for ax in _visible(fig)]


# -- the figure ----------------------------------------------------------------------------------------
def test_figure_has_every_panel_with_labelled_axes(with_extras, data):
    fit, val = data
    fig = plot_identification(with_extras, fit, val)
    titles = _titles(fig)
    # (a): the first and the last fitting piece and every held-out piece, each titled with its name
    pieces = [t for t in titles if t.startswith(("Y_id", "Y_vad"))]
    assert pieces[:2] == ["Y_id[0] fitting", "Y_id[25] fitting"]
    assert [t.split()[0] for t in pieces[2:]] == list(val.names)
    for name, rms in zip(with_extras.validation, with_extras.heldout_rms):
        assert any(t.startswith(f"{name} held out, RMS {1e3 * rms:.3g} mrad") for t in titles)
    for letter in "bcde":
        assert sum(t.startswith(f"({letter})") for t in titles) == 1, (letter, titles)
    assert any(sf._suptitle is not None and sf._suptitle.get_text().startswith("(a)") for sf in fig.subfigs
               for sf in [sf, *sf.subfigs])
    for ax in _visible(fig):
        assert ax.get_xlabel() and ax.get_ylabel(), ax.get_title(loc="left")
    units = {ax.get_title(loc="left")[:3]: (ax.get_xlabel(), ax.get_ylabel()) for ax in _visible(fig)}
    assert "[s]" in units["(b)"][0] and "[mrad]" in units["(b)"][1]
    assert "[%]" in units["(c)"][0]
    assert "[deg]" in units["(e)"][0] and "rad²" in units["(e)"][1]
    for ax in _visible(fig):
        if ax.get_title(loc="left").startswith("Y_"):
            assert ax.get_xlabel().endswith("[s]") and ax.get_ylabel() == "angle [deg]"
    # (c) names the ratios; (d) the free parameters on both axes, with a labelled colour bar
    c = next(ax for ax in _visible(fig) if ax.get_title(loc="left").startswith("(c)"))
    assert [t.get_text() for t in c.get_yticklabels()] == list(with_extras.ratios)
    d = next(ax for ax in _visible(fig) if ax.get_title(loc="left").startswith("(d)"))
    free = with_extras.settings["free"]
    assert [t.get_text() for t in d.get_xticklabels()] == free == [t.get_text() for t in d.get_yticklabels()]
    assert d.images and d.images[0].get_cmap().name == "RdBu_r" and d.images[0].get_clim() == (-1, 1)
    bars = [ax for ax in fig.get_axes() if ax.get_label() == "<colorbar>"]
    assert bars and "correlation" in bars[0].get_ylabel()
    # params0's prediction is drawn dashed beside the fitted model's
    a0 = next(ax for ax in _visible(fig) if ax.get_title(loc="left").startswith("Y_vad"))
    assert any(line.get_linestyle() == "--" for line in a0.get_lines())


def test_figure_without_profile_correlation_or_validation(linear, data):
    fit, _ = data
    fig = plot_identification(linear, fit)
    titles = _titles(fig)
    assert not any(t.startswith("(e)") for t in titles)  # no profile: no panel (e)
    assert [t for t in titles if t.startswith("Y_")] == ["Y_id[0] fitting", "Y_id[25] fitting"]
    b = next(ax for ax in _visible(fig) if ax.get_title(loc="left").startswith("(b)"))
    assert "no held-out pieces" in " ".join(t.get_text() for t in b.texts)
    d = next(ax for ax in _visible(fig) if ax.get_title(loc="left").startswith("(d)"))
    assert "no correlation matrix" in " ".join(t.get_text() for t in d.texts)


def test_figure_saves_png_atomically(linear, data, tmp_path):
    fit, val = data
    out = tmp_path / "fit.png"
    plot_identification(linear, fit, val, out)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    from PIL import Image

    with Image.open(out) as im:
        assert im.size == (1600, 1000)
    assert [p.name for p in tmp_path.iterdir()] == ["fit.png"]  # no temporary file beside it
    with pytest.raises(ParameterError, match="expected a file name ending in"):
        plot_identification(linear, fit, val, tmp_path / "fit.jpg")
    with pytest.raises(ParameterError, match="Identification"):
        plot_identification("not a result", fit, val)


# -- the report ----------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def report(with_extras, data, tmp_path_factory):
    fit, val = data
    d = tmp_path_factory.mktemp("report")
    path = write_identification_report(with_extras, fit, val, d / "identification.html")
    return path, path.read_text(encoding="utf-8")


def test_report_is_one_file_with_the_tables_numbers(report, with_extras):
    path, page = report
    assert [p.name for p in path.parent.iterdir()] == ["identification.html"]
    assert page.startswith("<!DOCTYPE html>") and page.rstrip().endswith("</html>")
    assert path.stat().st_size < 3_000_000
    for key, _ in RI.IDENTIFICATION_SECTIONS:
        assert f'id="{key}"' in page and f'href="#{key}"' in page
    for name in with_extras.names:
        assert f"<code>{name}</code>" in page
    for name in with_extras.ratios:
        assert f"<code>{name}</code>" in page
    for name, rms, rms0 in zip(with_extras.validation, with_extras.heldout_rms, with_extras.heldout_rms0):
        assert f"<code>{name}</code>" in page
        assert f"{rms:.4g} rad" in page and f"{rms0:.4g} rad" in page
    assert f"{with_extras.heldout_median:.4g} rad" in page
    assert "[−2.000°, 2.000°]" in page and "a note on the skew angle" in page
    for u in with_extras.undetermined:
        assert u.split(" (")[0] in page
    assert "skewpend simulate --config fit.toml" in page and "--out fit.toml" in page
    assert page.count('src="data:image/png;base64,') == 1


def test_report_references_nothing_outside_itself(report):
    _, page = report
    markup = re.sub(r"<(script|style)\b[^>]*>.*?</\1>", "", page, flags=re.S | re.I)
    refs = re.findall(r"""\b(?:src|href|poster|data)\s*=\s*["']([^"']*)["']""", markup, flags=re.I)
    assert refs
    for ref in refs:
        assert ref.startswith(("data:", "#")), ref[:80]
    assert not re.search(r"""(?:src|href)\s*=\s*["']?\s*(?:https?:)?//""", page, flags=re.I)
    styles = "".join(re.findall(r"<style\b[^>]*>(.*?)</style>", page, flags=re.S))
    assert not re.search(r"url\(\s*['\"]?(?!data:)", styles)
    assert "@import" not in page and re.search(r"<script\b|<link\b", page) is None


def test_report_written_atomically(linear, data, tmp_path, monkeypatch):
    fit, val = data
    out = tmp_path / "r.html"
    out.write_text("old")

    def boom(r):
        raise RuntimeError("boom")

    monkeypatch.setattr(RI, "_section_use", boom)  # a failure while the page is built
    with pytest.raises(RuntimeError):
        write_identification_report(linear, fit, val, out)
    assert out.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["r.html"]
    monkeypatch.undo()

    class Failing(str):
        def encode(self, *args, **kwargs):
            raise RuntimeError("disk full")

    monkeypatch.setattr(RI, "identification_html", lambda *a: Failing("<html>"))  # inside the atomic write
    with pytest.raises(RuntimeError):
        write_identification_report(linear, fit, val, out)
    assert out.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == ["r.html"]
    with pytest.raises(ParameterError):
        write_identification_report(linear, fit, val, tmp_path / "r.txt")
    assert [p.name for p in tmp_path.iterdir()] == ["r.html"]
