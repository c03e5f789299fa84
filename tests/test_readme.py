"""The README's Python example runs as written (a stale example is a bug for a new user)."""

import re
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"


def test_readme_python_examples_run():
    blocks = re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)
    assert blocks, "no Python example in the README"
    for code in blocks:
        ns: dict = {}
        exec(compile(code, str(README), "exec"), ns)  # noqa: S102 - our own README
        assert "est" in ns or "track" in ns
