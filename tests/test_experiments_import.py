"""
The research scripts of experiments/ still import: each loads as ``python experiments/<script>.py`` would load it
(experiments/ on ``sys.path``, for the scripts that import their siblings) without running its main, and those with a
command line print their ``--help``. A rename in the library that breaks a script fails here rather than in a run.
"""

import ast
import importlib.util
import sys
from pathlib import Path

import pytest

EXPERIMENTS = Path(__file__).resolve().parent.parent / "experiments"
SCRIPTS = sorted(EXPERIMENTS.glob("*.py"))


def has_main_guard(tree: ast.Module) -> bool:
    """Whether the module has a top-level ``if __name__ == "__main__":``."""
    return any(
        isinstance(node, ast.If)
        and isinstance(node.test, ast.Compare)
        and isinstance(node.test.left, ast.Name)
        and node.test.left.id == "__name__"
        and isinstance(node.test.comparators[0], ast.Constant)
        and node.test.comparators[0].value == "__main__"
        for node in tree.body
    )


def top_level_calls(tree: ast.Module) -> list[int]:
    """The lines of the calls made as statements at the top level (outside functions, classes and the main guard)."""
    return [node.lineno for node in tree.body if isinstance(node, ast.Expr) and isinstance(node.value, ast.Call)]


@pytest.fixture(scope="module")
def experiments_path():
    """experiments/ first on ``sys.path``, as for a script run from it; its modules are dropped again afterwards."""
    modules_before = set(sys.modules)
    sys.path.insert(0, str(EXPERIMENTS))
    yield
    sys.path.remove(str(EXPERIMENTS))
    for name in set(sys.modules) - modules_before:
        if getattr(sys.modules[name], "__file__", None) and Path(sys.modules[name].__file__).parent == EXPERIMENTS:
            del sys.modules[name]


def load_script(path: Path):
    """Import a script from its file under its own name (as its siblings import it), not as ``__main__``."""
    if path.stem in sys.modules:
        return sys.modules[path.stem]
    spec = importlib.util.spec_from_file_location(path.stem, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[path.stem] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[path.stem]
        raise
    return module


def test_there_are_scripts():
    assert len(SCRIPTS) >= 10


@pytest.mark.parametrize("path", SCRIPTS, ids=lambda path: path.name)
def test_script_imports_without_running(path, experiments_path, monkeypatch, capsys):
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    assert has_main_guard(tree), f'{path.name} has no `if __name__ == "__main__":` guard'
    assert not top_level_calls(tree), f"{path.name} makes calls at import time (lines {top_level_calls(tree)})"

    # Should a script run anyway, it would read these arguments: fail at once rather than start a run
    monkeypatch.setattr(sys, "argv", [str(path), "--no-such-flag"])
    module = load_script(path)
    assert capsys.readouterr().out == "", f"{path.name} printed at import"

    if "ArgumentParser(" not in path.read_text(encoding="utf-8"):
        return
    # The command line: argparse prints the help and exits 0 before main does any work
    monkeypatch.setattr(sys, "argv", [str(path), "--help"])
    with pytest.raises(SystemExit) as exit_info:
        module.main()
    assert exit_info.value.code == 0
    assert "usage:" in capsys.readouterr().out


def is_private(name: str) -> bool:
    """``_name`` is private; ``__name__`` (``sb3_maddpg.__main__``, the command line's module) is not."""
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


@pytest.mark.parametrize("path", SCRIPTS, ids=lambda path: path.name)
def test_script_uses_only_public_names(path):
    """No private name of the library and no helper taken from tests/: the scripts use the public API."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    private, from_tests = [], []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] in ("sb3_maddpg", "sb3_maddpg_envs"):
            if any(is_private(part) for part in node.module.split(".")):
                private.append(node.module)
            private += [f"{node.module}.{alias.name}" for alias in node.names if is_private(alias.name)]
        elif isinstance(node, ast.Attribute) and is_private(node.attr):
            private.append(f"….{node.attr}")
        elif isinstance(node, ast.Constant) and node.value == "tests":  # sys.path.insert(0, ... / "tests")
            from_tests.append(node.lineno)
    assert not private, f"{path.name} uses private names: {private}"
    assert not from_tests, f"{path.name} reaches into tests/ (lines {from_tests})"
