"""pointax report: one self-contained HTML page.

Checked structurally (html.parser: every image a data: URI holding a valid PNG, no
reference to anything outside the file, no script), numerically (the fit table and
the residual listing against numpy's least-squares solution of TPOINT's linear
equations, DESIGN.md), and, where Debian's chromium is installed, rendered in headless
Chromium: every image decodes and the console shows no error.
"""

from __future__ import annotations

import base64
import html.parser
import io
import math
import re
import shutil
import subprocess

import numpy as np
import pytest

pytest.importorskip("matplotlib", reason="matplotlib (pointax[plot]) is not installed")

from conftest import MMT_DAT  # noqa: E402

from pointax.cli import main  # noqa: E402

ARCSEC = math.pi / (180 * 3600)
MASK = "4,8"  # rows counted from 1
MASKED = [3, 7]


class Page(html.parser.HTMLParser):
    """Collects tags, attributes and table rows of a page."""

    def __init__(self):
        super().__init__()
        self.tags: list[tuple[str, dict]] = []
        self.rows: list[list[str]] = []
        self.row_class: list[str | None] = []
        self._row: list[str] | None = None
        self._cell: list[str] | None = None

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        self.tags.append((tag, attrs))
        if tag == "tr":
            self._row = []
            self.row_class.append(attrs.get("class"))
        elif tag in ("td", "th") and self._row is not None:
            self._cell = []

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None and self._row is not None:
            self._row.append("".join(self._cell).strip())
            self._cell = None
        elif tag == "tr" and self._row is not None:
            self.rows.append(self._row)
            self._row = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell.append(data)


def numpy_tpoint_fit(masked):
    """TPOINT's eight basic terms by ordinary least squares on (dA cos E, dE), the
    equations of DESIGN.md (A, E observed as the file gives them, d = observed - raw);
    returns the values (arcsec, in the order IA IE NPAE CA AN AW TF TX) and the
    residuals (n, 2) arcsec of every row."""
    import pointax as px

    run = px.io.read_tpoint(MMT_DAT, azimuth="S-E")  # angles as the file gives them, radians
    a_obs, e_obs = run.observed.T
    a_raw, e_raw = run.encoder.T
    da = np.angle(np.exp(1j * (a_obs - a_raw)))
    de = e_obs - e_raw
    c, s, t = np.cos(e_obs), np.sin(e_obs), np.tan(e_obs)
    sa, ca = np.sin(a_obs), np.cos(a_obs)
    zero, one = np.zeros_like(c), np.ones_like(c)
    # Columns: contribution of each term to (dA cos E, dE).
    cols_s = [-c, zero, -s, -one, -sa * s, -ca * s, zero, zero]
    cols_e = [zero, one, zero, zero, -ca, sa, -c, -1 / t]
    design = np.concatenate([np.stack(cols_s, 1), np.stack(cols_e, 1)])
    y = np.concatenate([da * c, de])
    keep = np.ones(len(c), bool)
    keep[masked] = False
    keep2 = np.concatenate([keep, keep])
    values, *_ = np.linalg.lstsq(design[keep2], y[keep2], rcond=None)
    r = y - design @ values
    return values / ARCSEC, np.stack([r[: len(c)], r[len(c) :]], 1) / ARCSEC


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    path = tmp_path_factory.mktemp("report") / "mmt.html"
    status = main(["report", str(MMT_DAT), "--azimuth", "S-E", "--mask", MASK, "--residuals", "tpoint", "--form", "linear",
                   "--kind", "summary", "--kind", "histogram", "--tpoint", "G Z A", "-o", str(path)])
    assert status == 0
    page = Page()
    page.feed(path.read_text(encoding="utf-8"))
    return path, page


def test_every_image_is_an_embedded_png_and_nothing_is_fetched(report):
    from PIL import Image

    path, page = report
    images = [attrs for tag, attrs in page.tags if tag == "img"]
    assert len(images) == 3  # summary, histogram, G Z A
    for attrs in images:
        src = attrs["src"]
        assert src.startswith("data:image/png;base64,")
        png = base64.b64decode(src.split(",", 1)[1], validate=True)
        assert png[:8] == b"\x89PNG\r\n\x1a\n"
        with Image.open(io.BytesIO(png)) as image:
            image.verify()
        assert attrs.get("alt")
    for tag, attrs in page.tags:
        assert tag not in ("script", "link", "iframe", "object", "embed"), tag
        for name in ("src", "href", "data", "action"):
            value = attrs.get(name) or ""
            assert not re.match(r"\s*(https?:|//|file:)", value), (tag, name, value)
    assert not re.search(r"url\(\s*['\"]?(https?:|//)", path.read_text()), "the style fetches something"


def test_fit_table_and_listing_match_numpys_least_squares(report):
    _, page = report
    values, residuals = numpy_tpoint_fit(MASKED)
    table = {r[1]: r for r in page.rows if len(r) == 5 and r[0].isdigit()}
    for name, value in zip(("IA", "IE", "NPAE", "CA", "AN", "AW", "TF", "TX"), values):
        assert float(table[name][2]) == pytest.approx(value, abs=6e-4), name  # printed to 4 decimals
    listing = [(r, cls) for r, cls in zip(page.rows, page.row_class) if cls in ("used", "masked", "outlier")]
    assert len(listing) == 80
    statuses = [cls for _, cls in listing]
    assert [i for i, s in enumerate(statuses) if s == "masked"] == MASKED
    for i, (row, cls) in enumerate(listing):
        assert int(row[0]) == i + 1
        # Every row, masked ones included, in the fit's (TPOINT's) residual form.
        np.testing.assert_allclose([float(row[4]), float(row[5])], residuals[i], atol=2e-3)
    stats = {r[0]: r[1] for r in page.rows if len(r) == 2}
    n = 78
    rms = math.sqrt(np.sum(residuals[np.setdiff1d(np.arange(80), MASKED)] ** 2) / n)
    assert float(stats["Sky RMS (arcsec)"]) == pytest.approx(rms, abs=6e-4)
    assert stats["observations used"] == "78" and stats["masked (weight 0)"] == "2"


def test_bad_output_name_is_refused_before_fitting(tmp_path, capsys):
    assert main(["report", str(MMT_DAT), "-o", str(tmp_path / "r.pdf")]) == 2
    assert "name it .html" in capsys.readouterr().err


CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.mark.skipif(CHROMIUM is None, reason="Debian's chromium is not installed (scripts/setup.sh installs it where apt-get can)")
def test_renders_in_headless_chromium_with_every_image_loaded(report, tmp_path):
    path, _ = report
    # A copy with a check appended: after load, the body gets one line per image
    # saying whether it decoded (the report itself has no script).
    probe = (
        "<script>window.addEventListener('load', () => { const out = document.createElement('pre');"
        " out.id = 'probe'; out.textContent = Array.from(document.images).map("
        "(im, k) => 'IMAGE ' + k + ' ' + (im.complete && im.naturalWidth > 0 ? 'ok' : 'BROKEN')).join('\\n');"
        " document.body.appendChild(out); });</script>"
    )
    copy = tmp_path / "probe.html"
    copy.write_text(path.read_text(encoding="utf-8").replace("</body>", probe + "</body>"), encoding="utf-8")
    proc = subprocess.run(
        [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--enable-logging=stderr", "--v=0",
         "--virtual-time-budget=5000", "--dump-dom", copy.as_uri()],
        capture_output=True, text=True, timeout=120,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = re.findall(r"IMAGE \d+ (ok|BROKEN)", proc.stdout)
    assert lines == ["ok"] * 3, proc.stdout[-2000:]
    console = [line for line in proc.stderr.splitlines() if "CONSOLE" in line or "Uncaught" in line]
    assert not console, console
