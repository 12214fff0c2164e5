"""Every ```python block of README.md runs as written (in order, sharing one namespace)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"
BLOCKS = re.findall(r"^```python\n(.*?)^```", README.read_text(encoding="utf-8"), flags=re.S | re.M)


def test_readme_has_python_examples() -> None:
    assert BLOCKS, "README.md has no ```python block"


def test_readme_python_blocks_run(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)  # files an example writes land in a scratch directory
    namespace: dict[str, object] = {"__name__": "__readme__"}
    for k, block in enumerate(BLOCKS):
        code = compile(block, f"README.md[python block {k + 1}]", "exec")
        exec(code, namespace)
