"""The one helper the contract tests share: the text of the error a call raises."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest


def refusal(error: type[Exception], fn: Callable[..., Any], *args: Any, **kw: Any) -> str:
    """``str`` of the ``error`` (or subclass) that ``fn(*args, **kw)`` raises; fails the test
    if it raises nothing. The contract tests compare it whole: a check that reports the wrong
    field, or a message that lost its key, then fails."""
    with pytest.raises(error) as info:
        fn(*args, **kw)
    return str(info.value)
