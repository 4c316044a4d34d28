"""The one error type for bad user input.

Every public entry point that takes user input (config, scene, trajectory, key file) raises
:class:`InputError` for input that cannot be used. The CLI prints it as one line
``error: <field>: <problem>`` and exits with code 2.
"""

from __future__ import annotations

import math
import reprlib
from typing import Any

_SHORT = reprlib.Repr()
_SHORT.maxstring, _SHORT.maxother, _SHORT.maxlong = 80, 80, 40
_SHORT.maxlist = _SHORT.maxtuple = _SHORT.maxdict = 8
_SHORT.maxlevel = 3
#: control characters that would break the one-line message, escaped
_ONE_LINE = {i: f"\\x{i:02x}" for i in range(32)} | {10: "\\n", 13: "\\r", 9: " "}


class InputError(ValueError):
    """Bad user input, named by the field (or file) it came from.

    :param field: dotted path of the offending field (``scene.street_width_m``) or a file name
    :param problem: what is wrong and what is allowed
    """

    def __init__(self, field: str, problem: str):
        # one line whatever the field (a file name may hold a line break) or the problem holds
        self.field = str(field).translate(_ONE_LINE)
        self.problem = str(problem).translate(_ONE_LINE)
        super().__init__(f"{self.field}: {self.problem}")

    def __reduce__(self):
        # rebuilt from both arguments when a worker process sends it back (the default pickles
        # only the message, and unpickling then fails in the pool's result thread, which hangs)
        return (type(self), (self.field, self.problem))


def short_repr(value: Any) -> str:
    """``repr(value)`` cut to a readable length (a message quotes the value, not all of it)."""
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 128:
        digits = int(value.bit_length() * math.log10(2)) + 1
        return f"{'-' if value < 0 else ''}<integer of about {digits} digits>"
    try:
        return _SHORT.repr(value)
    except (ValueError, RecursionError):
        return f"<{type(value).__name__}>"


def bad_value(field: str, value: Any, allowed: str) -> InputError:
    """Uniform message: ``<field>: got <value>, expected <allowed>`` (long values shortened)."""
    return InputError(field, f"got {short_repr(value)}, expected {allowed}")
