"""The package as a wheel ships it: every package folder listed, every imported library declared.

The install itself (a wheel in a fresh virtual environment, run from another folder) is
``tests/install_check.py``, which ``.ci/run`` runs after the test suite."""

import ast
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
META = tomllib.loads((ROOT / "pyproject.toml").read_text())

#: import name -> distribution name, where the two differ
DISTRIBUTION = {"sklearn": "scikit-learn", "yaml": "pyyaml", "hydra": "hydra-core",
                "hydra_plugins": "hydra-optuna-sweeper"}


def _listed_packages() -> set[str]:
    return set(META["tool"]["setuptools"]["packages"])


def test_every_folder_with_an_init_is_a_listed_package():
    found = {".".join(p.parent.relative_to(ROOT).parts)
             for p in (ROOT / "topomap").rglob("__init__.py") if "__pycache__" not in p.parts}
    missing = found - _listed_packages()
    assert not missing, f"pyproject.toml's [tool.setuptools] packages leaves out {sorted(missing)}"


def test_every_config_folder_is_a_listed_package():
    folders = {p.parent for p in (ROOT / "conf").rglob("*.yaml")}
    found = {".".join(("topomap", "conf", *f.relative_to(ROOT / "conf").parts)) for f in folders}
    missing = found - _listed_packages()
    assert not missing, f"pyproject.toml's packages leaves out the config folders {sorted(missing)}"


def _requirement_names(requirements) -> set[str]:
    names = set()
    for req in requirements:
        name = req.split(";")[0]
        for sep in "<>=![ ~":
            name = name.split(sep)[0]
        names.add(name.strip().lower())
    return names


def _imported_top_level_modules() -> set[str]:
    mods = set()
    for path in (ROOT / "topomap").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                mods.update(a.name.split(".")[0] for a in node.names)
            elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
                mods.add(node.module.split(".")[0])
    return mods - set(sys.stdlib_module_names) - {"topomap"}


def test_every_imported_library_is_declared():
    declared = _requirement_names(META["project"]["dependencies"])
    for extra in META["project"]["optional-dependencies"].values():
        declared |= _requirement_names(extra)
    undeclared = {m for m in _imported_top_level_modules()
                  if DISTRIBUTION.get(m, m).replace("_", "-").lower() not in declared}
    # apsw is rosbags' own storage layer, imported only to catch its errors when rosbags has it
    undeclared -= {"apsw"}
    assert not undeclared, f"imported but not in pyproject.toml: {sorted(undeclared)}"
