"""The layering rules that import-linter does not check: no private name crosses a module.

A name with a leading underscore is its module's own; another module (a test included) that
imports it, or reads it as an attribute of an imported module or of an object another module
built, couples itself to an implementation detail. Found with ``ast`` over the package, the
tests and the scripts. (The layers and the absence of cycles: ``lint-imports``, contracts in
pyproject.toml.)
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SOURCES = sorted([*(ROOT / "veriloc_rt").rglob("*.py"), *(ROOT / "tests").rglob("*.py"),
                  *(ROOT / "scripts").glob("*.py")])


#: private names still taken across modules, each (file, name): none is left; an entry would
#: make the test fail when it disappears too (so the list only shrinks).
PENDING: set[tuple[str, str]] = set()


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def private_uses(source: str) -> list[tuple[int, str]]:
    """``(line, name)`` of every private name this module takes from elsewhere: imported from a
    module, or read as an attribute of anything but ``self``/``cls`` (an object's own private
    attributes are its class's business; the class is defined in this module or it is not)."""
    tree = ast.parse(source)
    own = {n.name for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.ClassDef,
                                                              ast.AsyncFunctionDef))}
    own |= {t.id for n in ast.walk(tree) if isinstance(n, (ast.Assign, ast.AnnAssign))
            for t in (n.targets if isinstance(n, ast.Assign) else [n.target])
            if isinstance(t, ast.Name)}
    own_attrs = {t.attr for n in ast.walk(tree) if isinstance(n, (ast.Assign, ast.AnnAssign))
                 for t in (n.targets if isinstance(n, ast.Assign) else [n.target])
                 if isinstance(t, ast.Attribute)}
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            out += [(node.lineno, a.name) for a in node.names if _private(a.name)]
            if node.module and any(_private(p) for p in node.module.split(".")):
                out.append((node.lineno, node.module))
        elif isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names
                    if any(_private(p) for p in a.name.split("."))]
        elif isinstance(node, ast.Attribute) and _private(node.attr):
            base = node.value
            if isinstance(base, ast.Name) and base.id in ("self", "cls"):
                continue
            if node.attr in own or node.attr in own_attrs:   # this module's own class or name
                continue
            out.append((node.lineno, node.attr))
    return out


def test_the_check_finds_what_it_looks_for():
    src = ("from veriloc_rt.x import _a, b\n"
           "import veriloc_rt._hidden\n"
           "tx = make()\n"
           "tx._slots(3)\n"
           "class C:\n"
           "    def f(self):\n"
           "        self._own = 1\n"
           "        return self._own, C._helper\n"
           "    @staticmethod\n"
           "    def _helper():\n"
           "        pass\n"
           "obj = C()\n"
           "obj._own\n")
    assert private_uses(src) == [(1, "_a"), (2, "veriloc_rt._hidden"), (4, "_slots")]


def test_no_private_name_crosses_a_module():
    found = {(str(path.relative_to(ROOT)), name): line for path in SOURCES
             for line, name in private_uses(path.read_text())}
    new = sorted(f"{f}:{line}: {name}" for (f, name), line in found.items() if (f, name) not in PENDING)
    assert new == [], "private names used outside their module"
    assert sorted(PENDING - found.keys()) == [], "no longer used: remove from PENDING"
