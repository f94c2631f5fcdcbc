"""Loaders of higher packages are found through entry points, never named by lower packages."""

import ast
from pathlib import Path

import stageid
from stageid.plugins import HYSTERESIS_KINDS, MODEL_FORMATS, declared, load_object

SRC = Path(stageid.__file__).parent


def test_the_entry_points_are_declared_and_load():
    formats, kinds = declared(MODEL_FORMATS), declared(HYSTERESIS_KINDS)
    assert formats == {"stageid.hysteresis/1": "stageid.hysteresis.serialization:model_from_dict"}
    assert kinds == {
        "piezo-actuator": "stageid.plants.piezo_actuator:PiezoActuator.from_dict",
        "stage": "stageid.hysteresis.stage:StageModel.from_dict",
        "preisach": "stageid.hysteresis.preisach:PreisachModel.from_dict",
    }
    from stageid.plants.piezo_actuator import PiezoActuator

    assert load_object(kinds["piezo-actuator"]) == PiezoActuator.from_dict


def _code_strings(path: Path) -> list[str]:
    """String constants of a module that are not docstrings."""
    tree = ast.parse(path.read_text())
    docs = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
                docs.add(id(body[0].value))
    return [
        n.value
        for n in ast.walk(tree)
        if isinstance(n, ast.Constant) and isinstance(n.value, str) and id(n) not in docs
    ]


def test_lower_packages_do_not_name_higher_ones_in_code():
    # an import scan cannot see "stageid.plants.x:y" strings; this test can
    higher = {"models": ("stageid.hysteresis", "stageid.plants"), "hysteresis": ("stageid.plants",)}
    for package, names in higher.items():
        for path in (SRC / package).rglob("*.py"):
            for text in _code_strings(path):
                assert not any(name in text for name in names), f"{path.name} names {text!r}"
