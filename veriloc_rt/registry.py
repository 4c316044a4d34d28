"""Plug-in registries: a family of interchangeable parts (threats, detectors, propagation models)
looked up by the name the config gives.

A :class:`Registry` maps names to classes (or factories); a family's registry lives in the
family's package (``attacks.threats.THREAT_REGISTRY``,
``detectors.registry.DETECTOR_REGISTRY``, ``propagation.models.PROPAGATION_REGISTRY``) and its built-ins register themselves there the
way a plug-in does (``@REGISTRY.register("name")``). The config sits below those packages
(docs/design.md, "Plug-in registries"), so it checks a name's type only; the name is looked up,
and an unknown one refused with one line naming the config field, when the run is assembled
(:func:`veriloc_rt.sim.plugins.check_plugin_names`, before anything is computed). How to add
one: docs/extending.md.
"""

from __future__ import annotations

from typing import Callable, Generic, Iterator, TypeVar

from .errors import InputError

__all__ = ["Registry"]

T = TypeVar("T")


class Registry(Generic[T]):
    """Names -> registered objects of one plug-in family, in registration order.

    :param family: what one entry is, for messages ('threat', 'detector', ...)
    :param field: the config field that names entries, for messages ('run.scenarios')
    """

    def __init__(self, family: str, field: str):
        self.family, self.field = family, field
        self._entries: dict[str, T] = {}

    def register(self, name: str, obj: T | None = None) -> T | Callable[[T], T]:
        """Register ``obj`` under ``name``; without ``obj``, a decorator that does.

        The registered object gets ``name`` as its ``name`` attribute when it is a class.

        :raises ValueError: if ``name`` is taken or not a non-empty identifier-like string
        """
        if not isinstance(name, str) or not name or not name.replace("_", "a").replace(
                "-", "a").isalnum():
            raise ValueError(f"Argument `name` must be a non-empty name of letters, digits, "
                             f"'_' and '-', not {name!r}")
        if name in self._entries:
            raise ValueError(f"{self.family} {name!r} is already registered")

        def add(o: T) -> T:
            if isinstance(o, type):
                o.name = name
            self._entries[name] = o
            return o

        return add if obj is None else add(obj)

    def unregister(self, name: str) -> None:
        """Remove ``name`` (a test's example plug-in, after the test)."""
        del self._entries[name]

    def get(self, name: str, field: str | None = None) -> T:
        """The entry registered as ``name``.

        :param field: the config field naming it, for the error (default: the registry's)
        :raises InputError: one line naming ``field`` and the registered names
        """
        try:
            return self._entries[name]
        except (KeyError, TypeError):
            raise InputError(field or self.field,
                             f"unknown {self.family} {name!r}; registered: "
                             + ", ".join(repr(n) for n in self._entries)) from None

    def names(self) -> tuple[str, ...]:
        """The registered names, in registration order (the built-ins first)."""
        return tuple(self._entries)

    def items(self) -> list[tuple[str, T]]:
        return list(self._entries.items())

    def __contains__(self, name: object) -> bool:
        return name in self._entries

    def __iter__(self) -> Iterator[str]:
        return iter(self._entries)

    def __len__(self) -> int:
        return len(self._entries)

    def __repr__(self) -> str:
        return f"Registry({self.family!r}: {', '.join(self._entries)})"
