"""Short reprs for camkit's result objects.

A result of a calibration holds every view's points, residuals and detections; the dataclass
repr printed all of them (half a megabyte for Bouguet's 20 photos, which a notebook cell shows
in full). These reprs keep the ``Name(field=value, ...)`` form and show small values as they
are, but an array or a list beyond a few numbers as its shape or its length: the data stay one
attribute away.
"""

from __future__ import annotations

import dataclasses
from pathlib import PurePath
from typing import Any

import numpy as np

__all__ = ["short", "summary_repr"]

#: Arrays with up to this many elements, and lists with up to this many items, are shown whole.
_SMALL_ARRAY = 6
_SMALL_LIST = 4
#: Dicts of up to this many small values (a calibration's standard deviations) are shown whole.
_SMALL_DICT = 20
#: Inside a short list, any other value counts as small where its repr is at most this long
#: (a camera model: yes; a calibration result: no).
_SMALL_REPR = 400
#: Lists of names or numbers are shown whole while they fit in this many characters.
_SHORT_LINE = 120


def short(value: Any) -> str:
    """The repr of ``value``, with large arrays and long lists summarised."""
    if isinstance(value, np.ndarray):
        if value.size <= _SMALL_ARRAY:
            return " ".join(np.array2string(value, precision=6, separator=", ").split())
        return f"<array {tuple(value.shape)} {value.dtype}>"
    if isinstance(value, PurePath):
        return repr(str(value))
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, dict):
        if len(value) <= _SMALL_DICT and all(_is_small(v) for v in value.values()):
            return "{" + ", ".join(f"{k!r}: {short(v)}" for k, v in value.items()) + "}"
        return f"<dict of {len(value)}>"
    if isinstance(value, (list, tuple)):
        if (len(value) <= _SMALL_LIST and all(_is_small(v) for v in value)) or _few_words(value):
            inner = ", ".join(short(v) for v in value)
            if isinstance(value, tuple):
                return f"({inner},)" if len(value) == 1 else f"({inner})"
            return f"[{inner}]"
        kinds = sorted({type(v).__name__ for v in value})
        what = kinds[0] if len(kinds) == 1 else " / ".join(kinds)
        return f"<{type(value).__name__} of {len(value)}{' ' + what if value else ''}>"
    return repr(value)


def _few_words(value: list | tuple) -> bool:
    """Names or indices that fit on a short line (a calibration's free parameters)."""
    return (all(isinstance(v, (str, int)) for v in value)
            and sum(len(repr(v)) + 2 for v in value) <= _SHORT_LINE)


def _is_small(value: Any) -> bool:
    if isinstance(value, np.ndarray):
        return value.size <= _SMALL_ARRAY
    if isinstance(value, (list, tuple)):
        return (len(value) <= _SMALL_LIST and all(_is_small(v) for v in value)) or _few_words(value)
    if isinstance(value, dict):
        return False
    return len(short(value)) <= _SMALL_REPR


def summary_repr(obj: Any, **extra: Any) -> str:
    """``Name(field=short(value), ...)`` for the fields of the dataclass ``obj`` (those with
    ``repr=True``), then ``extra`` (computed summaries, shown with ``repr``)."""
    parts = [f"{f.name}={short(getattr(obj, f.name))}" for f in dataclasses.fields(obj) if f.repr]
    parts += [f"{name}={value!r}" for name, value in extra.items()]
    return f"{type(obj).__name__}({', '.join(parts)})"
