"""``archive site``: a static page that opens from the disk, the leaderboard and the ECDF first.

The page is read with the standard library's HTML parser (what comes first, that it names only files
beside it) and opened in headless Chromium where one is installed (`.ci/run` installs it with
apt-get where it can; elsewhere that test skips, saying so): there the first leaderboard table and
the ECDF figure, loaded, must lie on the first screen of a 1280 x 800 window."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import pytest

from nsbench.archive import leaderboard, load
from nsbench.archive.site import ArchiveSiteRequest, build_site
from nsbench.cli import main
from nsbench.errors import ConfigError


class _Page(HTMLParser):
    """The page's elements in order (tag, attributes) and its text."""

    def __init__(self) -> None:
        super().__init__()
        self.tags: list[tuple[str, dict[str, str | None]]] = []
        self.text: list[str] = []

    def handle_starttag(self, tag, attrs):
        self.tags.append((tag, dict(attrs)))

    def handle_data(self, data):
        self.text.append(data)


@pytest.fixture(scope="module")
def site(archive, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("site")
    outcome = build_site(ArchiveSiteRequest(archive=str(archive), out=str(out)))
    assert outcome.index == out / "index.html" and len(outcome.figures) == 1
    return out


def _parsed(site: Path) -> _Page:
    page = _Page()
    page.feed((site / "index.html").read_text(encoding="utf-8"))
    return page


def test_the_ecdf_and_the_first_leaderboard_table_come_first(site):
    tags = [t for t, _ in _parsed(site).tags]
    first_img, first_table = tags.index("img"), tags.index("table")
    second_block = [i for i, t in enumerate(tags) if t == "h2"][1]  # the runs' heading: after the block
    assert first_img < second_block and first_table < second_block
    img = dict(_parsed(site).tags[first_img][1])
    assert img["src"] == "figures/" + Path(img["src"]).parent.name + "/runtime_distribution.png"
    assert (site / img["src"]).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_page_names_only_files_beside_it_and_says_how_costs_compare(site):
    page = _parsed(site)
    links = [a.get(k) for _, a in page.tags for k in ("src", "href") if a.get(k)]
    assert links and all(not str(link).startswith(("http:", "https:", "/", "file:")) for link in links)
    assert all((site / str(link)).is_file() for link in links)
    text = " ".join(page.text)
    assert "Costs are compared only within one machine and environment" in text


def test_the_page_shows_every_leaderboard_entry(site, archive):
    board = leaderboard(load(archive))
    text = " ".join(_parsed(site).text)
    for run_id in set(board["run_id"]):
        assert text.count(run_id) >= (board["run_id"] == run_id).sum()
    headings = [f"{p}, switching-time error \u2264 {t:g}" for p, t in set(zip(board["problem"], board["target"]))]
    assert all(h in text for h in headings), headings


def test_site_on_the_command_line_and_its_bad_input(archive, tmp_path, capsys):
    assert main(["archive", "site", str(archive), "--out", str(tmp_path / "web")]) == 0
    assert "index.html (1 figure(s))" in capsys.readouterr().out
    assert main(["archive", "site", str(archive), "--out", str(archive)]) == 2
    assert "is the archive itself" in capsys.readouterr().err
    with pytest.raises(ConfigError, match="is no nsbench archive"):
        ArchiveSiteRequest(archive=str(tmp_path / "web"), out=str(tmp_path / "web2"))
    assert not (tmp_path / "web2").exists()


#: Where the page's first table and first image lie once Chromium has laid it out and loaded the image.
_PROBE = """<script>
window.addEventListener("load", () => {
  const box = (e) => { const r = e.getBoundingClientRect(); return [r.top, r.bottom, r.left, r.right]; };
  const img = document.querySelector("img"), table = document.querySelector("table");
  const out = document.createElement("pre");
  out.id = "probe";
  out.textContent = JSON.stringify({img: box(img), loaded: img.complete && img.naturalWidth > 0,
    table: box(table), rows: table.rows.length, height: window.innerHeight, width: window.innerWidth});
  document.body.appendChild(out);
});
</script>"""


def _browser() -> str | None:
    return next((b for b in ("chromium", "chromium-browser", "google-chrome") if shutil.which(b)), None)


@pytest.mark.skipif(_browser() is None, reason="no Chromium on this machine (.ci/run installs it with apt-get)")
def test_in_headless_chromium_the_leaderboard_and_the_ecdf_are_on_the_first_screen(site, tmp_path):
    page = (site / "index.html").read_text(encoding="utf-8")
    probed = site / "probed.html"  # beside the page, so that its figure paths resolve as the page's
    probed.write_text(page.replace("</body>", _PROBE + "</body>"), encoding="utf-8")
    try:
        done = subprocess.run(
            [
                _browser(),
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--window-size=1280,800",
                f"--user-data-dir={tmp_path / 'profile'}",
                "--virtual-time-budget=5000",
                "--dump-dom",
                probed.as_uri(),
            ],
            capture_output=True,
            text=True,
            timeout=120,
        )
    finally:
        probed.unlink()
    found = re.search(r'<pre id="probe">(.*?)</pre>', done.stdout, re.S)
    assert found, f"Chromium did not run the probe (exit {done.returncode}): {done.stderr[-2000:]}"
    seen = json.loads(found.group(1).replace("&quot;", '"'))
    assert seen["loaded"], seen  # the ECDF figure, a file beside the page, opened without a server
    assert seen["rows"] > 1, seen
    screen = seen["height"]
    for what in ("img", "table"):
        top, bottom, left, right = seen[what]
        assert 0 <= top < screen and right > left, (what, seen)  # its top is on the first screen
