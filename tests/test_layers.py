"""The import layers of docs/architecture.md: thermal_kernel <- tdem_post <- validation <- tdem
(the command line on top: `tdem validate` imports validation, validation never imports tdem),
and yade_scripts/ (run under YADE) importing of the others only the kernel's numpy-only
modules. An upward import, an import circle, a project module loading a test, or a by-path load
not listed here fails."""
import ast
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("thermal_kernel", "tdem_post", "tdem", "validation", "yade_scripts")
# package -> the project packages it must not import ("tests": nothing imports a test module)
FORBIDDEN = {
    "thermal_kernel": {"tdem_post", "tdem", "validation", "yade_scripts", "tests"},
    "tdem_post": {"tdem", "validation", "yade_scripts", "tests"},
    "tdem": {"tests"},
    "validation": {"tdem", "tests"},       # tdem imports it (`tdem validate`): one direction
    "yade_scripts": {"tdem_post", "tdem", "validation", "tests"},
}
# What YADE's Python (Debian's, numpy but no numba) may import of thermal_kernel: modules of
# numpy and the standard library only, each checked below. A piece both sides need goes here.
YADE_SAFE = {"thermal_kernel.placement", "thermal_kernel.packing_stats",
             "thermal_kernel.contact_check", "thermal_kernel.morton"}
# The modules that load a file by path (importlib's spec_from_file_location), which no import
# scan sees, and what they load: anything else loading by path fails the test below.
LOADS_BY_PATH = {
    "thermal_kernel/packing_h5.py": "its sibling atomic.py, when itself loaded by path in YADE",
    "tdem/yade.py": "yade_scripts/ from the folder YADE will run (TDEM_YADE_SCRIPTS)",
    "yade_scripts/tdem_dump.py": "thermal_kernel/packing_h5.py, the one packing writer",
    "yade_scripts/tdem_yade.py": "thermal_kernel/packing_h5.py (h5py: not in YADE_SAFE)",
}


def imported_packages(path: Path) -> set[str]:
    """Top-level names of every absolute import in a module (inside functions too)."""
    return {name.split(".")[0] for name in imported_modules(path)}


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imported_modules(path: Path) -> set[str]:
    """Dotted names of every module a file imports (relative imports resolved; ``from a import
    b`` names ``a.b`` when that is a module of the tree, else ``a``), inside functions too."""
    here = _module_name(path).split(".") if path.is_relative_to(ROOT) else []
    package = here if path.name == "__init__.py" else here[:-1]
    names = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(package[:len(package) - node.level + 1] + ([base] if base else []))
            for a in node.names:
                sub = f"{base}.{a.name}" if base else a.name
                names.add(sub if _is_module(sub) else base)
    return names


def _is_module(dotted: str) -> bool:
    p = ROOT.joinpath(*dotted.split("."))
    return p.with_suffix(".py").exists() or (p / "__init__.py").exists()


def _sources(package: str):
    return sorted((ROOT / package).rglob("*.py"))


def import_graph() -> dict[str, set[str]]:
    """module -> the project modules it imports (each package's own files)."""
    graph = {}
    for package in PACKAGES:
        for path in _sources(package):
            graph[_module_name(path)] = {m for m in imported_modules(path)
                                         if m.split(".")[0] in PACKAGES}
    return graph


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The import circles: strongly connected sets of two or more modules (Tarjan)."""
    index, low, stack, on, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                on.discard(w)
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                found.append(sorted(group))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


# every module of tests/ by name (a test helper such as a scene module counts, not only test_*)
TEST_MODULES = {p.stem for p in (ROOT / "tests").glob("*.py")} | {"tests"}


@pytest.mark.parametrize("folder", ["bench", "tools"])
def test_scripts_import_no_test_module(folder):
    # the benchmarks and tools are run by make and by hand: what they share with the tests
    # lives in the packages (e.g. tdem/committed_beds.py), never in tests/
    offenders = {str(p.relative_to(ROOT)): sorted(imported_packages(p) & TEST_MODULES)
                 for p in sorted((ROOT / folder).rglob("*.py"))}
    offenders = {k: v for k, v in offenders.items() if v}
    assert not offenders, f"{folder}/ imports a module of tests/: {offenders}"


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_no_module_imports_upward(package):
    offenders = {str(p.relative_to(ROOT)): sorted(imported_packages(p) & FORBIDDEN[package]
                                                  | imported_packages(p) & TEST_MODULES)
                 for p in _sources(package)}
    offenders = {k: v for k, v in offenders.items() if v}
    assert not offenders, f"imports against the layers of docs/architecture.md: {offenders}"


# No circle is allowed: the last one (the solvers package and its three solvers) ended when
# the helpers they share moved to thermal_kernel/solvers/common.py.
KNOWN_CIRCLES: list = []


def test_no_import_circles():
    # e.g. thermal_kernel.scene -> boundaries -> scene (SceneError now has its own home,
    # thermal_kernel/errors.py) or boundaries.flux -> calibrate -> boundaries (the section
    # geometry's home is thermal_kernel/section.py)
    assert circles(import_graph()) == KNOWN_CIRCLES


def test_the_packages_import_each_other_one_way():
    packages = {package: {m.split(".")[0] for p in _sources(package)
                          for m in imported_modules(p)} & set(PACKAGES) - {package}
                for package in PACKAGES}
    assert circles(packages) == []
    assert "validation" in packages["tdem"] and "tdem" not in packages["validation"]


def test_yade_scripts_import_only_the_numpy_only_kernel_modules():
    used = {m for p in _sources("yade_scripts") for m in imported_modules(p)
            if m.split(".")[0] == "thermal_kernel"}
    assert used <= YADE_SAFE, f"yade_scripts imports {sorted(used - YADE_SAFE)}: YADE's Python " \
                              "has no numba; add a numpy-only module to YADE_SAFE, or load by path"
    for module in YADE_SAFE:
        path = ROOT.joinpath(*module.split(".")).with_suffix(".py")
        outside = {m for m in imported_modules(path)
                   if m.split(".")[0] not in sys.stdlib_module_names | {"numpy", "__future__"}
                   and m not in YADE_SAFE}
        assert not outside, f"{module} is imported under YADE but imports {sorted(outside)}"


def test_only_the_listed_modules_load_files_by_path():
    loaders = {str(p.relative_to(ROOT)) for package in PACKAGES for p in _sources(package)
               if "spec_from_file_location" in p.read_text()}
    assert loaders == set(LOADS_BY_PATH)


def test_the_scan_sees_an_upward_import(tmp_path):
    bad = tmp_path / "m.py"
    bad.write_text("def f():\n    from tdem_post.fits import fit_gamma\n")
    assert "tdem_post" in imported_packages(bad)


def test_the_scan_resolves_relative_imports_and_finds_a_circle():
    flux = ROOT / "thermal_kernel" / "boundaries" / "flux.py"
    assert {"thermal_kernel.section", "thermal_kernel.boundaries.base"} <= imported_modules(flux)
    assert "thermal_kernel.boundaries" in imported_modules(ROOT / "thermal_kernel" / "problem.py")
    assert circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
