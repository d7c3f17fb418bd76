"""The walk-through of python/README.md: its code blocks run, in order, in one
namespace, in a temporary folder that sees the repository's examples."""

import os
import re

import pytest

from conftest import ROOT


def test_the_readme_walk_through_runs(tmp_path, monkeypatch):
    pytest.importorskip("matplotlib")
    text = (ROOT / "python" / "README.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert len(blocks) >= 4
    os.symlink(ROOT / "examples", tmp_path / "examples")
    monkeypatch.chdir(tmp_path)
    namespace = {}
    for k, block in enumerate(blocks):
        exec(compile(block, f"README.md block {k + 1}", "exec"), namespace)
    for picture in ["melt-energy.png", "merger.png"]:
        assert (tmp_path / picture).stat().st_size > 10_000
    assert (tmp_path / "melt" / "melt.gsd").exists()
    assert (tmp_path / "melt" / "energy.png").exists()
