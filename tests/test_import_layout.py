"""
No module of the library or its envs imports a module that imports it back (directly or through a chain), and the
library imports no task package: a task reaches it through its env's ``task_tools``.
"""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ((ROOT / "sb3_maddpg", "sb3_maddpg"), (ROOT / "envs", "sb3_maddpg_envs"))


def module_files() -> dict[str, Path]:
    modules = {}
    for folder, package in PACKAGES:
        for path in folder.rglob("*.py"):
            parts = [package, *path.relative_to(folder).with_suffix("").parts]
            modules[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return modules


def imported_modules(path: Path, modules: dict[str, Path]) -> set[str]:
    """The library modules a file imports, at the top or inside functions (``from a import b`` counts ``a.b`` if a module)."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found |= {f"{node.module}.{a.name}" if f"{node.module}.{a.name}" in modules else node.module for a in node.names}
        elif isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names}
    return {name for name in found if name in modules}


def test_no_module_imports_one_that_imports_it_back():
    modules = module_files()
    graph = {name: imported_modules(path, modules) - {name} for name, path in modules.items()}

    def reachable(start: str) -> set[str]:
        seen, stack = set(), [start]
        while stack:
            for dependency in graph[stack.pop()]:
                if dependency not in seen:
                    seen.add(dependency)
                    stack.append(dependency)
        return seen

    # a package's __init__ re-exports its modules: it is imported through, not a module with logic of its own
    plain = {name for name, path in modules.items() if path.name != "__init__.py"}
    cycles = sorted({tuple(sorted((a, b))) for a in plain for b in graph[a] & plain if a in reachable(b)})
    assert cycles == [], f"import cycles: {cycles}"
    assert len(plain) > 30  # the walk found the library


def task_package_imports(path: Path) -> list[str]:
    """
    Where a file imports the task package ``sb3_maddpg_envs``: ``import`` and ``from ... import`` statements at the
    top or inside functions, and ``import_module`` / ``__import__`` calls with the name written out.
    """
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            names = [node.module or ""] if node.level == 0 else []
        elif isinstance(node, ast.Call) and getattr(node.func, "attr", getattr(node.func, "id", None)) in (
            "import_module",
            "__import__",
        ):
            names = [arg.value for arg in node.args[:1] if isinstance(arg, ast.Constant) and isinstance(arg.value, str)]
        else:
            continue
        where = f"{path.relative_to(ROOT)}:{node.lineno}"
        found += [f"{where} {name}" for name in names if name.split(".")[0] == "sb3_maddpg_envs"]
    return found


def test_the_library_reaches_a_task_only_through_its_plug_in_point():
    # A task offers its baselines and pictures as its env's `task_tools` (sb3_maddpg/evaluation/task_tools.py); the
    # registry names env constructors by "module:attribute" strings, resolved when an env is made, as Gymnasium's does
    files = sorted((ROOT / "sb3_maddpg").rglob("*.py"))
    assert [line for path in files for line in task_package_imports(path)] == []
    assert len(files) > 30  # the walk found the library
    # the walk sees an import where there is one
    assert task_package_imports(ROOT / "tests" / "test_task_tools.py") == []
    assert task_package_imports(ROOT / "tests" / "test_eval_tensorboard.py") != []
