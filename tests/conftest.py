"""Shared fixtures."""
import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parent.parent / "README.md"


@pytest.fixture
def readme_model_file(tmp_path):
    """Save the README's "Your own model" class as a user's ``.py`` file under a fresh registry
    name; returns a function ``name -> path``."""
    def write(name: str) -> Path:
        section = README.read_text().split("## Your own model", 1)[1]
        code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
        code = code.split("\nm = ", 1)[0].replace('"my_growth"', f'"{name}"')
        path = tmp_path / f"{name}.py"
        path.write_text(code)
        return path
    return write
