"""The examples in the recipe modules' docstrings run and give what they show."""

from __future__ import annotations

import doctest
import importlib

import pytest


@pytest.mark.parametrize("name", ["models", "paths", "targets", "rapid", "store"])
def test_docstring_examples(name):
    module = importlib.import_module(f"doorloc.recipes.{name}")
    result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0
    assert result.attempted > 0
