"""Every ``veriloc_rt.<module>[.<name>]`` a manual names exists (issue #40: scenes/README.md
named a module path that no longer existed)."""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PAGES = sorted(ROOT.glob("docs/*.md")) + [ROOT / "README.md", ROOT / "scenes" / "README.md"]
DOTTED = re.compile(r"\bveriloc_rt(?:\.[A-Za-z_][A-Za-z0-9_]*)+")


def resolves(name: str) -> bool:
    """``name`` is a module, or an attribute path under the longest importable module."""
    parts = name.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:i]))
        except ModuleNotFoundError:
            continue
        for attr in parts[i:]:
            if not hasattr(obj, attr):
                return False
            obj = getattr(obj, attr)
        return True
    return False


def test_resolver_rejects_a_missing_path():
    assert resolves("veriloc_rt.world.scene.export.write_scene")
    assert not resolves("veriloc_rt.scene.export.write_scene")
    assert not resolves("veriloc_rt.config.no_such_name")


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_named_module_path_exists(page):
    names = set(DOTTED.findall(page.read_text()))
    assert [n for n in sorted(names) if not resolves(n)] == []
