"""The notebook docs/notebooks/quickstart.ipynb runs from top to bottom, as a reader runs it (nbclient, a Jupyter kernel)."""

import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
NOTEBOOK = ROOT / "docs" / "notebooks" / "quickstart.ipynb"
NOTEBOOK_PACKAGES = ("nbclient", "nbformat", "ipykernel")


def _notebook_packages() -> None:
    """The notebook extra; skipped without it, except in CI (CI=true), where scripts/install.sh installs it."""
    for package in NOTEBOOK_PACKAGES:
        if os.environ.get("CI", "").lower() == "true":
            __import__(package)
        else:
            pytest.importorskip(package, reason=f'no {package}: pip install -e ".[notebook]"')
    pytest.importorskip("mpe2", reason="the notebook trains on MPE2's simple_spread (the zoo extra)")


def test_the_quickstart_notebook_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    _notebook_packages()
    import nbformat
    from nbclient import NotebookClient

    notebook = nbformat.read(NOTEBOOK, as_version=4)
    assert all(not cell.get("outputs") for cell in notebook.cells if cell.cell_type == "code"), "commit it without outputs"
    # The kernel imports this checkout's package (what an editable install gives), whatever the working directory
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    monkeypatch.setenv("MPLBACKEND", "agg")
    client = NotebookClient(notebook, timeout=120, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}})
    client.execute()

    texts = [
        output.get("text", "") + str(output.get("data", {}).get("text/markdown", ""))
        for cell in notebook.cells
        for output in cell.get("outputs", [])
    ]
    assert any(text.startswith("simple_spread: team return") for text in texts)
    assert any("| maddpg | 2 |" in text and "eta_T" in text for text in texts)  # evaluate's table
    images = [output for cell in notebook.cells for output in cell.get("outputs", []) if "image/png" in output.get("data", {})]
    assert len(images) >= 3  # the frames and the training figures
    out = tmp_path / "runs" / "notebook"
    assert (out / "uav_team.zip").is_file() and (out / "episode.gif").is_file()
    assert (out / "uav" / "monitor.csv").is_file() and (out / "evaluation" / "results.md").is_file()
