"""The conventions page cites the tests that pin each convention: every cited test must exist."""

import ast
import re
from pathlib import Path

ROOT = Path(__file__).parent.parent


def cited_tests(page: Path) -> list[tuple[str, str | None]]:
    """``(file, test name or None)`` of each test cited as `tests/...py::name` or a bare `test_name`."""
    text = page.read_text()
    out, current = [], None
    for match in re.finditer(r"`(tests/[\w/]+\.py)(?:::(\w+))?`|`(test_\w+)`", text):
        if match.group(1):
            current = match.group(1)
            out.append((current, match.group(2)))
        else:
            out.append((current, match.group(3)))
    return out


def test_every_test_cited_by_the_conventions_page_exists():
    cited = cited_tests(ROOT / "docs" / "conventions.md")
    assert len(cited) >= 8
    for file, name in cited:
        path = ROOT / file
        assert path.exists(), f"docs/conventions.md cites {file}, which does not exist"
        if name:
            names = {n.name for n in ast.parse(path.read_text()).body if isinstance(n, ast.FunctionDef)}
            assert name in names, f"docs/conventions.md cites {file}::{name}, which does not exist"
