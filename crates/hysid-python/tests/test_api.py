"""Every public name of the package has a docstring (so that help() shows
it), the pure-Python ones carry type hints, and the stub of the extension
declares every public member of the extension with a docstring."""

import ast
import inspect
import pathlib

import pytest

import hysid
import hysid.plot

STUB = pathlib.Path(hysid.__file__).with_name("_hysid.pyi")


def own_members(cls):
    """The public attributes a class defines itself (not those inherited
    from object or the exception classes)."""
    for name, value in vars(cls).items():
        if not name.startswith("_"):
            yield name, value


def public():
    """(qualified name, object) of every public function, class, method
    and property of the package."""
    for name in hysid.__all__:
        obj = getattr(hysid, name)
        yield f"hysid.{name}", obj
        if inspect.isclass(obj):
            for member, value in own_members(obj):
                yield f"hysid.{name}.{member}", value
    for name, obj in vars(hysid.plot).items():
        if not name.startswith("_") and inspect.isfunction(obj) and obj.__module__ == "hysid.plot":
            yield f"hysid.plot.{name}", obj


def test_all_names_what_the_package_offers():
    assert set(hysid.__all__) == {"Estimator", "HysidError", "InputError", "MethodError", "Model", "Record",
                                  "compare", "identify", "load", "methods"}
    # The checks below walk the classes' members and hysid.plot too.
    walked = {name for name, _ in public()}
    assert {"hysid.Model.simulate", "hysid.Model.input_names", "hysid.Estimator.fit", "hysid.Estimator.score",
            "hysid.Record.from_dataframe", "hysid.plot.regions"} <= walked
    assert hysid.Estimator.__module__ == hysid.Record.__module__ == "hysid"


@pytest.mark.parametrize("name, obj", list(public()), ids=[n for n, _ in public()])
def test_every_public_name_has_a_docstring(name, obj):
    doc = inspect.getdoc(obj)
    assert doc and len(doc.split()) >= 3, f"{name} has no docstring"


def python_functions():
    """The pure-Python public functions and methods."""
    for name, obj in public():
        func = obj.__func__ if isinstance(obj, (classmethod, staticmethod)) else obj
        if inspect.isfunction(func):
            yield name, func


@pytest.mark.parametrize("name, func", list(python_functions()), ids=[n for n, _ in python_functions()])
def test_python_functions_carry_type_hints(name, func):
    signature = inspect.signature(func)
    assert signature.return_annotation is not inspect.Signature.empty, f"{name}: no return type"
    for p in signature.parameters.values():
        if p.name not in ("self", "cls") and p.kind not in (p.VAR_KEYWORD, p.VAR_POSITIONAL):
            assert p.annotation is not inspect.Signature.empty, f"{name}: parameter {p.name} has no type"


def test_arrays_are_typed_with_numpy_typing():
    hints = inspect.signature(hysid.Record.from_numpy).parameters
    assert "ArrayLike" in str(hints["u"].annotation)
    assert "NDArray[np.float64]" in str(inspect.signature(hysid.Estimator.simulate).return_annotation)
    assert "NDArray[np.float64]" in str(hysid.Record.__annotations__["u"])


def stub_classes():
    """Classes of the stub: {name: {member: docstring}}, and its functions'
    docstrings."""
    tree = ast.parse(STUB.read_text())
    classes, functions = {}, {}
    for node in tree.body:
        if isinstance(node, ast.ClassDef):
            classes[node.name] = {n.name: ast.get_docstring(n) for n in node.body
                                  if isinstance(n, ast.FunctionDef)}
            classes[node.name][None] = ast.get_docstring(node)
        elif isinstance(node, ast.FunctionDef):
            functions[node.name] = ast.get_docstring(node)
    return classes, functions


def test_the_stub_declares_the_extension_with_docstrings():
    classes, functions = stub_classes()
    for name in ("HysidError", "InputError", "MethodError", "Model"):
        assert classes[name][None], name
    declared = {k: v for k, v in classes["Model"].items() if k is not None}
    members = {name for name, _ in own_members(hysid.Model)}
    assert members == set(declared)
    assert all(declared.values()), [k for k, v in declared.items() if not v]
    extension = {n for n in dir(hysid._hysid) if not n.startswith("_") and callable(getattr(hysid._hysid, n))
                 and not inspect.isclass(getattr(hysid._hysid, n))}
    assert extension == set(functions) and all(functions.values())


def test_help_shows_the_rust_docstrings():
    text = inspect.getdoc(hysid.Model.simulate)
    assert "Free-run simulation" in text
    assert "identified on" in inspect.getdoc(hysid.Model.input_names)
