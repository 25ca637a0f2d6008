"""The README's Python examples run as written (the README never lies)."""

import pathlib
import re

import pytest

import direct

README = pathlib.Path(__file__).resolve().parent.parent / "README.md"
BLOCKS = re.findall(r"```python\n(.*?)```", README.read_text(encoding="utf-8"), flags=re.S)


def test_the_readme_has_python_examples():
    assert len(BLOCKS) >= 2


@pytest.mark.parametrize("k", range(len(BLOCKS)))
def test_each_python_example_runs(k):
    namespace: dict = {}
    exec(compile(BLOCKS[k], f"README.md, Python block {k}", "exec"), namespace)  # noqa: S102
    if "assert_agrees_with_oracle" in namespace:  # the property-test helper: it accepts J^G of cross, refuses 1 % off
        exact = 2 * 0.5**3 / 3
        namespace["assert_agrees_with_oracle"]("cross", exact * (1 + 1e-4), 1e-3)
        with pytest.raises(AssertionError):
            namespace["assert_agrees_with_oracle"]("cross", exact * 1.01, 1e-3)
    else:
        assert isinstance(namespace.get("res"), direct.Penalty)
