"""The docs say true things that do not go stale: the pages table is the same in the README and
on the site's front page, no page counts the tests, and the main config's comments name every
``learner.*`` setting."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def pages_table(path: Path, prefix: str) -> list[tuple[str, str, str]]:
    rows = re.findall(r"^\| \[([^\]]+)\]\(([^)]+)\) \| (.+) \|$", path.read_text(), re.M)
    return [(title, link.removeprefix(prefix), what) for title, link, what in rows]


def test_the_readme_and_the_front_page_list_the_same_pages():
    readme = pages_table(ROOT / "README.md", "docs/")
    front = pages_table(ROOT / "docs" / "index.md", "")
    assert readme and readme == front


def test_no_page_gives_a_count_of_the_tests():
    for page in [ROOT / "README.md", *(ROOT / "docs").glob("*.md")]:
        assert not re.search(r"\b\d[\d,]* tests\b", page.read_text()), page.name


def test_the_config_comments_name_every_learner_setting():
    from topomap.app.compose.schemas import fields_of, learner_schema

    text = (ROOT / "conf" / "config.yaml").read_text()
    comment = text[text.index("# learner:"):text.index("\noutput:")]
    named = set(re.findall(r"^#   ([\w, ]+?)\s{2,}", comment, re.M))
    named = {n.strip() for group in named for n in group.split(",")} - {""}
    assert set(fields_of(learner_schema())) == named
