"""The documentation site stays a set of pages a user reads in order, and its history stays out.

- **No page of ``docs/`` is longer than 600 lines.** About 600 lines of prose and tables is what
  a reader finishes in one sitting (twenty minutes or so at the pace technical text is read);
  a longer page is a page nobody reads to its end, and is split or trimmed instead.
- **The results page is at most 250 lines.** It is where a user looks up how well and how fast
  topomap works: the current figures on one page to scan, not a report.
- **The results page has no history.** Its figures are current, each section names the command
  that makes its figures and the date they were measured (``YYYY-MM-DD``), and it uses none of
  the words of a comparison between versions ("before", "now", "previously", "used to", "no
  longer", "was", "were", "earlier"): a figure that needs them belongs in the research log,
  ``benchmarks/notes/``.
- **The site reads in order**: install, a first map, each kind of data, the results, the limits.
- **The research log is outside the site and whole**: no page of ``docs/`` links into
  ``benchmarks/notes/`` (the site is built from ``docs/`` alone), and every relative link of the
  log resolves, to a file that exists and, with a ``#fragment``, to a heading of that file.
"""

import re
import unicodedata
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
NOTES = ROOT / "benchmarks" / "notes"
RESULTS = DOCS / "results.md"
#: the most lines a page of the site may have: one sitting's reading
MAX_LINES = 600
#: the most lines the results page may have: one page to scan
MAX_RESULTS_LINES = 250
#: words that compare one version with another: history, which the results page leaves out
HISTORY_WORDS = ("before", "now", "previously", "used to", "no longer", "was", "were", "earlier")
#: the reading order of the site's first pages, as the nav lists them
READING_ORDER = ["getting-started.md", "paper.md", "worlds.md", "refinement.md", "continuous.md",
                 "robot-logs.md", "results.md", "limits.md"]


def outside_fences(text: str) -> list[str]:
    """The lines of a Markdown text that are not in a fenced code block."""
    lines, fence = [], False
    for line in text.splitlines():
        if line.startswith("```"):
            fence = not fence
        elif not fence:
            lines.append(line)
    return lines


def slug(heading: str) -> str:
    """The anchor of a heading, as Python-Markdown's ``toc`` (and GitHub) make it, or the one
    the heading names (``{#anchor}``, the ``attr_list`` extension)."""
    named = re.search(r"\{#([\w-]+)\}\s*$", heading)
    if named:
        return named.group(1)
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading).replace("`", "").replace("*", "")
    text = unicodedata.normalize("NFKD", text).encode("ascii", "ignore").decode("ascii")
    text = re.sub(r"[^\w\s-]", "", text).strip().lower()
    return re.sub(r"[-\s]+", "-", text)


def anchors(path: Path) -> set[str]:
    return {slug(line.lstrip("#").strip()) for line in outside_fences(path.read_text())
            if re.match(r"#{1,6} ", line)}


def link_targets(path: Path) -> list[str]:
    return [url for line in outside_fences(path.read_text())
            for url in re.findall(r"\]\(([^)\s]+)\)", line)]


def nav_pages(items) -> list[str]:
    """The pages of mkdocs.yml's nav, in order."""
    pages = []
    for item in items:
        for value in item.values() if isinstance(item, dict) else [item]:
            pages += nav_pages(value) if isinstance(value, list) else [value]
    return pages


@pytest.mark.parametrize("page", sorted(DOCS.glob("*.md")), ids=lambda p: p.name)
def test_no_page_is_longer_than_one_sitting(page):
    assert len(page.read_text().splitlines()) <= MAX_LINES, page.name


def test_the_results_page_fits_on_one_page():
    assert len(RESULTS.read_text().splitlines()) <= MAX_RESULTS_LINES


def test_the_results_page_has_no_history():
    text = " ".join(outside_fences(RESULTS.read_text()))
    said = [w for w in HISTORY_WORDS if re.search(rf"\b{w}\b", text, re.I)]
    assert said == []


def test_every_section_of_the_results_page_gives_its_commands_and_dates():
    sections = re.split(r"^## ", RESULTS.read_text(), flags=re.M)[1:]
    assert len(sections) >= 6
    for section in sections:
        title = section.splitlines()[0]
        assert re.search(r"`(python benchmarks/\w+\.py|topomap)\b", section), title
        assert re.search(r"\b20\d\d-\d\d-\d\d\b", section), title


def test_the_site_reads_in_order():
    config = yaml.load((ROOT / "mkdocs.yml").read_text(), Loader=yaml.BaseLoader)
    pages = nav_pages(config["nav"])
    assert [p for p in pages if p in READING_ORDER] == READING_ORDER
    assert pages.index("limits.md") < min(pages.index(p) for p in pages if p not in READING_ORDER
                                          and p != "index.md")


def test_no_page_of_the_site_links_into_the_research_log():
    linked = [(page.name, url) for page in DOCS.glob("*.md") for url in link_targets(page)
              if "notes/" in url or "benchmarks/" in url]
    assert linked == []


def test_every_link_of_the_research_log_resolves():
    notes = sorted(NOTES.glob("*.md"))
    assert len(notes) >= 4
    broken = []
    for note in notes:
        for url in link_targets(note):
            if re.match(r"[a-z]+:", url):
                continue
            path, _, fragment = url.partition("#")
            target = (note.parent / path).resolve() if path else note
            if not target.exists() or (fragment and fragment not in anchors(target)):
                broken.append((note.name, url))
    assert broken == []
