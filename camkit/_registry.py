"""Registries of classes by name (camera models, calibration targets)."""

from __future__ import annotations

from typing import Any, TypeVar

from camkit.errors import ParameterError

__all__ = ["Registry"]

_C = TypeVar("_C")


class Registry(dict):
    """``name -> class``, filled by a class decorator; a name is taken by one class only (the
    same class re-registered, as on a module reload, is allowed). ``kind`` names the entries in
    messages ("model", "target")."""

    def __init__(self, kind: str) -> None:
        super().__init__()
        self.kind = kind

    def register(self, cls: _C) -> _C:
        name = cls.name  # type: ignore[attr-defined]
        old = self.get(name)
        if old is not None and (old.__module__, old.__qualname__) != (cls.__module__, cls.__qualname__):
            raise ParameterError(f"{self.kind} name {name!r} is already registered by {old.__qualname__}")
        self[name] = cls
        return cls

    def lookup(self, name: Any, arg: str = "name") -> Any:
        """The class registered as ``name``; a ParameterError naming ``arg`` and the choices
        otherwise."""
        try:
            return self[name]
        except (KeyError, TypeError):
            raise ParameterError(f"{arg}: expected one of {', '.join(map(repr, sorted(self)))}, got {name!r}") from None
