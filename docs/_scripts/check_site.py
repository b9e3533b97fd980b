"""Check the built site: every public name documented, every internal link and image
there, and every page opened in headless Chromium without a console error or a broken
image; then screenshots of the home page, one API page and one guide.

    python docs/_scripts/check_site.py docs/_build/html docs/_build/screenshots

Links and anchors are checked in the HTML itself (every ``href`` and ``src`` to a file
of the site, and the ``#anchor`` it names). Chromium (Debian's, as the HTML report's
test drives it: ``--headless --dump-dom``) then opens all pages in one process: a
harness page loads each in turn in an iframe and writes, per page, whether every image
decoded; Chromium's console log (``--enable-logging=stderr``) must hold no message.
Exit status 0 when all is well, 1 with the problems listed.
"""

from __future__ import annotations

import html.parser
import json
import re
import shutil
import subprocess
import sys
import tempfile
import zlib
from pathlib import Path
from urllib.parse import unquote, urlsplit

SCREENSHOTS = {"home.png": "index.html", "api.png": "api/generated/02_fitting.html", "guide.png": "guides/tpoint_users.html"}


class _Page(html.parser.HTMLParser):
    def __init__(self):
        super().__init__()
        self.links: list[tuple[str, str]] = []  # (attribute, value)
        self.ids: set[str] = set()

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if attrs.get("id"):
            self.ids.add(attrs["id"])
        if tag == "a" and attrs.get("name"):
            self.ids.add(attrs["name"])
        for key in ("href", "src"):
            if attrs.get(key) and tag in ("a", "img", "link", "script", "source"):
                self.links.append((tag, attrs[key]))


def parse(path: Path) -> _Page:
    page = _Page()
    page.feed(path.read_text(encoding="utf-8", errors="replace"))
    return page


def check_links(site: Path) -> list[str]:
    """Broken internal links, anchors and images of every page."""
    pages = {p.resolve(): parse(p) for p in site.rglob("*.html")}
    problems = []
    for path, page in pages.items():
        for tag, value in page.links:
            parts = urlsplit(value)
            if parts.scheme or parts.netloc or value.startswith(("mailto:", "data:", "javascript:")):
                continue  # external: not checked (the site must build offline)
            target = (path.parent / unquote(parts.path)).resolve() if parts.path else path
            if target.is_dir():
                target = target / "index.html"
            where = f"{path.relative_to(site.resolve())}: {tag} {value}"
            if not target.exists():
                problems.append(f"{where}: no such file")
            elif parts.fragment and target.suffix == ".html":
                ids = pages[target].ids if target in pages else parse(target).ids
                if unquote(parts.fragment) not in ids:
                    problems.append(f"{where}: no anchor #{parts.fragment}")
    return problems


def inventory(site: Path) -> set[str]:
    """The object names of the site's ``objects.inv``."""
    data = (site / "objects.inv").read_bytes()
    body = data.split(b"\n", 4)[4]
    return {line.split(" ", 1)[0] for line in zlib.decompress(body).decode().splitlines()}


def check_public_names(site: Path) -> list[str]:
    """Every name of ``pointax.__all__`` has an entry in the built API reference."""
    import pointax

    names = inventory(site)
    missing = []
    for name in pointax.__all__:
        target = f"pointax.{pointax._SUBMODULES[name]}" if name in pointax._SUBMODULES else f"pointax.{name}"
        if target not in names:
            missing.append(f"pointax.__all__ names {name}, but the site has no entry {target}")
    return missing


HARNESS = """<!doctype html><html><body><pre id="out"></pre><iframe id="f" width="1200" height="900"></iframe>
<script>
const pages = %s; const out = document.getElementById('out'); const frame = document.getElementById('f');
let k = 0;
function next() {
  if (k >= pages.length) { out.textContent += 'DONE\\n'; return; }
  const url = pages[k++];
  frame.onload = () => {
    let line;
    try {
      const doc = frame.contentDocument;
      const broken = Array.from(doc.images).filter(im => !(im.complete && im.naturalWidth > 0)).map(im => im.src);
      line = 'PAGE ' + url + ' images ' + doc.images.length + (broken.length ? ' BROKEN ' + broken.join(' ') : ' ok');
    } catch (e) { line = 'PAGE ' + url + ' UNREADABLE ' + e; }
    out.textContent += line + '\\n';
    setTimeout(next, 0);
  };
  frame.src = url;
}
window.addEventListener('load', next);  // after the empty iframe's own first load
</script></body></html>"""


def browser(site: Path, chromium: str) -> list[str]:
    """Open every page in headless Chromium: broken images and console messages."""
    pages = sorted(p.resolve().as_uri() for p in site.rglob("*.html"))
    with tempfile.TemporaryDirectory() as tmp:
        harness = Path(tmp) / "harness.html"
        harness.write_text(HARNESS % json.dumps(pages), encoding="utf-8")
        proc = subprocess.run(
            [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--allow-file-access-from-files",
             "--enable-logging=stderr", "--v=0", f"--user-data-dir={tmp}/profile",
             f"--virtual-time-budget={max(20000, 400 * len(pages))}", "--dump-dom", harness.as_uri()],
            capture_output=True, text=True, timeout=900,
        )
    problems = []
    if proc.returncode != 0:
        problems.append(f"chromium exited with {proc.returncode}: {proc.stderr[-2000:]}")
    report = re.search(r'<pre id="out">(.*?)</pre>', proc.stdout, flags=re.DOTALL)
    lines = re.findall(r"^PAGE .*$", report.group(1) if report else "", flags=re.MULTILINE)
    if report is None or "DONE" not in report.group(1) or len(lines) != len(pages):
        opened = {line.split()[1] for line in lines}
        problems.append(f"chromium opened {len(lines)} of {len(pages)} pages; not: {sorted(set(pages) - opened)[:10]}")
    problems += [line for line in lines if not line.endswith(" ok")]
    console = [line for line in proc.stderr.splitlines() if "CONSOLE" in line or "Uncaught" in line]
    problems += [f"console: {line}" for line in console]
    print(f"check_site: chromium opened {len(lines)} pages")
    return problems


def screenshots(site: Path, out: Path, chromium: str) -> list[str]:
    out.mkdir(parents=True, exist_ok=True)
    problems = []
    for name, page in SCREENSHOTS.items():
        path = out / name
        with tempfile.TemporaryDirectory() as tmp:
            subprocess.run(
                [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--hide-scrollbars", f"--user-data-dir={tmp}",
                 "--window-size=1280,900", "--virtual-time-budget=5000", f"--screenshot={path}", (site / page).resolve().as_uri()],
                capture_output=True, text=True, timeout=120,
            )
        if not path.exists() or path.stat().st_size < 1000:
            problems.append(f"no screenshot of {page}")
        else:
            print(f"check_site: screenshot {path} ({page})")
    return problems


def main(site: str, shots: str) -> int:
    site_path, shots_path = Path(site), Path(shots)
    problems = check_public_names(site_path) + check_links(site_path)
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        problems.append("chromium is not installed (scripts/setup.sh installs Debian's where apt-get can)")
    else:
        problems += browser(site_path, chromium) + screenshots(site_path, shots_path, chromium)
    for p in problems:
        print(f"check_site: {p}", file=sys.stderr)
    print(f"check_site: {len(list(site_path.rglob('*.html')))} pages, {len(problems)} problems")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:3]))
