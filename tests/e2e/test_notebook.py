"""docs/notebooks/lab-walkthrough.ipynb runs top to bottom against a real uvicorn server
and Celery worker (nbclient, a fresh Python kernel): its SI question, its 3-D sweep opened
as xarray and plotted, its fitted lab record turned into a stability answer; the
notebook's own ``assert`` lines check the answers (k_crit in closed form, classify on
either side of the critical jump, a sweep point against the single query bit for bit, the
fit against the record's true parameters)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from tests.conftest import ROOT, Redis, Server, Worker

pytestmark = pytest.mark.timeout(900)

NOTEBOOK = ROOT / "docs" / "notebooks" / "lab-walkthrough.ipynb"


def test_lab_walkthrough_runs(
    tmp_path: Path, procs: list, redis_exe: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    import nbformat
    from nbclient import NotebookClient

    # Redis as the broker: kombu's filesystem transport can hand a worker a message file
    # still being written (seen under load: the worker stops on a JSONDecodeError)
    procs.append(redis := Redis(redis_exe, tmp_path))
    procs.append(srv := Server(tmp_path, redis.url))
    procs.append(Worker(tmp_path, redis.url))
    # the kernel inherits this environment: the server's URL and our code (figures are
    # drawn by ipykernel's inline backend, headless)
    monkeypatch.setenv("RSF_URL", srv.url)
    monkeypatch.delenv("RSF_API_KEY", raising=False)
    monkeypatch.delenv("MPLBACKEND", raising=False)
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]))
    nb = nbformat.read(NOTEBOOK, as_version=4)
    for cell in nb.cells:  # the notebook is stored without outputs (clean diffs)
        assert cell.cell_type != "code" or not cell.outputs, "store the notebook without outputs"
    client = NotebookClient(
        nb,
        timeout=600,
        kernel_name="python3",
        resources={"metadata": {"path": str(NOTEBOOK.parent)}},
    )
    client.execute()  # raises CellExecutionError (with the cell and traceback) on any error
    text = "\n".join(
        o.get("text", "") for c in nb.cells if c.cell_type == "code" for o in c.outputs
    )
    assert "eps = 1.0: infinite" in text and "eps = 0.25: finite" in text, text
    assert "done 40/40 points, 0 failed" in text, text
    images = [o for c in nb.cells for o in c.get("outputs", []) if "image/png" in o.get("data", {})]
    assert len(images) >= 3  # the record, the sweep, the fit
    (tmp_path / "executed.ipynb").write_text(nbformat.writes(nb))  # for a look after a failure
