"""The one error type for bad user input.

Every public entry point that takes user input (config, scene, trajectory, key file) raises
:class:`InputError` for input that cannot be used. The CLI prints it as one line
``error: <field>: <problem>`` and exits with code 2.
"""

from __future__ import annotations

from typing import Any


class InputError(ValueError):
    """Bad user input, named by the field (or file) it came from.

    :param field: dotted path of the offending field (``scene.street_width_m``) or a file name
    :param problem: what is wrong and what is allowed
    """

    def __init__(self, field: str, problem: str):
        self.field = field
        self.problem = problem
        super().__init__(f"{field}: {problem}")


def bad_value(field: str, value: Any, allowed: str) -> InputError:
    """Uniform message: ``<field>: got <value>, expected <allowed>``."""
    return InputError(field, f"got {value!r}, expected {allowed}")
