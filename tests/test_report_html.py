"""The results page: built from the files the experiments wrote, every table and figure on it."""

from __future__ import annotations

from html.parser import HTMLParser

from sensact.evaluate.bars import at_most, not_scored, within_factor
from sensact.io.atomic import write_bytes, write_json, write_text
from sensact.report.html_report import folder_scorecards, tables_from_markdown, write_html_report
from sensact.report.tables import scorecard_table, to_markdown

TABLES = [
    ("Table 3.1 <sim> & more", ["quantity", "thesis", "ours"], [["sensor RMS", "3.7 mm", ""], ["a < b", "-", "x & y"]]),
    ("second", ["a", "b"], []),
]


class _Page(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.open: list[str] = []
        self.images: list[str] = []
        self.cells: list[str] = []
        self.headings: list[str] = []
        self._text: list[str] | None = None

    def handle_starttag(self, tag, attrs):
        if tag == "img":
            self.images.append(dict(attrs)["src"])
            return
        if tag not in ("meta", "br"):
            self.open.append(tag)
        if tag in ("td", "h2"):
            self._text = []

    def handle_endtag(self, tag):
        assert self.open and self.open.pop() == tag, f"</{tag}> closes {self.open[-1:]}"
        if tag in ("td", "h2") and self._text is not None:
            (self.cells if tag == "td" else self.headings).append("".join(self._text))
            self._text = None

    def handle_data(self, data):
        if self._text is not None:
            self._text.append(data)


def test_markdown_tables_read_back_exactly():
    text = to_markdown(TABLES)
    assert tables_from_markdown(text) == TABLES
    assert to_markdown(tables_from_markdown(text)) == text


def test_the_page_shows_each_experiments_tables_and_figures_in_the_thesiss_order(tmp_path):
    assert write_html_report(tmp_path) is None  # nothing written yet: no page
    write_text(tmp_path / "car.md", to_markdown(TABLES[:1]))
    write_text(tmp_path / "track1d.md", to_markdown(TABLES[1:]))
    write_text(tmp_path / "car.json", "{}")
    for name in ("fig5_3_laser_angles.png", "fig3_7_location_estimates.png", "stray.png"):
        write_bytes(tmp_path / name, b"\x89PNG\r\n\x1a\n")
    page = write_html_report(tmp_path)
    assert page == tmp_path / "index.html"
    p = _Page()
    p.feed(page.read_text(encoding="utf-8"))
    p.close()
    assert p.open == []  # every tag closed, in order
    assert [h.split(":")[0] for h in p.headings] == ["Chapter 3", "Chapter 5"]  # track1d before car
    assert p.images == ["fig3_7_location_estimates.png", "fig5_3_laser_angles.png"]  # stray.png is no one's
    assert p.cells == ["sensor RMS", "3.7 mm", "", "a < b", "-", "x & y"]  # escaped, then read back as written
    assert 'href="car.json"' in page.read_text() and 'href="track1d.json"' not in page.read_text()


def test_the_page_opens_with_every_experiments_bars_and_each_miss(tmp_path):
    cleared = at_most("laser", "laser angles, RMS over 64", 0.19, 0.544, "°", 3)
    missed = within_factor("robot1.bearing_sigma", "robot1: bearing sigma / truth's", 0.56, 1.5)
    unscored = not_scored("turtlebot.gain", "Turtlebot: action gain error", "≤ 5.00 %", "the log holds one command")
    for name, checks in (("car", [cleared]), ("real", [cleared, missed, unscored])):
        write_json(tmp_path / f"{name}.json", {"scorecard": [c.to_dict() for c in checks]})
        write_text(tmp_path / f"{name}.md", to_markdown([scorecard_table([c.to_dict() for c in checks])]))
    write_text(tmp_path / "em1d.md", to_markdown(TABLES[1:]))  # a section without a scorecard
    assert [(n, len(c)) for n, _, c in folder_scorecards(tmp_path)] == [("car", 1), ("real", 3)]
    p = _Page()
    p.feed(write_html_report(tmp_path).read_text(encoding="utf-8"))
    p.close()
    assert p.open == [] and p.headings[0] == "Bars"
    overview = p.cells[:6]
    assert overview[1:3] == ["1 of 1 cleared", "none"]
    assert overview[4:6] == ["1 of 2 cleared", "robot1: bearing sigma / truth's 0.56 (bar 0.67 to 1.50)"]
    # each section's own table, its verdicts as words
    assert p.cells[-4:] == [
        "Turtlebot: action gain error",
        "≤ 5.00 %",
        "not scored: the log holds one command",
        "not scored",
    ]
    assert "Bars: 1 of 2 cleared" in write_html_report(tmp_path).read_text(encoding="utf-8")
