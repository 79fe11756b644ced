"""The package's shape: entry points at the root, one folder per box of the pipeline (layers: import-linter)."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1] / "nextage_qp"

ENTRY_POINTS = {"__init__.py", "api.py", "cli.py", "errors.py", "geometry.py"}
BOXES = {"commands", "tune", "viz", "sweep", "manipulation", "experiments", "loop", "sensing", "estimation", "ik",
         "kinematics", "robots", "scene", "mobile", "native", "io", "planning"}


def test_the_package_root_holds_the_entry_points_and_one_folder_per_box():
    modules = {p.name for p in ROOT.glob("*.py")}
    folders = {p.name for p in ROOT.iterdir() if p.is_dir() and p.name != "__pycache__"}
    assert modules == ENTRY_POINTS, modules ^ ENTRY_POINTS
    assert folders == BOXES, folders ^ BOXES


def test_every_folder_is_a_package_with_a_docstring():
    for folder in [p for p in ROOT.rglob("*") if p.is_dir() and p.name != "__pycache__"]:
        init = folder / "__init__.py"
        assert init.is_file(), folder
        assert init.read_text().lstrip().startswith('"""'), init



def _assigned_attributes(tree: ast.AST, owner: str) -> set[str]:
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Assign, ast.AugAssign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for target in targets:
                for item in target.elts if isinstance(target, ast.Tuple) else [target]:
                    if isinstance(item, ast.Attribute) and isinstance(item.value, ast.Name) and item.value.id == owner:
                        found.add(item.attr)
    return found


@pytest.mark.parametrize(("module", "name"), [("manipulation/phases/push/phase.py", "Push"),
                                              ("manipulation/phases/grasp/phase.py", "Grasp")])
def test_a_state_machine_declares_its_state_in_one_place_and_nothing_else_writes_it(module, name):
    tree = ast.parse((ROOT / module).read_text())
    cls = next(n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == name)
    declared = {n.target.id for n in cls.body if isinstance(n, ast.AnnAssign) and isinstance(n.target, ast.Name)}
    undeclared = _assigned_attributes(cls, "self") - declared - {"info", "spec", "name", "t0"}
    assert not undeclared, undeclared
    for path in ROOT.rglob("*.py"):  # no function takes the phase as an argument to write its fields
        for fn in ast.walk(ast.parse(path.read_text())):
            if isinstance(fn, ast.FunctionDef):
                typed = {a.arg for a in fn.args.args if a.annotation is not None and name in ast.unparse(a.annotation)}
                for p in typed:
                    assert not _assigned_attributes(fn, p), (path, fn.name, p)
