"""Graphics files whose drawing fits the page (issue 27): every figure pointax writes,
as PostScript, EPS and PDF, through every writer (save_figure, ``pointax plot``,
``pointax fit --plot``, TPOINT's ``GC P FILE``).

The checks read the files themselves, never pointax: the DSC header of a PostScript
file (``%%DocumentPaperSizes``, ``%%Orientation``, ``%%BoundingBox``), the operators
that place the figure on the page (``translate``, ``rotate``, ``scale`` and the
figure's ``rectclip``, which clips everything drawn to the figure's rectangle; they
are composed here as 2-D affine maps), and a PDF's ``/MediaBox``. Paper sizes are
typed in (PostScript points, 72 per inch).
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("matplotlib", reason="matplotlib (pointax[plot]) is not installed")

import pointax as px  # noqa: E402
from pointax.cli import main  # noqa: E402
from pointax.plots import fit_figure, save_figure, tpoint_graph  # noqa: E402

from conftest import MMT_DAT  # noqa: E402

PAPER_PT = {"letter": (612.0, 792.0), "a4": (8.27 * 72, 11.69 * 72), "legal": (612.0, 1008.0)}
"""Portrait paper, points (matplotlib's sizes: letter 8.5 x 11 in, A4 8.27 x 11.69 in)."""

pytestmark = pytest.mark.filterwarnings("ignore:The PostScript backend does not support transparency")


# --------------------------------------------------------------------------- readers


def _header(text: str, key: str) -> str | None:
    m = re.search(rf"^%%{key}: (.*)$", text, re.M)
    return m.group(1).strip() if m else None


def drawing_extent(text: str) -> tuple[float, float, float, float]:
    """The page box that the figure's clip rectangle maps to, from the operators
    between the page start and ``rectclip`` (everything drawn lies inside it)."""
    start = text.find("%%Page: 1 1")
    start = text.find("%%EndProlog") if start < 0 else start
    assert start >= 0, "no page start in the PostScript"
    ctm = np.eye(3)
    for line in text[start:].splitlines()[1:]:
        words = line.split()
        if words[-1:] == ["translate"]:
            tx, ty = map(float, words[:2])
            ctm = ctm @ np.array([[1, 0, tx], [0, 1, ty], [0, 0, 1]])
        elif words[-1:] == ["rotate"]:
            a = math.radians(float(words[0]))
            ctm = ctm @ np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
        elif words[-1:] == ["scale"]:
            sx, sy = map(float, words[:2])
            ctm = ctm @ np.diag([sx, sy, 1.0])
        elif words[-1:] == ["rectclip"]:
            x, y, w, h = map(float, words[:4])
            corners = np.array([[x, y, 1], [x + w, y, 1], [x, y + h, 1], [x + w, y + h, 1]]).T
            page = (ctm @ corners)[:2]
            return (page[0].min(), page[1].min(), page[0].max(), page[1].max())
        elif words and words[0] not in ("mpldict", "gsave"):
            break
    raise AssertionError("no figure clip rectangle after the page start")


def check_postscript(path: Path, size_in, paper: str = "letter") -> dict:
    """A .ps file on ``paper``: the drawing lies on the page and within the declared
    bounding box, which lies on the page; returns what was read."""
    text = path.read_text("latin-1")
    assert text.startswith("%!PS-Adobe-3.0\n")
    assert _header(text, "DocumentPaperSizes") == paper
    orientation = _header(text, "Orientation")
    assert orientation in ("Portrait", "portrait", "Landscape", "landscape")
    pw, ph = PAPER_PT[paper]
    bbox = [int(v) for v in _header(text, "BoundingBox").split()]
    hires = [float(v) for v in _header(text, "HiResBoundingBox").split()]
    extent = drawing_extent(text)
    assert 0 <= bbox[0] and 0 <= bbox[1] and bbox[2] <= pw and bbox[3] <= ph, (path.name, bbox, (pw, ph))
    assert 0 <= extent[0] and 0 <= extent[1] and extent[2] <= pw + 1e-6 and extent[3] <= ph + 1e-6, extent
    np.testing.assert_allclose(hires, extent, atol=1e-3)  # the header tells where the drawing is
    assert bbox[0] <= extent[0] + 1e-6 and bbox[1] <= extent[1] + 1e-6
    assert extent[2] <= bbox[2] + 1e-6 and extent[3] <= bbox[3] + 1e-6
    w, h = (72 * x for x in size_in)
    dw, dh = extent[2] - extent[0], extent[3] - extent[1]
    landscape = orientation.lower() == "landscape"
    scale = (dh / w) if landscape else (dw / w)
    # The drawing keeps the figure's proportions (turned a quarter in landscape).
    assert (dw / dh) == pytest.approx((h / w) if landscape else (w / h), rel=1e-6)
    assert scale <= 1 + 1e-9
    # Centred on the page.
    assert extent[0] + extent[2] == pytest.approx(pw, abs=1e-3) and extent[1] + extent[3] == pytest.approx(ph, abs=1e-3)
    fits_upright = w <= pw - 36 and h <= ph - 36
    if fits_upright:
        assert not landscape and scale == pytest.approx(1.0)
    elif w > h:
        assert landscape, f"{path.name}: a wide figure ({w / 72} x {h / 72} in) not turned"
    return {"orientation": orientation.lower(), "scale": scale, "bbox": bbox, "extent": extent}


def check_eps(path: Path, size_in) -> None:
    """An EPS's page is its bounding box: the figure's own size at the origin."""
    text = path.read_text("latin-1")
    assert text.startswith("%!PS-Adobe-3.0 EPSF-3.0\n")
    bbox = [int(v) for v in _header(text, "BoundingBox").split()]
    w, h = (72 * x for x in size_in)
    assert bbox[:2] == [0, 0] and bbox[2] == math.ceil(w - 1e-9) and bbox[3] == math.ceil(h - 1e-9)
    extent = drawing_extent(text)
    assert extent[0] >= 0 and extent[1] >= 0 and extent[2] <= bbox[2] + 1e-6 and extent[3] <= bbox[3] + 1e-6


def pdf_media_boxes(path: Path) -> list[list[float]]:
    data = path.read_bytes()
    assert data[:5] == b"%PDF-"
    boxes = re.findall(rb"/MediaBox\s*\[\s*([-\d.\s]+)\]", data)
    return [[float(v) for v in box.split()] for box in boxes]


def check_pdf(path: Path, sizes_in) -> None:
    boxes = pdf_media_boxes(path)
    assert len(boxes) == len(sizes_in)
    for box, (w, h) in zip(boxes, sizes_in):
        np.testing.assert_allclose(box, [0, 0, 72 * w, 72 * h], atol=0.01)


def check_drawn_within_figure(fig) -> None:
    """Every artist's extent (text included) lies inside the figure, so inside the
    page of an EPS or PDF (whose page is the figure) and of the drawing's box."""
    renderer = fig.canvas.get_renderer()
    fig.draw(renderer)
    tight = fig.get_tightbbox(renderer)  # inches
    w, h = fig.get_size_inches()
    tol = 0.02
    assert tight.x0 >= -tol and tight.y0 >= -tol and tight.x1 <= w + tol and tight.y1 <= h + tol, (tight, (w, h))


# --------------------------------------------------------------------------- figures


@pytest.fixture(scope="module")
def mmt():
    run = px.io.read_tpoint(MMT_DAT, azimuth="S-E")
    model = px.AltAz(px.terms.tpoint("IA IE NPAE CA AN AW TF TX"), azimuth="S-E")
    return run.observations, px.fit(model, run.observations)


def write_all(fig, tmp_path: Path, stem: str) -> dict:
    size = tuple(fig.get_size_inches())
    ps, eps, pdf = (tmp_path / f"{stem}.{ext}" for ext in ("ps", "eps", "pdf"))
    said = save_figure(fig, ps)
    assert "letter" in said
    read = check_postscript(ps, size)
    np.testing.assert_array_equal(fig.get_size_inches(), size)  # the figure is left as it was
    save_figure(fig, eps)
    check_eps(eps, size)
    save_figure(fig, pdf)
    check_pdf(pdf, [size])
    check_drawn_within_figure(fig)
    return read


def test_page_layout_numbers():
    """16 x 8 in on letter (8.5 x 11 in, 0.25 in margins: 8 x 10.5 in of room): upright
    it would shrink to 8/16 = 50%, turned to 10.5/16 = 65.6%: landscape, 378 x 756 pt,
    centred at (117, 18). 6.5 x 6.5 fits upright at 100%."""
    from pointax.plots.save import page_layout

    wide = page_layout((16.0, 8.0), "letter")
    assert (wide.orientation, wide.scale) == ("landscape", pytest.approx(10.5 / 16))
    np.testing.assert_allclose(wide.bbox, [117, 18, 495, 774])
    square = page_layout((6.5, 6.5), "letter")
    assert (square.orientation, square.scale) == ("portrait", 1.0)
    np.testing.assert_allclose(square.bbox, [72, 162, 540, 630])
    turned = page_layout((10.0, 7.0), "letter")  # fits only turned: landscape at full size
    assert (turned.orientation, turned.scale) == ("landscape", 1.0)
    np.testing.assert_allclose(turned.bbox, [54, 36, 558, 756])
    with pytest.raises(ValueError, match="unknown paper type 'tabloidx'"):
        page_layout((5, 5), "tabloidx")


@pytest.mark.parametrize("kind", ["summary", "residuals", "sky", "scatter", "histogram", "tpoint9"])
def test_fit_figures_fit_the_page(mmt, tmp_path, kind):
    obs, result = mmt
    read = write_all(fit_figure(result, obs, kind), tmp_path, kind)
    if kind in ("summary", "residuals", "histogram", "tpoint9"):
        assert read["scale"] < 1 and read["orientation"] == "landscape"


@pytest.mark.parametrize("command", ["G S A", "G AM Z", "GSMAP", "GHIST", "GSCAT", "A9"])
def test_tpoint_graphs_fit_the_page(mmt, tmp_path, command):
    obs, result = mmt
    write_all(tpoint_graph(command, result, obs), tmp_path, re.sub(r"\W", "", command))


def test_heliostat_network_and_families_figures_fit_the_page(tmp_path):
    from pointax.analysis.comparison import Comparison, FamilyStats
    from pointax.fitting.statistics import AxisRMS
    from pointax.analysis.heliostat import HeliostatCalibration
    from pointax.analysis.network import NetworkResult
    from pointax.plots import families_figure, heliostat_figure, network_figure

    rng = np.random.default_rng(1)
    before, after, loo = (rng.uniform(1, 20, 18) * 1e-3 for _ in range(3))
    cal = HeliostatCalibration(tuple(f"s{i}" for i in range(18)), None, before, after, loo, np.zeros(18, bool), np.ones(18, bool))
    write_all(heliostat_figure(cal), tmp_path, "heliostat")
    sites = tuple(
        {"site": f"site{i:02d}", "format": "tpoint", "status": "converged", "reason": "", "sky_rms_arcsec": 1.0 + i % 5}
        for i in range(70)
    )
    fig = network_figure(NetworkResult("m.csv", sites))
    assert fig.get_size_inches()[0] == 24.0  # the widest figure pointax draws
    assert write_all(fig, tmp_path, "network")["scale"] < 0.5
    arc = math.pi / 180 / 3600

    def row(label, m):
        return FamilyStats(label, None, object(), m, AxisRMS(0, 0, 6 * arc, 60), 0.0, AxisRMS(0, 0, 7 * arc, 20), 0.0, 0.0, 1.0 * m, {}, (), True)

    comparison = Comparison(tuple(row(f"family{i}", 4 + i) for i in range(6)), "holdout", "60 + 20", 60, 20, "sky", ("az", "el"))
    write_all(families_figure(comparison), tmp_path, "families")


def test_other_paper_and_matplotlib_papersize(mmt, tmp_path):
    import matplotlib as mpl

    obs, result = mmt
    fig = fit_figure(result, obs, "summary")
    save_figure(fig, tmp_path / "a4.ps", papertype="A4")
    check_postscript(tmp_path / "a4.ps", (16, 8), "a4")
    with mpl.rc_context({"ps.papersize": "legal"}):
        save_figure(fig, tmp_path / "legal.ps")
    check_postscript(tmp_path / "legal.ps", (16, 8), "legal")
    with pytest.raises(ValueError, match="unknown paper type"):
        save_figure(fig, tmp_path / "bad.ps", papertype="napkin")
    assert not (tmp_path / "bad.ps").exists()


def test_unfamiliar_postscript_falls_back_to_a_smaller_figure(mmt, tmp_path, monkeypatch):
    """Where matplotlib's PostScript lacks the lines the scaling edits, the figure
    itself is drawn at the page's size instead, and left at its own size after."""
    from pointax.plots import save as save_module

    monkeypatch.setattr(save_module, "_scaled_postscript", lambda text, layout: None)
    obs, result = mmt
    fig = fit_figure(result, obs, "histogram")
    said = save_figure(fig, tmp_path / "h.ps")
    assert "at " not in said.split(",")[1]  # drawn at full size on the page
    read = check_postscript(tmp_path / "h.ps", (14 * 10.5 / 14, 4.5 * 10.5 / 14))
    assert read["orientation"] == "landscape" and read["scale"] == pytest.approx(1.0)
    np.testing.assert_array_equal(fig.get_size_inches(), [14.0, 4.5])


# --------------------------------------------------------------------------- writers


def test_pointax_plot_postscript_fits_the_page(tmp_path, capsys):
    out = tmp_path / "x.ps"
    assert main(["plot", str(MMT_DAT), "--azimuth", "S-E", "-o", str(out)]) == 0
    assert "letter landscape" in capsys.readouterr().out
    check_postscript(out, (16, 8))
    a9 = tmp_path / "a9.ps"
    assert main(["plot", str(MMT_DAT), "--azimuth", "S-E", "--kind", "tpoint9", "-o", str(a9)]) == 0
    check_postscript(a9, (15, 14))
    assert main(["plot", str(MMT_DAT), "--azimuth", "S-E", "--kind", "sky", "--kind", "histogram", "-o", str(tmp_path / "two.eps")]) == 0
    check_eps(tmp_path / "two-sky.eps", (7.5, 7.5))
    check_eps(tmp_path / "two-histogram.eps", (14, 4.5))
    assert main(["plot", str(MMT_DAT), "--azimuth", "S-E", "--kind", "sky", "--kind", "tpoint9", "-o", str(tmp_path / "two.pdf")]) == 0
    check_pdf(tmp_path / "two.pdf", [(7.5, 7.5), (15, 14)])


def test_fit_plot_postscript_fits_the_page(tmp_path, capsys):
    out = tmp_path / "fit.ps"
    assert main(["fit", str(MMT_DAT), "--azimuth", "S-E", "--plot", str(out)]) == 0
    check_postscript(out, (16, 8))


def test_tpoint_gc_p_file_fits_the_page(tmp_path, capsys):
    script = tmp_path / "gc.ptp"
    script.write_text(f"indat {MMT_DAT}\nuse IA IE\nfit\ng s a\ngc p one.ps\na9\ngc p nine.ps\ngc nine.eps\n")
    assert main(["tpoint", "--azimuth", "S-E", str(script)]) == 0
    check_postscript(tmp_path / "one.ps", (8, 5))
    check_postscript(tmp_path / "nine.ps", (15, 14))
    check_eps(tmp_path / "nine.eps", (15, 14))
