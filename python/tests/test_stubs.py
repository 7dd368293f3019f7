"""The type stubs (gelenk/_gelenk.pyi) describe the extension module as it is: every public name
has a stub and every stub a real object, the parameters are the same, and each docstring in the
stubs (what an IDE shows) is the one `help()` shows (the Rust doc comment)."""

import ast
import inspect
from pathlib import Path

import pytest

import gelenk
import gelenk._gelenk as ext

STUB = Path(gelenk.__file__).with_name("_gelenk.pyi")


def stubs():
    """The stub's top-level definitions: name -> list of ast nodes (overloads repeat a name)."""
    found = {}
    for node in ast.parse(STUB.read_text(encoding="utf-8")).body:
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            found.setdefault(node.name, []).append(node)
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            found.setdefault(node.target.id, []).append(node)
    return found


def members(cls_node):
    """A stub class's methods and properties: name -> list of FunctionDef (getter and setter)."""
    found = {}
    for node in cls_node.body:
        if isinstance(node, ast.FunctionDef):
            found.setdefault(node.name, []).append(node)
    return found


def is_setter(node):
    return any(isinstance(d, ast.Attribute) and d.attr == "setter" for d in node.decorator_list)


def runtime_member(cls, name):
    """A class's attribute as defined: the property itself, the function of a static method."""
    attr = inspect.getattr_static(cls, name)
    return attr.__func__ if isinstance(attr, staticmethod) else attr


def public(obj):
    return {n for n in dir(obj) if not n.startswith("_")}


def stub_parameters(node):
    args = node.args
    names = [a.arg for a in args.posonlyargs + args.args + args.kwonlyargs]
    return [n for n in names if n != "self"]


def runtime_parameters(obj):
    return [n for n in inspect.signature(obj).parameters if n not in ("self", "$self")]


def docstring(node):
    doc = ast.get_docstring(node, clean=True)
    return doc


def test_every_public_name_has_a_stub_and_every_stub_names_a_real_object():
    top = stubs()
    assert public(ext) - {"__version__"} <= set(top), f"no stub for {sorted(public(ext) - set(top))}"
    assert set(top) <= public(ext) | {"Array", "PathLike", "Index", "__version__"}, \
        f"stubs of nothing: {sorted(set(top) - public(ext))}"
    for name, (node, *_) in top.items():
        if isinstance(node, ast.ClassDef):
            cls = getattr(ext, name)
            stubbed = set(members(node)) - {"__init__"}
            inherited = {n for base in cls.__mro__[1:] for n in public(base)}
            assert public(cls) - inherited <= stubbed, \
                f"{name}: no stub for {sorted(public(cls) - inherited - stubbed)}"
            assert stubbed <= public(cls), f"{name}: stubs of nothing: {sorted(stubbed - public(cls))}"


def test_stub_parameters_are_the_runtime_ones():
    checked = 0
    for name, nodes in stubs().items():
        obj = getattr(ext, name, None)
        if isinstance(nodes[0], ast.FunctionDef):
            for node in nodes:  # each overload
                assert stub_parameters(node) == runtime_parameters(obj), name
                checked += 1
        elif isinstance(nodes[0], ast.ClassDef):
            for member, defs in members(nodes[0]).items():
                if member == "__init__":
                    assert stub_parameters(defs[0]) == runtime_parameters(obj), f"{name}()"
                    checked += 1
                    continue
                attr = inspect.getattr_static(obj, member)
                if callable(attr) or isinstance(attr, staticmethod):
                    assert stub_parameters(defs[0]) == runtime_parameters(getattr(obj, member)), \
                        f"{name}.{member}"
                    checked += 1
    assert checked > 40


def test_stub_docstrings_are_the_runtime_docstrings():
    """Each docstring in the stub equals `help()`'s, and every public object has one."""
    checked = 0
    for name, nodes in stubs().items():
        if isinstance(nodes[0], ast.AnnAssign):
            continue
        obj = getattr(ext, name)
        want = inspect.cleandoc(obj.__doc__ or "")
        assert want, f"{name} has no docstring"
        docs = [docstring(n) for n in nodes if docstring(n)]
        assert docs and all(d == want for d in docs), f"stub docstring of {name} differs:\n{want}"
        checked += 1
        if isinstance(nodes[0], ast.ClassDef):
            for member, defs in members(nodes[0]).items():
                if member == "__init__":
                    assert docstring(defs[0]) is None, f"{name}.__init__: documented on the class"
                    continue
                want = inspect.cleandoc(runtime_member(obj, member).__doc__ or "")
                assert want, f"{name}.{member} has no docstring"
                getter = [d for d in defs if not is_setter(d)][0]
                assert docstring(getter) == want, f"stub docstring of {name}.{member} differs:\n{want}"
                checked += 1
    assert checked > 60


@pytest.mark.parametrize("name", sorted(public(gelenk.problems)))
def test_the_problems_module_is_documented(name):
    obj = getattr(gelenk.problems, name)
    if inspect.isfunction(obj) or inspect.isclass(obj):
        if obj.__module__ == "gelenk.problems":
            assert inspect.getdoc(obj), f"gelenk.problems.{name} has no docstring"
