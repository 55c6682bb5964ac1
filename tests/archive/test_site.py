"""``archive site``: a static page that opens from the disk, the leaderboard and the ECDF first.

(Not tested in headless Chromium: no browser on this machine. The page is read with the standard
library's HTML parser: what it shows first, and that it names only files beside it.)"""

from __future__ import annotations

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
