"""The README's Python example runs and its commented numbers hold."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"


@pytest.mark.slow
def test_readme_example_runs_and_numbers_hold():
    block = re.search(r"```python\n(.*?)```", README.read_text(), re.S).group(1)
    scope: dict = {}
    exec(compile(block, str(README), "exec"), scope)
    assert scope["m"].margin == pytest.approx(0.2295391304, abs=2e-10)
    assert scope["m"].omega == pytest.approx(6.2809603591, abs=1e-9)
    assert scope["roots"].count == 39 and scope["roots"].certified
    assert scope["F"].principal_part().is_strongly_stable()
    # Rates are compared from the rightmost eigenmode in test_simulate.py; a smooth
    # generic state excites the dominant high-frequency chain too little for a fit.
    assert scope["sim"].norm[-1] < 0.5 * scope["sim"].norm[0]
