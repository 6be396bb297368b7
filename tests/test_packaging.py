"""Packaging: what the wheel installs (the recipes under pfbench's namespace, no top-level
``reproductions``), declared dependencies, the files a release carries, the lint that the code
passes, and dask as the optional extra ``cluster``."""
import ast
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner

ROOT = Path(__file__).resolve().parent.parent
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())
PAPERS = ("embedded", "multipdf", "rtd", "thesis")


def test_wheel_installs_the_recipes_as_pfbench_reproductions():
    """The packages setuptools finds with the project's settings: before, the wheel held a
    top-level ``reproductions`` package (a generic name that clashes with others)."""
    from setuptools import find_packages

    found = set(find_packages(str(ROOT), **PYPROJECT["tool"]["setuptools"]["packages"]["find"]))
    assert not {p for p in found if p.split(".")[0] != "pfbench"}, found
    assert {"pfbench.reproductions", *(f"pfbench.reproductions.{p}" for p in PAPERS)} <= found
    assert "*/*.csv" in PYPROJECT["tool"]["setuptools"]["package-data"]["pfbench.reproductions"]


def test_recipes_load_under_pfbench_only():
    from pfbench.recipes import discover

    recs = discover()
    assert {r.func.__module__.split(".")[:2] == ["pfbench", "reproductions"] for r in recs.values()} == {True}
    assert not [m for m in sys.modules if m.split(".")[0] == "reproductions"]


def _third_party_imports() -> set[str]:
    names = set()
    for path in (ROOT / "pfbench").rglob("*.py"):
        if "reproductions" in path.relative_to(ROOT).parts[1:2]:
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                names |= {a.name.split(".")[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names.add(node.module.split(".")[0])
    return names - set(sys.stdlib_module_names) - {"pfbench"}


#: import name -> distribution name, where they differ
DIST = {"yaml": "PyYAML", "distributed": "dask", "cupy": "cupy-cuda12x", "llvmlite": "numba"}
#: imported but deliberately not a dependency: `particles` pins an older NumPy, so it runs in its own
#: environment (.venv-particles, `make bench`) and pfbench reaches it out of process
UNDECLARED = {"particles"}


def _dist(req: str) -> str:
    return re.split(r"[<>=!\[; ]", req, maxsplit=1)[0].lower()


def test_every_imported_package_is_declared():
    """Before, PyYAML (grid files) arrived only through dask."""
    proj = PYPROJECT["project"]
    core = {_dist(r) for r in proj["dependencies"]}
    extras = {_dist(r) for reqs in proj["optional-dependencies"].values() for r in reqs}
    undeclared = {n for n in _third_party_imports() - UNDECLARED if DIST.get(n, n).lower() not in core | extras}
    assert not undeclared, f"imported by pfbench but not declared in pyproject.toml: {undeclared}"
    assert "pyyaml" in core
    assert "dask" not in core and "dask" in {_dist(r) for r in proj["optional-dependencies"]["cluster"]}
    assert "dask" in {_dist(r) for r in proj["optional-dependencies"]["test"]}  # the tests use it


def test_build_requirements_match_the_license_field():
    """``license = "MIT"`` (an SPDX expression) needs setuptools >= 77; >= 68 was declared."""
    (req,) = [r for r in PYPROJECT["build-system"]["requires"] if _dist(r) == "setuptools"]
    assert isinstance(PYPROJECT["project"]["license"], str)
    assert tuple(int(x) for x in req.split(">=")[1].split(".")) >= (77,)


def test_release_files():
    assert "MIT License" in (ROOT / "LICENSE").read_text() and "the pfbench authors" in (ROOT / "LICENSE").read_text()
    assert (ROOT / "CHANGELOG.md").read_text().startswith("# Changelog")
    assert (ROOT / "pfbench" / "py.typed").is_file()
    assert "py.typed" in PYPROJECT["tool"]["setuptools"]["package-data"]["pfbench"]


def test_citation_cites_pfbench_and_the_four_source_works():
    cff = yaml.safe_load((ROOT / "CITATION.cff").read_text(encoding="utf-8"))
    assert cff["cff-version"] == "1.2.0" and cff["type"] == "software" and cff["license"] == "MIT"
    refs = (ROOT / "docs" / "REFERENCES.md").read_text(encoding="utf-8")
    rows = {key: next(ln for ln in refs.splitlines() if ln.startswith(f"| [{key}]"))
            for key in ("Embedded", "MultiPDF", "Thesis", "RTD")}
    cited = {r["notes"].split("]")[0] + "]": r for r in cff["references"]}
    assert set(cited) == {f"[{k}]" for k in rows}
    for key, row in rows.items():
        ref = cited[f"[{key}]"]
        assert ref["title"].split(" (")[0].strip('"') in row or ref["title"].startswith("The MultiPDF"), key
        doi = re.search(r"10\.\d{4,}/[\w.()-]+\d", row)
        assert str(ref.get("doi")) == (doi.group(0) if doi else "None"), key


def test_ruff_passes():
    """The lint of pyproject.toml's [tool.ruff] (pyflakes rules): unused and undefined names."""
    pytest.importorskip("ruff")
    r = subprocess.run([sys.executable, "-m", "ruff", "check", "--no-cache", "pfbench", "reproductions"],
                       cwd=ROOT, capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr


def test_dask_executor_without_dask_is_one_line(monkeypatch, tmp_path):
    """Dask is the extra `cluster`: without it, --executor dask says how to install it."""
    from pfbench.cli import main

    monkeypatch.setitem(sys.modules, "distributed", None)  # as if not installed
    r = CliRunner().invoke(main, ["sweep", "--model", "ob1", "--runs", "1", "--steps", "3", "--particles", "10",
                                  "--method", "bootstrap", "--executor", "dask", "--out", str(tmp_path / "s.jsonl")])
    assert r.exit_code == 2, r.output
    assert r.stderr.strip() == "error: --executor dask needs Dask, which is not installed: pip install 'pfbench[cluster]'"
    assert not (tmp_path / "s.jsonl").exists()


def test_the_lazy_names_are_listed_and_the_errors_exported():
    """dir(pfbench) lacked run_filter (a notebook completed nothing), pfbench.compare raised a bare
    AttributeError and ModelError, documented, was not at the top level."""
    import pfbench

    assert {"run_filter", "FilterResult", "compare", "tasks", "models"} <= set(dir(pfbench))
    assert pfbench.ModelError.__mro__[1] is pfbench.InputError
    assert callable(pfbench.compare.make_spec) and callable(pfbench.tasks.get)
