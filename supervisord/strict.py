"""One strict reader for every table of untrusted values: the robot's TOML file, an output's
options, a client's API request.

Pure: no I/O, no clock. A value is read by its key path (``vsc.timeout_ms``,
``outputs[1].chip``, ``value.key``) against a declared :class:`Key`; a value that does not fit
raises :class:`Invalid` (or the subclass the caller names, e.g.
:class:`~supervisord.errors.ConfigError`) carrying the key path, the offending value and a
hint, in one wording for every reader:

====================  ========================================================================
what                  hint
====================  ========================================================================
whole number          ``use a whole number from LOW to HIGH`` (``, without quotes``: not a number)
flag                  ``use true or false, without quotes``
text                  ``use a non-empty string in double quotes, e.g. EXAMPLE``
name (a pattern)      ``use RULE, e.g. EXAMPLE``
choice                ``use one of "a", "b"``
table                 ``make it a table: a line [KEY] followed by its keys``
array of tables       ``write each entry as its own [[KEY]] table, e.g. [[KEY]] EXAMPLE``
unknown key           ``unknown key: did you mean 'x'? (known: ...)`` or ``...: remove it (...)``
====================  ========================================================================

The value is shown with :func:`shown`: bounded, never an unbounded ``repr`` (a peer's megabyte
string, a deeply nested list, an integer of a million digits). A safety value must never fall
back to a default because of a typo (SR-11.2), so a key nobody declared is an error, never
ignored.

Each :class:`Key` also describes itself as JSON Schema (:meth:`Key.json_schema`), so that the
config's published schema and its validation come from the same declaration
(``supervisord.config.schema``).
"""

from __future__ import annotations

import abc
import dataclasses
import difflib
import re
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Final, TypeVar

SHOWN_TEXT: Final = 60
"""Characters of a string shown in an error message before it is cut."""
SHOWN_DIGITS: Final = 30
"""Digits of an integer shown in an error message: a longer one is described, not printed."""

_PRINTABLE: Final = "[^\\u0000-\\u001f\\u007f-\\u009f]"
_VISIBLE: Final = "[^ \\u0000-\\u001f\\u007f-\\u009f]"
TEXT_PATTERN: Final = f"^{_PRINTABLE}*{_VISIBLE}{_PRINTABLE}*$"
"""A non-empty string without control characters, not only spaces. The same text is the
``pattern`` of the JSON Schema (ECMA 262 and Python read it alike)."""
_TEXT: Final = re.compile(TEXT_PATTERN)


class _Missing:
    """The value of a key that is not set (shown as ``(not set)``)."""

    def __repr__(self) -> str:
        return "(not set)"


MISSING: Final = _Missing()
"""What :meth:`Fields.raw` returns for a key the table does not set."""


class _Required:
    def __repr__(self) -> str:
        return "(required)"


REQUIRED: Final = _Required()
"""The default of a key that must be set."""


def shown(value: object) -> str:
    """``value`` for an error message: short, one line, never an unbounded ``repr``."""
    if isinstance(value, str):
        cut = value[:SHOWN_TEXT]
        return repr(cut) + ("..." if len(value) > SHOWN_TEXT else "")
    if isinstance(value, bool) or value is None or isinstance(value, float | _Missing):
        return repr(value)
    if isinstance(value, int):
        if -(10**SHOWN_DIGITS) < value < 10**SHOWN_DIGITS:
            return repr(value)
        return f"(a whole number of {value.bit_length()} bits)"
    if isinstance(value, bytes):
        return repr(value[:SHOWN_TEXT]) + ("..." if len(value) > SHOWN_TEXT else "")
    if isinstance(value, list | tuple):
        if not value:
            return "[]"
        return f"[{shown(value[0])}{', ...' if len(value) > 1 else ''}] ({len(value)} items)"
    if isinstance(value, Mapping):
        if not value:
            return "{}"
        first = next(iter(value))
        more = ", ..." if len(value) > 1 else ""
        return f"{{{shown(first)}: {shown(value[first])}{more}}} ({len(value)} keys)"
    return f"(a {type(value).__name__})"


class Invalid(ValueError):
    """A refused value: ``key`` (its path), ``value`` (as given) and ``fix`` (the hint)."""

    def __init__(self, key: str, value: object, fix: str, *, where: str = "") -> None:
        self.key, self.value, self.fix = key, value, fix
        super().__init__(f"{where}{key} = {shown(value)}: {fix}")

    @property
    def shown(self) -> str:
        """The value as the message shows it."""
        return shown(self.value)


ErrorType = Callable[[str, object, str], Invalid]
"""What a reader raises: :class:`Invalid` or a subclass taking ``(key, value, fix)``."""

_T = TypeVar("_T")


def join(path: str, name: str | int) -> str:
    """The key path of ``name`` under ``path``: ``a.b``, or ``a[1]`` for an index."""
    if isinstance(name, int):
        return f"{path}[{name}]"
    return f"{path}.{name}" if path else name


# ---------------------------------------------------------------------------------------------
# Declared keys


@dataclasses.dataclass(frozen=True, kw_only=True, eq=False)
class Key(abc.ABC):
    """One key of a table: its ``name``, ``doc``, ``default`` (:data:`REQUIRED`, or ``None``
    for "absent: the reader decides"), an ``example`` value and, rarely, a ``hint`` that
    replaces the common wording where the rule is not the type's (e.g. a fixed baud rate)."""

    name: str
    doc: str
    default: object = REQUIRED
    example: object = None

    hint: str | None = None

    @property
    def required(self) -> bool:
        """Whether the table must set this key."""
        return self.default is REQUIRED

    def read(self, raw: object, key: str, error: ErrorType = Invalid) -> object:
        """The checked value of ``raw`` (``MISSING``: the default, or an error if required)."""
        if raw is MISSING:
            if self.required:
                raise error(key, raw, self.fix(raw))
            return self.default
        if not self.fits(raw):
            raise error(key, raw, self.fix(raw))
        return raw

    @abc.abstractmethod
    def fits(self, raw: object) -> bool:
        """Whether ``raw`` (a value that is set) is acceptable."""

    def fix(self, raw: object) -> str:
        """The hint shown when ``raw`` does not fit."""
        return self.hint or self.wording(raw)

    @abc.abstractmethod
    def wording(self, raw: object) -> str:
        """The common wording of this kind of key."""

    @abc.abstractmethod
    def type_schema(self) -> dict[str, object]:
        """This key's value as JSON Schema (draft 2020-12), without its documentation."""

    def json_schema(self) -> dict[str, object]:
        """This key as JSON Schema: the type, the description, the default and an example."""
        schema: dict[str, object] = {"description": self.doc, **self.type_schema()}
        if self.default is not REQUIRED and self.default is not None:
            schema["default"] = self.default
        if self.example is not None:
            schema["examples"] = [self.example]
        return schema


def _quoted(raw: object, right_type: bool) -> str:
    """The reminder for a value of the wrong type (most often a number or flag in quotes)."""
    return "" if right_type else ", without quotes"


@dataclasses.dataclass(frozen=True, kw_only=True, eq=False)
class Whole(Key):
    """A whole number (never a bool, never a float) from ``low`` to ``high``; with ``values``,
    one of those only (e.g. the standard CAN bit rates)."""

    low: int
    high: int
    values: tuple[int, ...] = ()

    def fits(self, raw: object) -> bool:
        if type(raw) is not int:
            return False
        return raw in self.values if self.values else self.low <= raw <= self.high

    def wording(self, raw: object) -> str:
        if self.values:
            listed = ", ".join(str(value) for value in self.values)
            return f"use one of {listed}{_quoted(raw, type(raw) is int)}"
        return f"use a whole number from {self.low} to {self.high}{_quoted(raw, type(raw) is int)}"

    def type_schema(self) -> dict[str, object]:
        if self.values:
            return {"type": "integer", "enum": list(self.values)}
        return {"type": "integer", "minimum": self.low, "maximum": self.high}


@dataclasses.dataclass(frozen=True, kw_only=True, eq=False)
class Flag(Key):
    """``true`` or ``false``."""

    def fits(self, raw: object) -> bool:
        return isinstance(raw, bool)

    def wording(self, raw: object) -> str:
        return f"use true or false{_quoted(raw, False)}"

    def type_schema(self) -> dict[str, object]:
        return {"type": "boolean"}


@dataclasses.dataclass(frozen=True, kw_only=True, eq=False)
class Text(Key):
    """A string: non-empty, without control characters (:data:`TEXT_PATTERN`), or matching
    ``pattern`` (described to the user as ``rule``), at most ``max_length`` characters.
    ``not_dir``: a file's path, so it may not end with ``/``."""

    pattern: str | None = None
    rule: str = "a non-empty string in double quotes"
    max_length: int | None = None
    not_dir: bool = False

    def fits(self, raw: object) -> bool:
        if not isinstance(raw, str) or re.fullmatch(self.pattern or TEXT_PATTERN, raw) is None:
            return False
        if self.max_length is not None and len(raw) > self.max_length:
            return False
        return not (self.not_dir and raw.endswith("/"))

    def wording(self, raw: object) -> str:
        example = f", e.g. {self.example_text}" if self.example is not None else ""
        if isinstance(raw, str) and re.fullmatch(self.pattern or TEXT_PATTERN, raw):
            if self.max_length is not None and len(raw) > self.max_length:
                return f"use at most {self.max_length} characters{example}"
            return f"use a file's path, not a directory's{example}"
        return f"use {self.rule}{example}"

    @property
    def example_text(self) -> str:
        """The example as written in TOML."""
        return f'"{self.example}"'

    def type_schema(self) -> dict[str, object]:
        pattern = self.pattern or TEXT_PATTERN
        schema: dict[str, object] = {
            "type": "string",
            "pattern": pattern if pattern.startswith("^") else f"^(?:{pattern})$",
        }
        if self.max_length is not None:
            schema["maxLength"] = self.max_length
        if self.not_dir:
            schema["not"] = {"pattern": "/$"}
        return schema


@dataclasses.dataclass(frozen=True, kw_only=True, eq=False)
class Choice(Key):
    """One of ``values`` (strings), each with an optional note shown in the hint. ``values``
    may be a function, for a list known only where it is needed (python-can's interfaces)."""

    values: Mapping[str, str] | Callable[[], Mapping[str, str]]
    rule: str = ""
    """Describes the values in the hint instead of listing them (for a long list)."""

    @property
    def allowed(self) -> Mapping[str, str]:
        """The accepted values and their notes."""
        return self.values() if callable(self.values) else self.values

    def fits(self, raw: object) -> bool:
        return isinstance(raw, str) and raw in self.allowed

    def wording(self, raw: object) -> str:
        allowed = self.allowed
        close = (
            difflib.get_close_matches(raw, list(allowed), n=1, cutoff=0.6)
            if isinstance(raw, str)
            else []
        )
        hint = f"did you mean {close[0]!r}? " if close else ""
        if self.rule:
            return f"{hint}use {self.rule}"
        listed = ", ".join(f'"{v}"' + (f" ({note})" if note else "") for v, note in allowed.items())
        return f"{hint}use one of {listed}"

    def type_schema(self) -> dict[str, object]:
        return {"type": "string", "enum": list(self.allowed)}


@dataclasses.dataclass(frozen=True, kw_only=True, eq=False)
class Either(Key):
    """A value that fits one of ``options`` (e.g. a CAN channel: a name or a number); the
    hint names them all, joined by "or"."""

    options: tuple[Key, ...]

    def fits(self, raw: object) -> bool:
        return any(option.fits(raw) for option in self.options)

    def wording(self, raw: object) -> str:
        parts = [option.wording(raw).removeprefix("use ") for option in self.options]
        return "use " + " or ".join(parts)

    def type_schema(self) -> dict[str, object]:
        return {"anyOf": [option.type_schema() for option in self.options]}


# ---------------------------------------------------------------------------------------------
# Tables


def unknown_key(
    key: str,
    name: str,
    value: object,
    known: Sequence[str],
    *,
    renamed: Mapping[str, str] | None = None,
    error: ErrorType = Invalid,
) -> Invalid:
    """The error for ``name``, a key no one declared: a hint to the key meant (an old name in
    ``renamed``, or a close spelling), or to remove it."""
    hint = (renamed or {}).get(name)
    if hint not in known:
        close = difflib.get_close_matches(name, known, n=1, cutoff=0.6)
        hint = close[0] if close else None
    listed = ", ".join(known)
    if hint:
        return error(key, value, f"unknown key: did you mean {hint!r}? (known: {listed})")
    return error(key, value, f"unknown key: remove it (known: {listed})")


class Fields:
    """The values of one table of untrusted input, read key by key.

    ``path`` is the table's own key path (``""`` for the top); ``error`` what to raise.
    Every read marks its key used; :meth:`finish` refuses a key no one read.
    """

    def __init__(
        self,
        table: Mapping[str, object],
        path: str = "",
        *,
        error: ErrorType = Invalid,
        renamed: Mapping[str, str] | None = None,
    ) -> None:
        self.table, self.path, self.error = table, path, error
        self.renamed = renamed or {}
        self.used: dict[str, None] = {}  # the keys read, in order

    def key(self, name: str | int) -> str:
        """The key path of ``name`` in this table."""
        return join(self.path, name)

    def has(self, name: str) -> bool:
        """Whether the table sets ``name``."""
        return name in self.table

    def raw(self, name: str) -> object:
        """The value of ``name`` as given (:data:`MISSING` when absent), marked used."""
        self.used[name] = None
        return self.table.get(name, MISSING)

    def read(self, key: Key) -> object:
        """The value of ``key``, checked (see :meth:`Key.read`)."""
        return key.read(self.raw(key.name), self.key(key.name), self.error)

    def whole(self, key: Whole) -> int:
        """A :class:`Whole` key's value (its default may be ``None``: then ``None``)."""
        value = self.read(key)
        assert value is None or isinstance(value, int)
        return value  # type: ignore[return-value]

    def flag(self, key: Flag) -> bool:
        """A :class:`Flag` key's value."""
        value = self.read(key)
        assert isinstance(value, bool)
        return value

    def text(self, key: Text) -> str:
        """A :class:`Text` key's value."""
        value = self.read(key)
        assert isinstance(value, str)
        return value

    def refuse(self, name: str | int, value: object, fix: str) -> Invalid:
        """The error for ``name`` = ``value``, with ``fix`` (for rules beyond one key's)."""
        return self.error(self.key(name), value, fix)

    def table_at(self, name: str) -> Fields:
        """The table under ``name`` (absent: an empty one)."""
        raw = self.raw(name)
        if raw is MISSING:
            return Fields({}, self.key(name), error=self.error, renamed=self.renamed)
        if not isinstance(raw, dict):
            raise self.refuse(
                name, raw, f"make it a table: a line [{self.key(name)}] followed by its keys"
            )
        return Fields(raw, self.key(name), error=self.error, renamed=self.renamed)

    def tables_at(self, name: str, example: str) -> list[Fields]:
        """The array of tables under ``name`` (absent: none)."""
        raw = self.raw(name)
        if raw is MISSING:
            return []
        key = self.key(name)
        if not isinstance(raw, list) or not all(isinstance(entry, dict) for entry in raw):
            raise self.refuse(
                name, raw, f"write each entry as its own [[{key}]] table, e.g. [[{key}]] {example}"
            )
        return [
            Fields(entry, join(key, i), error=self.error, renamed=self.renamed)
            for i, entry in enumerate(raw)
        ]

    def check_keys(self, known: Iterable[str]) -> None:
        """Refuse the first key of the table that is not in ``known``."""
        names = list(known)
        for name, value in self.table.items():
            if name not in names:
                raise unknown_key(
                    self.key(name), name, value, names, renamed=self.renamed, error=self.error
                )

    def finish(self) -> None:
        """Refuse the first key of the table that no read asked for."""
        self.check_keys(self.used)


def check_value(key: Key, value: _T, path: str, error: ErrorType = Invalid) -> _T:
    """``value`` itself, after checking it against ``key`` (for values built in code)."""
    key.read(value, path, error)
    return value


_K = TypeVar("_K", bound=Key)


def named(keys: Sequence[Key], name: str, kind: type[_K]) -> _K:
    """The key called ``name`` among a table's ``keys``, of ``kind``. Looked up by name, not
    by place: a reordered schema cannot swap two keys of one kind (``max_bytes`` and ``keep``
    are both whole numbers). A wrong name or kind is the code's mistake, found at import."""
    for key in keys:
        if key.name == name and isinstance(key, kind):
            return key
    raise LookupError(f"no {kind.__name__} key {name!r} among {[k.name for k in keys]}")


def object_schema(keys: Sequence[Key], *, doc: str = "") -> dict[str, object]:
    """A closed JSON Schema object of ``keys``: unknown keys are refused, as the reader does."""
    schema: dict[str, object] = {"type": "object"}
    if doc:
        schema["description"] = doc
    schema["properties"] = {key.name: key.json_schema() for key in keys}
    required = [key.name for key in keys if key.required]
    if required:
        schema["required"] = required
    schema["additionalProperties"] = False
    return schema


# ---------------------------------------------------------------------------------------------
# Single values built in code (a dataclass checking its own fields), in the same wording


def whole(key: str, value: object, low: int, high: int, error: ErrorType = Invalid) -> int:
    """``value`` if it is a whole number from ``low`` to ``high``; else ``error``."""
    checked = Whole(name=key, doc="", low=low, high=high).read(value, key, error)
    assert isinstance(checked, int)
    return checked


def flag(key: str, value: object, error: ErrorType = Invalid) -> bool:
    """``value`` if it is a bool; else ``error``."""
    checked = Flag(name=key, doc="").read(value, key, error)
    assert isinstance(checked, bool)
    return checked


def name(key: str, value: object, rule: Text, error: ErrorType = Invalid) -> str:
    """``value`` if it fits the :class:`Text` ``rule`` (a name pattern); else ``error``."""
    checked = rule.read(value, key, error)
    assert isinstance(checked, str)
    return checked
