"""Every ```python block in README.md and docs/*.md runs (blocks of one file share a namespace)."""

from __future__ import annotations

import pathlib
import re

import matplotlib
import pytest

matplotlib.use("Agg")

ROOT = pathlib.Path(__file__).resolve().parents[1]
FILES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)


#: pages whose examples compile several loops of their own (a minute or more on a fresh cache)
#: pages whose examples compile loops of their own for minutes on a fresh cache (filament.md: the
#: compiled rattle loop of its dynamics example; kirchhoff-love.md: ≈ 1 min of static solves)
SLOW_PAGES = {"integrators.md", "plugins.md", "relativistic-rod.md", "verification.md", "filament.md",
              "kirchhoff-love.md"}


@pytest.mark.parametrize("path", [pytest.param(p, marks=[pytest.mark.slow] if p.name in SLOW_PAGES else [])
                                  for p in FILES], ids=[p.name for p in FILES])
def test_snippets_run(path, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "__docs__"}
    for i, block in enumerate(BLOCK.findall(path.read_text())):
        try:
            exec(compile(block, f"{path.name}[block {i}]", "exec"), namespace)
        except Exception as exc:  # pragma: no cover - reported with the snippet
            pytest.fail(f"{path.name} block {i} failed: {type(exc).__name__}: {exc}\n{block}")
