"""The examples in the package's docstrings run and print what they say (``doctest``); an example
that cannot run here (a DataLoader with worker processes in the package docstring) is marked
``+SKIP`` where it stands."""

import doctest

import pytest

import sidar_torch
import sidar_torch.data.augment
import sidar_torch.data.augment_step

pytestmark = pytest.mark.gl  # the examples render


@pytest.mark.parametrize("module", [sidar_torch, sidar_torch.data.augment, sidar_torch.data.augment_step], ids=lambda m: m.__name__)
def test_docstring_examples_run(module):
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS, verbose=False)
    assert result.attempted > 0 and result.failed == 0, result
