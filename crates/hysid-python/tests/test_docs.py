"""The tutorial docs/python.md runs as written: its Python blocks in order,
in one namespace, from a folder that sees the repository's models/ (its
asserts check the figures it quotes)."""

import os
import re

from conftest import REPO


def test_the_tutorial_runs(tmp_path, monkeypatch):
    text = (REPO / "docs" / "python.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert len(blocks) >= 6
    (tmp_path / "models").symlink_to(REPO / "models")
    monkeypatch.chdir(tmp_path)
    os.environ.setdefault("MPLBACKEND", "Agg")
    namespace = {}
    for i, block in enumerate(blocks):
        exec(compile(block, f"docs/python.md, python block {i + 1}", "exec"), namespace)
    assert (tmp_path / "out" / "python-regions.png").stat().st_size > 0
