"""The wire's typed values: each field declared once, and their one encoder and one decoder.

A typed value of the client API or the stop record is a frozen dataclass that derives from
:class:`Wire`; each field is declared once (its name, its type, and with :func:`wire` where
the wire says more: another name, left out when ``None``, flattened into its parent, a
default for an absent field). From that one declaration :meth:`Wire.json` writes the object
(a function generated once per class, as fast as one written by hand: the daemon writes one
push per joystick message) and :meth:`Wire.read` reads it back, strict about types: a field
of the wrong type is a :class:`WireError`, never a ``KeyError``, ``TypeError`` or
``ValueError``.

A client may talk to a newer daemon (docs/api.md "Framing": new fields may be added), so
the readers here ignore every field they are not asked for; a field that is asked for and
missing, or of the wrong type, is a :class:`WireError`, never a ``KeyError`` or
``TypeError``. The client library turns it into its ``ProtocolError``.

Pure and small: the client library and the stop record import it, so it imports nothing of
the daemon, the API or the safety core (docs/ros2.md "The client library").
"""

from __future__ import annotations

import collections.abc
import dataclasses
import enum
import math
import types
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Final, TypeVar, Union, cast, get_args, get_origin, get_type_hints

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

    def get(self, key: str) -> object:
        """A field's value, or ``None`` where it is absent."""
        return self._obj.get(key)

    def wrong(self, key: str, what: str, value: object) -> WireError:
        return WireError(f"{self.where}.{key}: not {what}: {value!r}"[:200])

    def integer(self, key: str) -> int:
        value = self._get(key)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.wrong(key, "an integer", value)
        return value

    def maybe_integer(self, key: str) -> int | None:
        """An integer, or ``None`` for null or an absent field."""
        return None if self._obj.get(key) is None else self.integer(key)

    def number(self, key: str) -> float:
        """A finite number (an integer on the wire stays an ``int``)."""
        value = self._get(key)
        if not _is_number(value) or not isinstance(value, int | float):
            raise self.wrong(key, "a finite number", value)
        return value

    def maybe_number(self, key: str) -> float | None:
        return None if self._obj.get(key) is None else self.number(key)

    def text(self, key: str) -> str:
        value = self._get(key)
        if not isinstance(value, str):
            raise self.wrong(key, "text", value)
        return value

    def maybe_text(self, key: str) -> str | None:
        return None if self._obj.get(key) is None else self.text(key)

    def flag(self, key: str) -> bool:
        value = self._get(key)
        if not isinstance(value, bool):
            raise self.wrong(key, "true or false", value)
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
            raise self.wrong(key, "an array", value)
        return value

    def objects(self, key: str) -> list[Fields]:
        """A JSON array of objects."""
        return [Fields(item, f"{self.where}.{key}[{i}]") for i, item in enumerate(self.items(key))]

    def texts(self, key: str) -> tuple[str, ...]:
        values = self.items(key)
        if not all(isinstance(v, str) for v in values):
            raise self.wrong(key, "an array of text", values)
        return tuple(str(v) for v in values)

    def numbers(self, key: str) -> tuple[float, ...]:
        values = self.items(key)
        if not all(_is_number(v) for v in values):
            raise self.wrong(key, "an array of numbers", values)
        return tuple(v for v in values if isinstance(v, int | float))

    def integers(self, key: str) -> tuple[int, ...]:
        values = self.items(key)
        if not all(isinstance(v, int) and not isinstance(v, bool) for v in values):
            raise self.wrong(key, "an array of integers", values)
        return tuple(v for v in values if isinstance(v, int))

    def mapping(self, key: str) -> Fields:
        """An object read as a whole (its keys are data, not field names): see
        :meth:`text_values`, :meth:`flag_values`, :meth:`integer_values`."""
        return self.obj(key)

    def raw(self, key: str) -> JsonDict:
        """An object kept as JSON (a record's trigger: its fields depend on its event)."""
        value = self._get(key)
        if not isinstance(value, Mapping):
            raise self.wrong(key, "an object", value)
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


# -- each field declared once ---------------------------------------------------------------


class _Missing(enum.Enum):
    MISSING = enum.auto()


_NO_DEFAULT: Any = _Missing.MISSING
"""No value declared (``None`` is one)."""


@dataclass(frozen=True, slots=True)
class _Say:
    """What a field's declaration says about the wire (see :func:`wire`)."""

    name: str | None = None
    omit_none: bool = False
    flat: bool = False
    by_name: bool = False
    absent: Any = _NO_DEFAULT
    decode: Callable[[Fields, str], Any] | None = None


def wire(
    *,
    name: str | None = None,
    omit_none: bool = False,
    flat: bool = False,
    by_name: bool = False,
    absent: Any = _NO_DEFAULT,
    decode: Callable[[Fields, str], Any] | None = None,
    default: Any = _NO_DEFAULT,
    default_factory: Any = _NO_DEFAULT,
) -> Any:
    """A field's wire, where it is not just its name and type: ``name`` on the wire;
    ``omit_none``, left out when ``None``; ``flat``, a nested object's (or a mapping's)
    fields written into its parent's (an optional one is there when its first field is);
    ``by_name``, an enum written as its member's name (the states: ``STOPPED``), not its
    value; ``absent``, the value of a field an older daemon leaves out (or sends as null);
    ``decode``, a reader of its own for a field whose shape the type does not say. ``default``
    and ``default_factory`` are the dataclass's."""
    say = _Say(name, omit_none, flat, by_name, absent, decode)
    metadata = {_SAY: say}
    if default_factory is not _NO_DEFAULT:
        return dataclasses.field(default_factory=default_factory, metadata=metadata)
    if default is not _NO_DEFAULT:
        return dataclasses.field(default=default, metadata=metadata)
    return dataclasses.field(metadata=metadata)


_SAY: Final = "wire"
_T = TypeVar("_T", bound="Wire")


class Wire:
    """A typed value of the wire, a frozen dataclass: ``json()`` writes it, ``read(fields)``
    reads it, both from its fields' one declaration. ``WIRE_HEAD`` are the constant fields
    written first (a push's ``event``, a message's ``type``, a reply's ``ok``)."""

    __slots__ = ()
    WIRE_HEAD: ClassVar[Mapping[str, object]] = {}

    def json(self) -> JsonDict:
        """The object on the wire. The first call makes the class's encoder, which takes this
        method's place: from then on, a call is that function's call alone."""
        return _encoder(type(self))(self)

    @classmethod
    def read(cls: type[_T], f: Fields) -> _T:
        """The value in ``f``'s object; raises :class:`WireError` for one not of its shape."""
        return _decoder(cls)(f)


def to_json(value: Wire) -> JsonDict:
    """``value`` as the object on the wire."""
    return value.json()


def from_json(kind: type[_T], obj: object, where: str = "") -> _T:
    """The ``kind`` in the JSON object ``obj``; raises :class:`WireError` for one not of its
    shape (``where`` names it in the error)."""
    return kind.read(Fields(obj, where or kind.__name__))


@dataclass(frozen=True, slots=True)
class _Field:
    """One field, resolved: its attribute, wire name, type (``Optional`` taken off) and what
    its declaration says."""

    attr: str
    key: str
    kind: Any
    optional: bool
    say: _Say


def _fields(cls: type) -> list[_Field]:
    hints = get_type_hints(cls)
    out = []
    for f in dataclasses.fields(cls):
        say = f.metadata.get(_SAY, _Say())
        kind, optional = _unoptional(hints[f.name])
        out.append(_Field(f.name, say.name or f.name, kind, optional, say))
    return out


def _unoptional(kind: Any) -> tuple[Any, bool]:
    args = get_args(kind)
    if get_origin(kind) in (Union, types.UnionType) and type(None) in args:
        rest = tuple(a for a in args if a is not type(None))
        return (rest[0] if len(rest) == 1 else Union[rest]), True  # noqa: UP007
    return kind, False


def _is_wire(kind: Any) -> bool:
    return isinstance(kind, type) and issubclass(kind, Wire)


def _is_text(kind: Any) -> bool:
    """A value written as text by its own ``to_text`` and read by its ``from_text``."""
    return isinstance(kind, type) and hasattr(kind, "from_text")


def _written_as_text(origin: Any, args: tuple[Any, ...]) -> bool:
    """A union of values that each write themselves as text (a cause's name: a known one or
    one kept as written); read by the field's own ``decode``."""
    return origin in (Union, types.UnionType) and all(hasattr(a, "to_text") for a in args)


# -- the encoder: a function generated once per class ---------------------------------------


def _encoder(cls: type[Wire]) -> Callable[[Any], JsonDict]:
    """Writes and compiles ``cls``'s encoder: one dict display for its plain fields in wire
    order, a statement for each one left out when ``None`` or flattened; installed as
    ``cls.json``."""
    names: dict[str, object] = {}
    lines = ["def encode(o):", "    out = {}"]
    # Consecutive plain fields, written as one dict display; the constants first (text, a
    # number or a flag: written as literals).
    plain = [f"{key!r}: {value!r}" for key, value in cls.WIRE_HEAD.items()]

    def flush() -> None:
        if plain:
            lines.append(f"    out.update({{{', '.join(plain)}}})")
            plain.clear()

    for f in _fields(cls):
        attr = f"o.{f.attr}"
        value = _value_expression(attr, f.kind, f.say)
        if f.say.flat:
            flush()
            if f.optional:
                lines += [f"    if {attr} is not None:", f"        out.update({value})"]
            else:
                lines.append(f"    out.update({value})")
        elif f.say.omit_none and f.optional:
            flush()
            lines += [f"    if {attr} is not None:", f"        out[{f.key!r}] = {value}"]
        elif f.optional and value != attr:
            plain.append(f"{f.key!r}: None if {attr} is None else {value}")
        else:
            plain.append(f"{f.key!r}: {value}")
    flush()
    if len(lines) == 3 and lines[1] == "    out = {}" and lines[2].startswith("    out.update("):
        lines[1:] = [f"    return {lines[2][len('    out.update(') : -1]}"]  # one display
    else:
        lines.append("    return out")
    exec(compile("\n".join(lines), f"<encoder of {cls.__name__}>", "exec"), names)  # noqa: S102
    encode = cast(Callable[[Any], JsonDict], names["encode"])
    cls.json = encode  # type: ignore[method-assign,assignment]
    return encode


def _value_expression(v: str, kind: Any, say: _Say) -> str:
    """The expression that writes the value ``v`` (not ``None``) of type ``kind`` as JSON."""
    origin, args = get_origin(kind), get_args(kind)
    if isinstance(kind, type) and hasattr(kind, "json"):
        return f"{v}.json()"
    if isinstance(kind, type) and issubclass(kind, enum.Enum):
        return f"{v}.name" if say.by_name else f"{v}.value"
    if _is_text(kind) or _written_as_text(origin, args):
        return f"{v}.to_text()"
    if origin is tuple:
        item = _value_expression("i", args[0], say)
        return f"list({v})" if item == "i" else f"[{item} for i in {v}]"
    if origin in (dict, collections.abc.Mapping):
        item = _value_expression("i", args[1], say)
        return f"dict({v})" if item == "i" else f"{{k: {item} for k, i in {v}.items()}}"
    return v


# -- the decoder -----------------------------------------------------------------------------


def _decoder(cls: type[_T]) -> Callable[[Fields], _T]:
    readers = [(f.attr, _reader(f)) for f in _fields(cls)]

    def decode(f: Fields) -> _T:
        return cls(**{attr: read(f) for attr, read in readers})

    cls.read = classmethod(lambda _cls, f: decode(f))  # type: ignore[assignment]
    return decode


def _reader(f: _Field) -> Callable[[Fields], Any]:
    key, say = f.key, f.say
    if say.decode is not None:
        custom = say.decode
        base: Callable[[Fields], Any] = lambda fields: custom(fields, key)  # noqa: E731
    elif say.flat:
        first = _fields(f.kind)[0].key
        nested = cast(type[Wire], f.kind)
        if f.optional:
            return lambda fields: nested.read(fields) if fields.has(first) else None
        return nested.read
    else:
        read_value = _value_reader(f.kind, say)
        base = lambda fields: read_value(fields, key)  # noqa: E731
    if f.optional or say.absent is not _NO_DEFAULT:
        fallback = None if say.absent is _NO_DEFAULT else say.absent
        if isinstance(fallback, dict):  # a value's own, never one shared by every value
            return lambda fields: dict(fallback) if fields.get(key) is None else base(fields)
        return lambda fields: fallback if fields.get(key) is None else base(fields)
    return base


_SCALARS: Final[Mapping[Any, Callable[[Fields, str], Any]]] = {
    bool: Fields.flag,
    int: Fields.integer,
    float: Fields.number,
    str: Fields.text,
}
_SCALAR_ARRAYS: Final[Mapping[Any, Callable[[Fields, str], Any]]] = {
    str: Fields.texts,
    int: Fields.integers,
    float: Fields.numbers,
}
_SCALAR_VALUES: Final[Mapping[Any, Callable[[Fields], Any]]] = {
    str: Fields.text_values,
    bool: Fields.flag_values,
    int: Fields.integer_values,
}


def _value_reader(kind: Any, say: _Say) -> Callable[[Fields, str], Any]:
    """The reader of a present, non-null field of type ``kind``."""
    origin, args = get_origin(kind), get_args(kind)
    if kind in _SCALARS:
        return _SCALARS[kind]
    if _is_wire(kind):
        return lambda f, key: kind.read(f.obj(key))
    if isinstance(kind, type) and issubclass(kind, enum.Enum):
        return lambda f, key: _member(f, key, kind, say.by_name)
    if _is_text(kind):
        return lambda f, key: _parsed(f, key, kind)
    if origin is tuple:
        return _array_reader(args[0], say)
    if origin in (dict, collections.abc.Mapping):
        value = args[1]
        if value is Any:
            return Fields.raw
        if value in _SCALAR_VALUES:
            values = _SCALAR_VALUES[value]
            return lambda f, key: values(f.mapping(key))
        if _is_wire(value):
            return lambda f, key: _wire_values(f.mapping(key), value)
    raise TypeError(f"no wire reader for {kind!r}")


def _array_reader(item: Any, say: _Say) -> Callable[[Fields, str], Any]:
    if item in _SCALAR_ARRAYS:
        return _SCALAR_ARRAYS[item]
    if _is_wire(item):
        return lambda f, key: tuple(item.read(o) for o in f.objects(key))
    if isinstance(item, type) and issubclass(item, enum.Enum):
        return lambda f, key: tuple(_member(f, key, item, say.by_name, t) for t in f.texts(key))
    raise TypeError(f"no wire reader for an array of {item!r}")


def _wire_values(f: Fields, kind: type[Wire]) -> dict[str, Any]:
    return {name: kind.read(f.obj(name)) for name in f.names()}


def _member(
    f: Fields, key: str, kind: type[enum.Enum], by_name: bool, text: str | None = None
) -> Any:
    word = f.text(key) if text is None else text
    try:
        return kind[word] if by_name else kind(word)
    except (KeyError, ValueError):
        raise f.wrong(key, f"a {kind.__name__}", word) from None


def _parsed(f: Fields, key: str, kind: Any) -> Any:
    text = f.text(key)
    try:
        return kind.from_text(text)
    except ValueError as error:
        raise f.wrong(key, f"a {kind.__name__} ({error})", text) from None
