"""The declared public API (vesicle_core.PUBLIC_API): every name imports, has a docstring, and is exactly what
docs/reference/api.md documents, so the API page cannot silently drop or add a name."""

import importlib
import re
from pathlib import Path

import pytest

import vesicle_core

ROOT = Path(__file__).resolve().parents[1]


def _resolve(dotted: str):
    module, _, name = dotted.rpartition(".")
    return getattr(importlib.import_module(module), name)


@pytest.mark.parametrize("dotted", vesicle_core.PUBLIC_API)
def test_public_name_imports_and_is_documented(dotted):
    obj = _resolve(dotted)
    assert (obj.__doc__ or "").strip(), f"{dotted} has no docstring"


def test_api_page_lists_exactly_the_public_api():
    page = (ROOT / "docs" / "reference" / "api.md").read_text()
    listed = re.findall(r"^   (vesicle_core\.[\w.]+)$", page, flags=re.M)
    assert sorted(listed) == sorted(vesicle_core.PUBLIC_API)
    assert len(set(listed)) == len(listed)
