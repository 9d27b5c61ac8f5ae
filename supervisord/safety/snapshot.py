"""The safety core's whole state as plain JSON values, and a core made again from them: what a
flight recorder's window starts from when it does not reach back to the daemon's start
(SR-7.11; ``docs/record.md`` "The flight recorder").

The core is a pure state machine: from the same state, the same inputs give the same decisions.
A window of its inputs can therefore be replayed only from the state the core was in when the
window began, which is not its start state (clients connected, causes latched, a proof test
half done, a record budget spent). :func:`snapshot` writes that state down and :func:`restore`
builds a core in exactly that state.

Generic on purpose: it walks the core's object graph (every attribute of every object, the
dictionaries, sets, deques and read-only mappings between them) instead of naming the core's
fields, so a field added to the core tomorrow is in the snapshot without anyone remembering to
add it, and a round trip test (``tests/record/test_snapshot.py``) catches what it cannot hold.
Objects shared within the graph stay shared (each is written once, then referred to).

The configuration is not part of it: the window stores that once, in its stable form
(``supervisord/record/flight_codec.py``), and :func:`restore` takes it back. The daemon's
configuration holds the output kinds' own specifications (a GPIO chip, a file path), which the
core never reads and a snapshot need not know.

Safe to read from a file: :func:`restore` makes only instances of the classes defined in the
core's own modules and the protocol's message modules (:data:`MODULES`), sets on each exactly
the fields its class declares (:class:`_Declared`: a dataclass's fields, else the attributes a
fresh core's instance holds and the class's own annotated or cached ones; never a name that is
a method of the class, never one missing), each of its declared type, and never calls a
constructor, a method or anything named in the data (SR-7.13): once made, the core composes the
view of its machines again (``SafetyCore._compose``: built from them, never in a snapshot).
Tied to the code that wrote it: the state of one version of the core is not a state of another,
which the window's header says (``srcsd`` version) and ``srcsctl replay`` checks.

Pure, as the rest of the core (``tests/safety/test_purity.py``).
"""

from __future__ import annotations

import dataclasses
import enum
import functools
import types
import typing
from collections import deque
from collections.abc import Callable, Iterator, Mapping
from types import MappingProxyType, ModuleType
from typing import Any, Final

from supervisord.protocol import codes, messages
from supervisord.safety import (
    battery,
    book,
    budget,
    causes,
    clients,
    config,
    core,
    decision,
    display,
    events,
    outputs,
    progress,
    prooftest,
    transitions,
    vsc,
)
from supervisord.safety.config import SafetyConfig
from supervisord.safety.core import SafetyCore

MODULES: Final[tuple[ModuleType, ...]] = (
    battery,
    book,
    budget,
    causes,
    clients,
    config,
    core,
    decision,
    display,
    events,
    outputs,
    progress,
    prooftest,
    transitions,
    vsc,
    codes,
    messages,
)
"""The modules whose classes a snapshot may hold: the core's own and the protocol's messages
and codes (a decoded VSC message is part of a decision and of the core's display store), with
the package's classes they import."""

Json = Any
"""A plain JSON value: ``None``, ``bool``, ``int``, ``float``, ``str``, lists and objects."""


class SnapshotError(ValueError):
    """The core holds something a snapshot cannot write, or the data is no snapshot this code
    can restore (another version of the core, or damaged)."""


def _classes() -> dict[str, type]:
    """The package's classes these modules define or name (a vocabulary they import from a
    module of its own, such as a release's ``Request``), by where each is defined."""
    found: dict[str, type] = {}
    for module in MODULES:
        for value in vars(module).values():
            if isinstance(value, type) and value.__module__.startswith("supervisord."):
                found[f"{value.__module__}:{value.__qualname__}"] = value
    return found


CLASSES: Final[dict[str, type]] = _classes()
"""Every class :func:`restore` may make, by ``module:qualname``: nothing from outside the
package, and nothing of it that the core's and the messages' modules do not name."""


def _name(cls: type) -> str:
    name = f"{cls.__module__}:{cls.__qualname__}"
    if CLASSES.get(name) is not cls:
        raise SnapshotError(f"a snapshot cannot hold a {name}: not a class of the core")
    return name


def _attributes(obj: object) -> Iterator[tuple[str, object]]:
    """Every attribute ``obj`` holds: its slots (through its classes) and its ``__dict__``."""
    for cls in type(obj).__mro__:
        for slot in cls.__dict__.get("__slots__", ()):
            if slot not in ("__dict__", "__weakref__") and hasattr(obj, slot):
                yield slot, getattr(obj, slot)
    yield from getattr(obj, "__dict__", {}).items()


class _Writer:
    """One walk of the graph; each container or object gets a number, met again a reference."""

    def __init__(self) -> None:
        self.numbers: dict[int, int] = {}
        self.kept: list[object] = []  # alive until the walk ends, so no id() is reused
        self.by_type: dict[type, Callable[[Any, int], Json]] = {
            tuple: lambda v, n: {"t": "tuple", "i": n, "v": [self.value(x) for x in v]},
            list: lambda v, n: {"t": "list", "i": n, "v": [self.value(x) for x in v]},
            set: lambda v, n: {"t": "set", "i": n, "v": [self.value(x) for x in v]},
            frozenset: lambda v, n: {"t": "frozenset", "i": n, "v": [self.value(x) for x in v]},
            dict: lambda v, n: {"t": "dict", "i": n, "v": self.pairs(v)},
            MappingProxyType: lambda v, n: {"t": "proxy", "i": n, "v": self.pairs(v)},
            deque: lambda v, n: {
                "t": "deque",
                "i": n,
                "v": [self.value(x) for x in v],
                "maxlen": v.maxlen,
            },
        }

    def pairs(self, mapping: Any) -> list[Json]:
        return [[self.value(k), self.value(v)] for k, v in mapping.items()]

    def value(self, value: object) -> Json:
        kind = type(value)
        if value is None or kind is bool or kind is int or kind is str:
            return value
        if isinstance(value, enum.Enum):
            return {"t": "enum", "c": _name(kind), "v": value.value}
        if kind is float:
            return value
        number = self.numbers.get(id(value))
        if number is not None:
            return {"t": "ref", "i": number}
        number = self.numbers[id(value)] = len(self.numbers)
        self.kept.append(value)
        write = self.by_type.get(kind)
        if write is not None:
            return write(value, number)
        if isinstance(value, type) or callable(value):
            raise SnapshotError(f"a snapshot cannot hold {value!r}")
        name = _name(kind)
        return {
            "t": "obj",
            "c": name,
            "i": number,
            "f": {key: self.value(v) for key, v in _attributes(value)},
        }


CONFIG: Final = "_config"
"""The core's attribute that holds its configuration: left out, given back to :func:`restore`."""


def snapshot(safety: SafetyCore) -> Json:
    """The core's whole state but its configuration, as plain JSON values (:func:`restore`
    makes it again). Raises :class:`SnapshotError` if the core holds something no snapshot can
    (it never does: only values of the core's own classes, the protocol's messages and the
    builtin containers)."""
    writer = _Writer()
    state = {
        name: writer.value(value)
        for name, value in vars(safety).items()
        if name != CONFIG and name not in SafetyCore.COMPOSED
    }
    return {"t": "obj", "c": _name(SafetyCore), "i": -1, "f": state}


def _conforms(value: object, hint: Any) -> bool:
    """Whether ``value`` is of the declared type ``hint`` (the forms the core's annotations
    use: classes, ``X | None``, and the builtin containers with their item types)."""
    if hint is Any or hint is object:
        return True
    if hint is None or hint is type(None):
        return value is None
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin is typing.Union or origin is types.UnionType:
        return any(_conforms(value, arg) for arg in args)
    if origin is None:
        if hint is float:
            return isinstance(value, int | float) and not isinstance(value, bool)
        return isinstance(hint, type) and isinstance(value, hint)
    if origin is typing.Literal:
        return value in args
    if not isinstance(value, origin):
        return False
    if origin is tuple and isinstance(value, tuple):
        if len(args) == 2 and args[1] is Ellipsis:
            return all(_conforms(item, args[0]) for item in value)
        return len(args) == len(value) and all(map(_conforms, value, args))
    if isinstance(value, Mapping) and len(args) == 2:
        return all(_conforms(k, args[0]) and _conforms(v, args[1]) for k, v in value.items())
    if isinstance(value, list | set | frozenset | deque) and len(args) == 1:
        return all(_conforms(item, args[0]) for item in value)
    return True


class _Declared:
    """The fields the snapshot format declares for each class, with their types: a dataclass's
    fields and their annotations; for the core's other classes, the attributes an instance of
    a fresh core holds (typed as the fresh value's class, or ``None``), and the class's own
    annotated, defaulted or cached attributes, which a snapshot may leave out (the class's
    value then stands). Never a name the class defines as a method or property (SR-7.13)."""

    def __init__(self, config: SafetyConfig) -> None:
        self.required: dict[type, dict[str, Any]] = {}
        self.optional: dict[type, dict[str, Any]] = {}
        self._fresh(SafetyCore(config, 0))

    def _fresh(self, core: SafetyCore) -> None:
        todo: list[object] = [core]
        seen: set[int] = set()
        while todo:
            obj = todo.pop()
            if id(obj) in seen or isinstance(obj, type):
                continue
            seen.add(id(obj))
            if isinstance(obj, dict | MappingProxyType):
                todo.extend(obj.values())
            elif isinstance(obj, list | tuple | set | frozenset | deque):
                todo.extend(obj)
            elif type(obj) in CLASSES.values() and not dataclasses.is_dataclass(obj):
                fields = self.required.setdefault(type(obj), {})
                for name, value in getattr(obj, "__dict__", {}).items():
                    if obj is core and (name == CONFIG or name in SafetyCore.COMPOSED):
                        continue  # never in a snapshot: restore gives it back
                    fields[name] = Any if value is None else type(value) | None
                    todo.append(value)

    def of(self, cls: type) -> tuple[dict[str, Any], dict[str, Any]]:
        """The required and the optional fields of ``cls``, by name, with their types."""
        if dataclasses.is_dataclass(cls):
            hints = _hints(cls)
            return {f.name: hints.get(f.name, Any) for f in dataclasses.fields(cls)}, {}
        optional = self.optional.get(cls)
        if optional is None:
            optional = self.optional[cls] = _class_fields(cls)
        return self.required.get(cls, {}), optional


@functools.cache
def _hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def _class_fields(cls: type) -> dict[str, Any]:
    """The attributes ``cls`` declares itself that an instance may hold: annotated or given a
    plain value in the class body, or cached properties (typed by what they return)."""
    found: dict[str, Any] = {}
    hints = _hints(cls)
    for klass in reversed(cls.__mro__[:-1]):
        for name, value in vars(klass).items():
            if name.startswith("__"):
                continue
            if isinstance(value, functools.cached_property):
                found[name] = typing.get_type_hints(value.func).get("return", Any)
            elif name in hints:
                found[name] = hints[name]
            elif isinstance(value, bool | int | str | float) or value is None:
                found[name] = type(value)
    for name, hint in hints.items():
        if typing.get_origin(hint) is not typing.ClassVar:
            found.setdefault(name, hint)
    return found


class _Reader:
    def __init__(self, declared: _Declared) -> None:
        self.made: dict[int, object] = {}
        self.declared = declared

    def value(self, data: Json) -> Any:
        if data is None or isinstance(data, bool | int | str | float):
            return data
        if not isinstance(data, dict):
            raise SnapshotError(f"not a snapshot value: {str(data)[:60]}")
        tag = data.get("t")
        if tag == "enum":
            return self.enum(data)
        if tag == "ref":
            number = data.get("i")
            if not isinstance(number, int) or number not in self.made:
                raise SnapshotError(f"a reference to nothing: {number!r}")
            return self.made[number]
        number = data.get("i")
        if not isinstance(number, int) or number in self.made:
            raise SnapshotError(f"a value without a number of its own: {str(data)[:60]}")
        if tag == "obj":
            return self.obj(data, number)
        if tag in ("dict", "proxy"):
            return self.mapping(data, number, proxy=tag == "proxy")
        if tag in ("list", "set", "deque"):
            return self.mutable(data, number, tag)
        if tag in ("tuple", "frozenset"):
            # Immutable: made from its items, so it cannot be part of a cycle (neither can
            # it in the core: a tuple is built from values that exist already).
            values = [self.value(item) for item in self.items(data.get("v"))]
            result = tuple(values) if tag == "tuple" else frozenset(values)
            self.made[number] = result
            return result
        raise SnapshotError(f"unknown snapshot value {tag!r}")

    def enum(self, data: dict[str, Json]) -> enum.Enum:
        cls = self.cls(data)
        if not issubclass(cls, enum.Enum):
            raise SnapshotError(f"{data.get('c')} is not an enumeration")
        try:
            return cls(data.get("v"))
        except ValueError as error:
            raise SnapshotError(str(error)) from error

    def mapping(self, data: dict[str, Json], number: int, *, proxy: bool) -> object:
        made: dict[object, object] = {}
        self.made[number] = made
        for pair in self.items(data.get("v")):
            if not isinstance(pair, list) or len(pair) != 2:
                raise SnapshotError("a mapping entry is not a pair")
            made[self.value(pair[0])] = self.value(pair[1])
        if proxy:
            self.made[number] = view = MappingProxyType(made)
            return view
        return made

    def mutable(self, data: dict[str, Json], number: int, tag: str) -> object:
        container: list[object] | set[object] | deque[object]
        if tag == "list":
            container = []
        elif tag == "set":
            container = set()
        else:
            maxlen = data.get("maxlen")
            # Past the interpreter's ssize_t a deque refuses it with OverflowError (SR-7.13).
            if maxlen is not None and (
                not isinstance(maxlen, int) or isinstance(maxlen, bool) or not 0 <= maxlen < 2**63
            ):
                raise SnapshotError(f"a deque's maxlen: {str(maxlen)[:40]}")
            container = deque(maxlen=maxlen)
        self.made[number] = container
        add = container.add if isinstance(container, set) else container.append
        for item in self.items(data.get("v")):
            add(self.value(item))
        return container

    @staticmethod
    def items(items: Json) -> list[Json]:
        if not isinstance(items, list):
            raise SnapshotError("a container's items are not a list")
        return items

    @staticmethod
    def cls(data: dict[str, Json]) -> type:
        name = data.get("c")
        cls = CLASSES.get(name) if isinstance(name, str) else None
        if cls is None:
            raise SnapshotError(f"not a class of the core: {name!r}")
        return cls

    def obj(self, data: dict[str, Json], number: int) -> object:
        cls = self.cls(data)
        if issubclass(cls, enum.Enum | BaseException):
            raise SnapshotError(f"{data.get('c')} is not made from attributes")
        made = object.__new__(cls)
        self.made[number] = made
        attributes = data.get("f")
        if not isinstance(attributes, dict):
            raise SnapshotError(f"{data.get('c')} without attributes")
        required, optional = self.declared.of(cls)
        unknown = sorted(set(attributes) - required.keys() - optional.keys())
        if unknown:
            raise SnapshotError(f"{data.get('c')}: fields its class does not declare: {unknown}")
        missing = sorted(required.keys() - attributes.keys())
        if missing:
            raise SnapshotError(f"{data.get('c')}: declared fields missing: {missing}")
        for key, value in attributes.items():
            restored = self.value(value)
            if not _conforms(restored, required.get(key, optional.get(key))):
                raise SnapshotError(f"{data.get('c')}.{key}: not of its declared type")
            try:
                object.__setattr__(made, key, restored)
            except (AttributeError, TypeError) as error:
                raise SnapshotError(f"{data.get('c')}.{key}: {error}") from error
        return made


def restore(data: Json, config: SafetyConfig) -> SafetyCore:
    """The core in the state :func:`snapshot` wrote, with ``config`` (the one it ran with).
    Raises :class:`SnapshotError` for data that is not a snapshot of a core this code can make
    (another version's, or damaged)."""
    if not isinstance(data, dict) or data.get("c") != _name(SafetyCore):
        raise SnapshotError("the snapshot is not of a safety core")
    try:
        made = _Reader(_Declared(config)).value(data)
    except SnapshotError:
        raise
    except RecursionError as error:
        raise SnapshotError("a snapshot nested too deep") from error
    except (TypeError, ValueError) as error:  # e.g. an unhashable key: damaged
        raise SnapshotError(f"not a snapshot: {error}") from error
    if not isinstance(made, SafetyCore) or CONFIG in vars(made):
        raise SnapshotError("the snapshot is not of a safety core")
    object.__setattr__(made, CONFIG, config)
    made._compose()  # the view of its machines: built from them, never in the data (face.py)
    return made
