"""Reading a reply or push back into its typed value: field by field, with types checked.

A client may talk to a newer daemon (docs/api.md "Framing": new fields may be added), so
the readers here ignore every field they are not asked for; a field that is asked for and
missing, or of the wrong type, is a :class:`WireError`, never a ``KeyError`` or
``TypeError``. The client library turns it into its ``ProtocolError``.

Pure and small: the client library imports it, so it imports nothing of the daemon
(docs/ros2.md "The client library").
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from supervisord.errors import SrcsError

JsonDict = dict[str, Any]


class WireError(SrcsError, ValueError):
    """A reply or push that is not what docs/api.md says it is."""


class Fields:
    """The fields of one JSON object, read by name and type; ``where`` names the object in
    errors (``status.daemon.link``). Fields not asked for are ignored."""

    __slots__ = ("_obj", "where")

    def __init__(self, obj: object, where: str) -> None:
        if not isinstance(obj, Mapping):
            raise WireError(f"{where}: not a JSON object: {obj!r}"[:200])
        self._obj: Mapping[str, object] = obj
        self.where = where

    def has(self, key: str) -> bool:
        return key in self._obj

    def _get(self, key: str) -> object:
        try:
            return self._obj[key]
        except KeyError:
            raise WireError(f"{self.where}: no field {key!r}") from None

    def _wrong(self, key: str, what: str, value: object) -> WireError:
        return WireError(f"{self.where}.{key}: not {what}: {value!r}"[:200])

    def integer(self, key: str) -> int:
        value = self._get(key)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self._wrong(key, "an integer", value)
        return value

    def maybe_integer(self, key: str) -> int | None:
        """An integer, or ``None`` for null or an absent field."""
        return None if self._obj.get(key) is None else self.integer(key)

    def number(self, key: str) -> float:
        """A finite number (an integer on the wire stays an ``int``)."""
        value = self._get(key)
        if not _is_number(value) or not isinstance(value, int | float):
            raise self._wrong(key, "a finite number", value)
        return value

    def maybe_number(self, key: str) -> float | None:
        return None if self._obj.get(key) is None else self.number(key)

    def text(self, key: str) -> str:
        value = self._get(key)
        if not isinstance(value, str):
            raise self._wrong(key, "text", value)
        return value

    def maybe_text(self, key: str) -> str | None:
        return None if self._obj.get(key) is None else self.text(key)

    def flag(self, key: str) -> bool:
        value = self._get(key)
        if not isinstance(value, bool):
            raise self._wrong(key, "true or false", value)
        return value

    def maybe_flag(self, key: str) -> bool | None:
        return None if self._obj.get(key) is None else self.flag(key)

    def obj(self, key: str) -> Fields:
        return Fields(self._get(key), f"{self.where}.{key}")

    def maybe_obj(self, key: str) -> Fields | None:
        return None if self._obj.get(key) is None else self.obj(key)

    def items(self, key: str) -> list[object]:
        """A JSON array's items."""
        value = self._get(key)
        if not isinstance(value, list):
            raise self._wrong(key, "an array", value)
        return value

    def objects(self, key: str) -> list[Fields]:
        """A JSON array of objects."""
        return [Fields(item, f"{self.where}.{key}[{i}]") for i, item in enumerate(self.items(key))]

    def texts(self, key: str) -> tuple[str, ...]:
        values = self.items(key)
        if not all(isinstance(v, str) for v in values):
            raise self._wrong(key, "an array of text", values)
        return tuple(str(v) for v in values)

    def numbers(self, key: str) -> tuple[float, ...]:
        values = self.items(key)
        if not all(_is_number(v) for v in values):
            raise self._wrong(key, "an array of numbers", values)
        return tuple(v for v in values if isinstance(v, int | float))

    def integers(self, key: str) -> tuple[int, ...]:
        values = self.items(key)
        if not all(isinstance(v, int) and not isinstance(v, bool) for v in values):
            raise self._wrong(key, "an array of integers", values)
        return tuple(v for v in values if isinstance(v, int))

    def mapping(self, key: str) -> Fields:
        """An object read as a whole (its keys are data, not field names): see
        :meth:`text_values`, :meth:`flag_values`, :meth:`integer_values`."""
        return self.obj(key)

    def raw(self, key: str) -> JsonDict:
        """An object kept as JSON (a record's trigger: its fields depend on its event)."""
        value = self._get(key)
        if not isinstance(value, Mapping):
            raise self._wrong(key, "an object", value)
        return dict(value)

    def text_values(self) -> dict[str, str]:
        if not all(isinstance(v, str) for v in self._obj.values()):
            raise WireError(f"{self.where}: not text values: {dict(self._obj)!r}"[:200])
        return {str(k): str(v) for k, v in self._obj.items()}

    def flag_values(self) -> dict[str, bool]:
        if not all(isinstance(v, bool) for v in self._obj.values()):
            raise WireError(f"{self.where}: not true/false values: {dict(self._obj)!r}"[:200])
        return {str(k): bool(v) for k, v in self._obj.items()}

    def integer_values(self) -> dict[str, int]:
        values = self._obj.values()
        if not all(isinstance(v, int) and not isinstance(v, bool) for v in values):
            raise WireError(f"{self.where}: not integer values: {dict(self._obj)!r}"[:200])
        return {str(k): v for k, v in self._obj.items() if isinstance(v, int)}

    def raw_value(self, key: str) -> object:
        """A field's value as it came (an error's extra fields: their meaning is its code's)."""
        return self._get(key)

    def names(self) -> list[str]:
        """The names of the fields present."""
        return [str(k) for k in self._obj]


def _is_number(value: object) -> bool:
    """A finite JSON number (not ``true``/``false``, which Python counts as integers)."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return False
    return math.isfinite(value)
