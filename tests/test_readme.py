"""The README's custom-model example runs on both backends and is under 25 lines of model."""
import re
from pathlib import Path

README = Path(__file__).resolve().parent.parent / "README.md"


def _custom_model_block() -> str:
    text = README.read_text()
    section = text.split("## Your own model", 1)[1]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def test_custom_model_example_runs_on_both_backends(capsys):
    code = _custom_model_block()
    model_lines = [ln for ln in code.splitlines() if ln.strip()]
    assert len(model_lines) <= 25 + 3  # the model itself, plus the 3-line usage at the end
    ns: dict = {"__name__": "readme_example"}
    exec(compile(code.replace('"my_growth"', '"my_growth_readme_test"'), "README.md", "exec"), ns)
    out = capsys.readouterr().out.splitlines()
    lls = {ln.split()[0]: float(ln.split()[1]) for ln in out}
    assert set(lls) == {"numpy", "numba"}
    assert abs(lls["numpy"] - lls["numba"]) < 1e-6


def test_marginalized_pf_example_runs_on_both_backends(capsys):
    # The "Marginalized PF: declare the structure" example: a user model under 30 lines whose MPF
    # gives the same log-likelihood on both backends (same draws, same step math: <= 1e-9).
    section = README.read_text().split("## Marginalized PF: declare the structure", 1)[1]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    lines = [ln for ln in code.splitlines() if ln.strip()]
    assert len(lines) < 30 + 3 + 3  # the model, plus 3 import lines and the 3-line usage
    ns: dict = {"__name__": "readme_mpf_example"}
    exec(compile(code.replace('"my_mixed"', '"my_mixed_readme_test"'), "README.md", "exec"), ns)
    out = capsys.readouterr().out.splitlines()
    lls = {ln.split()[0]: float(ln.split()[1]) for ln in out}
    assert set(lls) == {"numpy", "numba"}
    assert abs(lls["numpy"] - lls["numba"]) <= 1e-9 * abs(lls["numpy"])
