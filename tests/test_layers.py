"""The import layers of docs/architecture.md: thermal_kernel <- tdem_post <- tdem, and
yade_scripts/ (run under YADE) importing none of them. An upward import fails here."""
import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
# package -> the project packages it must not import
FORBIDDEN = {
    "thermal_kernel": {"tdem_post", "tdem", "validation", "yade_scripts"},
    "tdem_post": {"tdem", "validation"},
    # tdem may import validation: its CLI dispatches `tdem validate` (lazily) to validation/run.py
    "tdem": set(),
    "yade_scripts": {"thermal_kernel", "tdem_post", "tdem", "validation"},
}


def imported_packages(path: Path) -> set[str]:
    """Top-level names of every absolute import in a module (inside functions too)."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names.update(a.name.split(".")[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    return names


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_no_module_imports_upward(package):
    offenders = {str(p.relative_to(ROOT)): sorted(imported_packages(p) & FORBIDDEN[package])
                 for p in sorted((ROOT / package).rglob("*.py"))}
    offenders = {k: v for k, v in offenders.items() if v}
    assert not offenders, f"imports against the layers of docs/architecture.md: {offenders}"


def test_the_scan_sees_an_upward_import(tmp_path):
    bad = tmp_path / "m.py"
    bad.write_text("def f():\n    from tdem_post.fits import fit_gamma\n")
    assert "tdem_post" in imported_packages(bad)
