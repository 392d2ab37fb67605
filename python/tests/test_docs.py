"""Every Python snippet of docs/python.md runs (in order, one namespace, as a reader would
run them), and every docstring example of the package holds."""

from __future__ import annotations

import doctest
import os
import re
from pathlib import Path

import pytest

import ringsync
from ringsync import _dask, _path, _plan, _run, _scenario, _sweep

DOC = Path(__file__).resolve().parents[2] / "docs" / "python.md"


def snippets() -> list[str]:
    return re.findall(r"^```python\n(.*?)^```", DOC.read_text(), flags=re.S | re.M)


def test_docs_python_md_runs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    blocks = snippets()
    assert len(blocks) >= 4
    monkeypatch.chdir(tmp_path)  # files the walk-through writes land here
    import matplotlib

    matplotlib.use("Agg")  # no display here: figures are drawn and saved, not shown
    # Run as a script runs them: the Dask snippet's `if __name__ == "__main__":` block too.
    namespace: dict[str, object] = {"__name__": "__main__"}
    for i, code in enumerate(blocks):
        try:
            exec(compile(code, f"{DOC.name}, snippet {i + 1}", "exec"), namespace)
        except Exception as e:  # name the snippet
            raise AssertionError(f"docs/python.md snippet {i + 1} failed:\n{code}") from e


@pytest.mark.parametrize("module", [ringsync, _scenario, _run, _sweep, _plan, _dask, _path], ids=lambda m: m.__name__)
def test_docstring_examples(module: object, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    r = doctest.testmod(module, extraglobs={"ringsync": ringsync, "os": os}, optionflags=doctest.ELLIPSIS)  # type: ignore[arg-type]
    assert r.failed == 0
    assert r.attempted > 0


def test_every_public_name_has_a_docstring_with_an_example() -> None:
    for name in ringsync.__all__:
        obj = getattr(ringsync, name)
        if name in ("__version__", "ScenarioLike"):
            continue
        doc = obj.__doc__ or ""
        assert doc.strip(), name
        assert ">>>" in doc, f"{name} has no example"  # the exceptions too
    help_text = __import__("pydoc").render_doc(ringsync, renderer=__import__("pydoc").plaintext)
    for name in ("simulate", "sweep", "check", "load", "Scenario", "Run", "Sweep", "ScenarioError"):
        assert name in help_text
