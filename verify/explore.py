"""The exhaustive exploration of the real ``SafetyCore`` (docs/verification.md; ``./dev verify``).

Breadth first from the start over every state the core reaches on the inputs of
:mod:`verify.model`, each input at the current instant and at every boundary a clock can see
(one nanosecond before, at and after each constant it is compared with). States are compared
by the core's canonical form (``SafetyCore.canonical``) and the checker's ghost; a state is
expanded once. Every step is checked against every property (:mod:`verify.properties`); a
violation is reported with the shortest input sequence that reaches it, printed as a pytest
test.

The core is deterministic, so a state is carried as a copy of the core that reached it
(``copy.deepcopy``, with the frozen value classes shared rather than copied: they cannot
change).
"""

from __future__ import annotations

import argparse
import dataclasses
import enum
import hashlib
import sys
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, cast

from supervisord.safety import Event, SafetyCore
from supervisord.safety.canonical import Clock
from verify import model
from verify.clone import clone
from verify.properties import (
    PROPERTIES,
    Ghost,
    Step,
    Violation,
    advance,
    check,
    first_ghost,
    full_step,
    without_cheap,
)


@dataclass(frozen=True)
class Counterexample:
    """A violated property and the shortest input sequence from start that shows it."""

    pid: str
    what: str
    events: tuple[Event, ...]
    names: tuple[str, ...]  # the inputs' names, for the reader


@dataclass
class Result:
    """What an exploration saw."""

    states: int = 0
    steps: int = 0  # inputs fed (edges evaluated), each checked against every property
    depth: int = 0  # breadth-first levels fully expanded
    complete: bool = False  # no new state was left unexpanded: every reachable state was seen
    seconds: float = 0.0
    started: float = field(default_factory=time.perf_counter)
    counterexamples: list[Counterexample] = field(default_factory=list)
    steps_seen: set[bytes] | None = None  # with ``digest``: each step's hash (``step_hash``)

    def digest(self) -> str:
        """One hash of the set of every step seen (state, input, decision): two explorations
        that found the same states and decided alike in every step have the same digest."""
        assert self.steps_seen is not None, "explore(..., digest=True)"
        whole = hashlib.sha256()
        for item in sorted(self.steps_seen):
            whole.update(item)
        return whole.hexdigest()[:16]


def normal(value: object) -> object:
    """``value`` in a form that does not depend on how it is laid out: the canonical form's
    facts and clocks in the order of their names, sets and mappings sorted, dataclasses and
    enums by their names and fields (never by ``id`` or the hash seed). So a canonical form
    whose pairs are listed in another order, and a decision built by other code, normalise
    alike when they say the same."""
    if isinstance(value, enum.Enum):
        return (type(value).__name__, value.name)
    if isinstance(value, (str, int, float, bytes, type(None))):
        return value
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return (
            type(value).__name__,
            tuple((f.name, normal(getattr(value, f.name))) for f in dataclasses.fields(value)),
        )
    if isinstance(value, Mapping):
        return (
            "map",
            tuple(sorted(((repr(normal(k)), normal(v)) for k, v in value.items()), key=repr)),
        )
    if isinstance(value, (set, frozenset)):
        return ("set", tuple(sorted((normal(v) for v in value), key=repr)))
    if isinstance(value, (tuple, list)):
        items = tuple(normal(v) for v in value)
        if items and all(_is_pair(i) for i in items):  # (name, value) pairs: by their names
            return tuple(sorted(items, key=repr))
        return items
    return (type(value).__name__, repr(value))


def _is_pair(item: object) -> bool:
    return isinstance(item, tuple) and len(item) >= 2 and isinstance(item[0], str)


def step_hash(key: object, name: str, delta: int, decision: object) -> bytes:
    """The hash of one step: the state it starts from (its key), the input and when, the
    decision (``normal``: independent of how either is laid out)."""
    return hashlib.sha256(repr(normal((key, name, delta, decision))).encode()).digest()


UNIT_NS = 10_000_000
"""Every constant a clock is compared with is a multiple of this (10 ms: the 20 ms of the
takeover's rate and the 50 ms of the user heartbeat's period; ``region`` checks it)."""

_checked_limits: set[tuple[int, ...]] = set()


def region(clocks: Sequence[Clock]) -> tuple[object, ...]:
    """The clocks up to region equivalence (docs/verification.md "The time abstraction"): each
    clock's whole number of units, whether it sits exactly on one, and the order of the
    clocks' fractions. With every constant a whole number of units, clocks equal in these
    pass and fail every guard together at every later time, whatever the nanoseconds."""
    wholes: list[object] = []
    fractions: list[int] = []
    for name, age, limits in clocks:
        if limits not in _checked_limits:
            if any(limit % UNIT_NS for limit in limits):
                raise ValueError(f"clock {name}: limits {limits} are not whole units")
            _checked_limits.add(limits)
        if age >= max(limits):
            wholes.append((name, None))  # at or past every limit: all alike
        else:
            whole, fraction = divmod(age, UNIT_NS)
            wholes.append((name, whole, fraction == 0))
            fractions.append(fraction)
    rank = {f: i for i, f in enumerate(sorted(set(fractions)))}
    return tuple(wholes), tuple(rank[f] for f in fractions)


def merged(facts: tuple[object, ...]) -> tuple[object, ...]:
    """The core's canonical facts with what the exploration merges left out (docs/
    verification.md "What the exploration merges"): which stop causes are latched but clear
    (and their details), only whether any is (no guard reads more: the state, the re-arm and the
    heartbeat's byte read whether any stop is latched and when the last cleared, a clock the
    form keeps; only the lists of causes in decisions and records name them), the quieting of
    a repeated takeover refusal (it decides only whether a refusal is reported and recorded)
    and, in ``state``, the schedule of the key-85 query (it decides only when a query goes
    out)."""
    kept: list[object] = []
    for item in facts:
        label, value = cast(tuple[str, Any], item)  # the core's facts are (name, value) pairs
        if label == "quiet":
            continue
        if label == "causes":
            value = (
                tuple((name, details) for name, on, _, details in value if on),
                any(latched and not on for _, on, latched, _ in value),
            )
        kept.append((label, value))
    return tuple(kept)


@dataclass(slots=True)
class _Node:
    core: SafetyCore
    ghost: Ghost
    index: int
    clocks: tuple[Clock, ...]
    key: object = None


def _boundaries(
    clocks: Sequence[Clock], budget_limit: int, kinds: Callable[[str], frozenset[str]]
) -> dict[int, set[str]]:
    """Every time ahead (ns from now) at which a clock's guard can change, each with the kinds
    of input offered there: one nanosecond before, at and after each limit."""
    found: dict[int, set[str]] = {1: {model.TICK}}  # 1 ns on: the next instant
    budgets: dict[str, tuple[int, list[int]]] = {}
    for name, age, limits in clocks:
        if name.startswith("budget:"):
            budgets.setdefault(name, (limits[0], []))[1].append(age)
            continue
        offered = kinds(name)
        if not offered:
            continue
        for limit in limits:
            ahead = limit - age
            if ahead > 0:
                for delta in (ahead - 1, ahead, ahead + 1):
                    if delta > 0:
                        found.setdefault(delta, set()).update(offered)
    for name, (window, ages) in budgets.items():
        # A user's budget changes only when the record that keeps it exhausted ages out; the
        # budget of all users (640) is out of the exploration's reach.
        if name == "budget:all" or not budget_limit or len(ages) < budget_limit:
            continue
        ages.sort(reverse=True)
        ahead = window - ages[len(ages) - budget_limit]
        for delta in (ahead - 1, ahead, ahead + 1):
            if delta > 0:
                found.setdefault(delta, set()).update(kinds(name))
    return found


class _Stop(Exception):
    """The search is over (a violation, or enough states)."""


class _Search:
    """One breadth-first exploration (:func:`explore`)."""

    def __init__(
        self,
        target: model.Model,
        core_class: type[SafetyCore],
        max_states: int | None,
        all_violations: bool,
        digest: bool = False,
    ) -> None:
        self.target = target
        self.config = target.config
        self.max_states = max_states
        self.all_violations = all_violations
        self.by_kind: dict[str, list[model.Input]] = {}
        for item in target.inputs:
            self.by_kind.setdefault(item.kind, []).append(item)
        self.timed = [i for i in target.inputs if i.kind in model.TIMED]
        self.result = Result(steps_seen=set() if digest else None)
        self.violated: set[str] = set()
        root = target.start(core_class)
        first = root.decision
        ghost = first_ghost(first)
        key, clocks = self.state(root, ghost)
        self.seen: dict[object, int] = {key: 0}
        # For each state, the state it was reached from and the input that reached it.
        self.parents: list[tuple[int, Event, str]] = [(0, first.records[0].trigger, "start")]
        self.frontier = [_Node(root, ghost, 0, clocks, key)]

    def state(self, core: SafetyCore, ghost: Ghost) -> tuple[object, tuple[Clock, ...]]:
        """The key a state is compared by, and its clocks (the boundaries come from them)."""
        facts, clocks = without_cheap(core.canonical())  # P17 checks the cheap path
        # merged(): what the exploration merges; the budget's clocks when out of reach (the
        # budget of all users, 640 records, always is)
        dropped: tuple[str, ...] = ("quiet", "key85:next", "budget:all")
        if self.target.budget_limit is None:
            dropped += ("budget:",)
        clocks = tuple(c for c in clocks if not c[0].startswith(dropped))
        *seen_facts, seen_clocks = ghost.key(core.decision.now, self.config)
        assert isinstance(seen_clocks, tuple)
        clocks += seen_clocks
        return (merged(facts), tuple(seen_facts), region(clocks)), clocks

    def offered(self, ghost: Ghost, items: Sequence[model.Input]) -> list[model.Input]:
        """``items`` but a client's input on a connection the API server would not send."""
        return [
            i
            for i in items
            if i.connection is None or (i.connection in ghost.connected) is not i.connects
        ]

    def level(self) -> None:
        """Expand every state of the frontier; the new ones are the next frontier."""
        following: list[_Node] = []
        for node in self.frontier:
            for delta, items, go_on in self.offers(node):
                for item in items:
                    successor = self.step(node, item, delta, go_on)
                    if successor is not None:
                        following.append(successor)
        self.frontier = following
        self.result.depth += 1
        self.result.states = len(self.seen)

    def offers(self, node: _Node) -> list[tuple[int, list[model.Input], bool]]:
        """Continued: every input now, the timed ones one grid step on. Probed (checked, not
        continued): the inputs that can see a clock at each of its boundaries within the
        next grid step (the later ones are probed once the grid is there)."""
        grid = self.target.grid_ns
        offers = [
            (0, self.offered(node.ghost, self.target.inputs), True),
            (grid, self.offered(node.ghost, self.timed), True),
        ]
        limit = self.target.budget_limit or 0
        for delta, kinds in sorted(_boundaries(node.clocks, limit, model.seen_by).items()):
            if delta != grid and delta <= grid + 1:
                items = [i for k in sorted(kinds) for i in self.by_kind.get(k, ())]
                offers.append((delta, self.offered(node.ghost, items), False))
        return offers

    def step(self, node: _Node, item: model.Input, delta: int, go_on: bool) -> _Node | None:
        """Feed ``item`` ``delta`` after the state of ``node`` to a copy of its core, check
        every property, and return the new state if it is one to continue from."""
        successor = clone(node.core)
        before = node.core.decision
        event = item.build(before.now + delta)
        full = full_step(node.core, event)
        reflex = node.core.reflex(event.now)  # P23: what the loop writes off before the step
        after = successor.handle(event)
        ghost = advance(node.ghost, self.config, event, after)
        step = Step(self.config, successor, before, after, event, node.ghost, ghost, full, reflex)
        found = check(step)
        self.result.steps += 1
        if self.result.steps_seen is not None:
            self.result.steps_seen.add(step_hash(node.key, item.name, delta, after))
        if found:
            self.report(found, node.index, event, item.name)
        if not go_on:
            return None
        key, clocks = self.state(successor, ghost)
        if key in self.seen:
            return None
        index = self.seen[key] = len(self.parents)
        self.parents.append((node.index, event, item.name))
        if self.max_states is not None and len(self.seen) >= self.max_states:
            raise _Stop
        return _Node(successor, ghost, index, clocks, key)

    def report(self, found: list[Violation], index: int, event: Event, name: str) -> None:
        """Keep the first counterexample of each property, with its input sequence."""
        steps = [(event, name)]
        while index > 0:
            index, earlier, earlier_name = self.parents[index]
            steps.append((earlier, earlier_name))
        steps.reverse()
        for pid, what in found:
            if pid not in self.violated:
                self.violated.add(pid)
                events = tuple(e for e, _ in steps)
                names = tuple(n for _, n in steps)
                self.result.counterexamples.append(Counterexample(pid, what, events, names))
                if not self.all_violations:
                    raise _Stop


def explore(
    target: model.Model,
    *,
    core_class: type[SafetyCore] = SafetyCore,
    max_depth: int | None = None,
    max_states: int | None = None,
    all_violations: bool = False,
    progress: Callable[[Result, int], None] | None = None,
    digest: bool = False,
) -> Result:
    """Explore ``target`` breadth first from the start; stop at the first violation (unless
    ``all_violations``: then the first of each property), after ``max_depth`` levels or once
    ``max_states`` states are known. With ``digest``, ``Result.digest()`` hashes every step."""
    search = _Search(target, core_class, max_states, all_violations, digest)
    result = search.result
    try:
        while search.frontier and (max_depth is None or result.depth < max_depth):
            search.level()
            if progress is not None:
                progress(result, len(search.frontier))
        result.complete = not search.frontier
    except _Stop:
        pass
    result.states = len(search.seen)
    result.seconds = time.perf_counter() - result.started
    return result


def regression_test(example: Counterexample, model_name: str) -> str:
    """The counterexample as a pytest test: it fails until the core is fixed."""
    messages = sorted({type(m).__name__ for e in example.events if (m := getattr(e, "message", 0))})
    imports = [
        f"from supervisord.protocol.messages import {', '.join(messages)}" if messages else "",
        "from supervisord.safety import Caller, Request, SafetyCore  # noqa: F401 -- as needed",
        "from supervisord.safety.events import "
        + ", ".join(sorted({type(e).__name__ for e in example.events})),
        "from verify.model import START_NS",
        "from verify.properties import check_trace",
    ]
    events = "\n".join(
        f"        {model.code(e)},  # {n}"
        for e, n in zip(example.events, example.names, strict=True)
    )
    header = "\n".join(line for line in imports if line)
    return f'''{header}


def test_exploration_{example.pid.lower()}() -> None:
    """{PROPERTIES[example.pid].requirements}: {example.pid} holds on the shortest input
    sequence the exploration found to break it ({example.what})."""
    events = [
{events}
    ]
    assert check_trace(SafetyCore, "{model_name}", events) == []
'''


def _show(result: Result, frontier: int) -> None:
    print(
        f"   level {result.depth}: {result.states} states, {frontier} new, "
        f"{result.steps} steps, {time.perf_counter() - result.started:.0f} s",
        flush=True,
    )


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="./dev verify", description=__doc__)
    parser.add_argument("models", nargs="*", help=f"models (default: {' '.join(model.MODELS)})")
    parser.add_argument("--depth", type=int, default=None, help="stop after this many levels")
    parser.add_argument("--states", type=int, default=None, help="stop at this many states")
    parser.add_argument(
        "--bounded",
        action="store_true",
        help="each model to its depth of the bounded run (model.BOUNDED, the tests' bound)",
    )
    parser.add_argument(
        "--digest",
        action="store_true",
        help="print a digest of every step (state, input, decision): a refactoring of the core "
        "that changes no behaviour keeps every model's states, steps and digest",
    )
    args = parser.parse_args(argv)
    failed = False
    for name in args.models or model.MODELS:
        target = model.MODELS[name]
        print(f"== {name}: {target.what}", flush=True)
        depth = target.depth if args.depth is None else args.depth
        if args.bounded:
            depth = model.BOUNDED[name]
        result = explore(
            target,
            max_depth=depth,
            max_states=args.states,
            all_violations=True,
            progress=None if args.digest else _show,
            digest=args.digest,
        )
        print(
            f"{name}: {result.states} states, {result.steps} steps, {result.depth} levels "
            f"({'complete' if result.complete else 'bounded'}), {len(PROPERTIES)} properties "
            f"checked at every step, {result.seconds:.0f} s",
            flush=True,
        )
        if args.digest:
            print(f"{name}: digest {result.digest()}", flush=True)
        for example in result.counterexamples:
            failed = True
            print(f"\n# {example.pid} violated: {example.what}\n")
            print(regression_test(example, name))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
