"""Data flows one way: scene -> frames -> events -> detector -> metrics -> report.

``detector`` never imports ``sim`` or ``bench`` (a real camera has no ground
truth); ``sim`` never imports ``detector`` or ``bench``; the core
(``evedge/``) imports none of the three.
"""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

FORBIDDEN = {
    "detector": ("evedge.sim", "evedge.bench"),
    "sim": ("evedge.detector", "evedge.bench"),
    "evedge": ("evedge.sim", "evedge.detector", "evedge.bench"),
}


def _imports(path: Path, package: str, root: Path = ROOT):
    tree = ast.parse(path.read_text(), filename=str(path))
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name
        elif isinstance(node, ast.ImportFrom):
            if node.level == 0:
                yield node.module or ""
            else:
                # resolve relative imports against the installed package name
                parts = path.relative_to(root / package).parent.parts
                base = ["evedge"] if package == "evedge" else ["evedge", package]
                base = base + list(parts)
                up = base[: len(base) - (node.level - 1)] if node.level > 1 else base
                yield ".".join(up + ([node.module] if node.module else []))


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_no_upstream_imports(package):
    files = sorted((ROOT / package).rglob("*.py"))
    assert files, f"no Python files under {package}/"
    offenders = []
    for path in files:
        if package == "evedge" and path.name == "cli.py" and path.parent == ROOT / "evedge":
            continue  # the CLI names subcommands by string; it imports none of them
        for name in _imports(path, package):
            if name.startswith(FORBIDDEN[package]):
                offenders.append(f"{path.relative_to(ROOT)} imports {name}")
    assert not offenders, "\n".join(offenders)


def test_resolver_sees_relative_imports(tmp_path):
    # the check above must be able to fail: a relative import of ..sim from detector is caught
    (tmp_path / "detector").mkdir()
    bad = tmp_path / "detector" / "bad.py"
    bad.write_text("from ..sim import scene\nimport evedge.bench.cdm\n")
    names = list(_imports(bad, "detector", root=tmp_path))
    assert names == ["evedge.sim", "evedge.bench.cdm"]
