"""The type stubs (servostack/_native.pyi) name what the extension has: every class, function and public member."""

import ast
from pathlib import Path

import servostack._native as native

STUB = Path(__file__).resolve().parents[1] / "servostack/_native.pyi"


def stub_members():
    tree = ast.parse(STUB.read_text())
    members = {}
    for node in tree.body:
        if isinstance(node, ast.ClassDef):
            members[node.name] = {n.name for n in node.body if isinstance(n, ast.FunctionDef)} - {"__init__"}
        elif isinstance(node, ast.FunctionDef):
            members[node.name] = None
        elif isinstance(node, ast.AnnAssign):
            members[node.target.id] = None
    return members


def test_every_name_of_the_extension_is_in_the_stubs_and_back():
    stubs = stub_members()
    public = {name for name in dir(native) if not name.startswith("_")}
    typed_dicts = {"Event", "ServoOutput"}  # stub-only shapes of the dicts the extension returns
    assert public == set(stubs) - typed_dicts
    for name, members in stubs.items():
        if members is None or name in typed_dicts or issubclass(getattr(native, name), Exception):
            continue
        runtime = {m for m in dir(getattr(native, name)) if not m.startswith("_")}
        assert runtime == members, name
