"""The README and the docs pages name only things that exist.

Every ``sb.<name>`` (``import spiralbayes as sb``) and every dotted ``spiralbayes.<module>[.<name>]``
written in README.md or a docs page must resolve, so a user copying a line gets the object and not an AttributeError.
"""

import importlib
import re
from pathlib import Path

import pytest

import spiralbayes as sb

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
SB_NAME = re.compile(r"(?<![\w.])sb\.([A-Za-z_]\w*(?:\.[A-Za-z_]\w*)*)")
DOTTED = re.compile(r"(?<![\w./-])spiralbayes((?:\.[A-Za-z_]\w*)+)")


def _resolve(root, parts: list[str]):
    """Follow ``parts`` from ``root`` by attribute, importing submodules on the way."""
    obj, path = root, root.__name__
    for part in parts:
        path = f"{path}.{part}"
        if hasattr(obj, part):
            obj = getattr(obj, part)
            continue
        try:
            obj = importlib.import_module(path)
        except ImportError:
            raise AttributeError(path) from None
    return obj


def _names(pattern: re.Pattern) -> list[tuple[str, str]]:
    found = set()
    for page in PAGES:
        for match in pattern.finditer(page.read_text()):
            found.add((page.name, match.group(1).lstrip(".")))
    return sorted(found)


@pytest.mark.parametrize(("page", "name", "shown"), [(page, name, f"sb.{name}") for page, name in _names(SB_NAME)]
                         + [(page, name, f"spiralbayes.{name}") for page, name in _names(DOTTED)])
def test_every_name_in_the_docs_exists(page, name, shown):
    try:
        _resolve(sb, name.split("."))
    except AttributeError:
        pytest.fail(f"{page} shows {shown}, which does not exist")


def test_the_check_finds_a_missing_name():
    with pytest.raises(AttributeError):
        _resolve(sb, ["no_such_function_here"])
    assert _resolve(sb, ["plotting", "plot_corner"]) is sb.plotting.plot_corner
