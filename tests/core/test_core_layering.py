"""The architecture as a test: which package may import which, and no two modules that
import each other. Read from the source (every import statement, at module level or inside
a function), so a lazy import does not hide a cycle."""
from __future__ import annotations

import ast
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
PACKAGES = ("mnacore", "texture", "render", "scenes", "mna")
#: package -> the packages of ours it may import. mnacore is the torch-free core; texture and
#: render build on it and never reach the torch side (mna) or the CLI.
ALLOWED = {
    "mnacore": set(),
    "texture": {"mnacore"},
    "scenes": {"mnacore"},
    "render": {"mnacore", "texture", "scenes"},
    "mna": {"mnacore", "texture", "render", "scenes"},
}


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(REPO).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _imports(path: Path) -> set[str]:
    """Modules of ours that ``path`` imports (``from a.b import c`` counts a.b and a.b.c)."""
    tree = ast.parse(path.read_text(), str(path))
    package = _module_name(path).rsplit(".", 1)[0] if path.name != "__init__.py" else _module_name(path)
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative: resolve against this module's package
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            found.add(base)
            found |= {f"{base}.{a.name}" for a in node.names}
    return {m for m in found if m.split(".")[0] in PACKAGES}


def graph() -> dict[str, set[str]]:
    modules = {_module_name(p): p for pkg in PACKAGES for p in (REPO / pkg).rglob("*.py")}
    return {name: {m for m in _imports(path) if m in modules and m != name} for name, path in modules.items()}


def test_packages_import_only_downwards():
    bad = sorted(f"{a} -> {b}" for a, deps in graph().items() for b in deps
                 if b.split(".")[0] != a.split(".")[0] and b.split(".")[0] not in ALLOWED[a.split(".")[0]])
    assert not bad, "imports against the layering: " + ", ".join(bad)


def test_no_two_modules_import_each_other():
    g = graph()
    pairs = sorted({tuple(sorted((a, b))) for a, deps in g.items() for b in deps if a in g.get(b, set())})
    assert not pairs, f"modules that import each other: {pairs}"


def test_the_reader_sees_lazy_and_relative_imports(tmp_path):
    # the rule must be able to fail: an import inside a function, and a relative one, are found
    src = REPO / "mnacore" / "_layering_probe.py"
    src.write_text("def f():\n    import mna.fit\n    from . import frame\n")
    try:
        assert {"mna.fit", "mnacore.frame"} <= _imports(src)
    finally:
        src.unlink()
