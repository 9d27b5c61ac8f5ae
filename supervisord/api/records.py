"""A stop record as the client API pushes it (docs/record.md "What a record holds",
docs/api.md "Pushes"): typed, frozen, with one encoder (``json``: the record's object as the
record file holds it) and one decoder (``read``; unknown fields are ignored).

The record's own format belongs to the record (``supervisord/record/format.py`` builds it from
the safety core's record); this is how a client reads it. Pure and small: the client library
imports it (docs/ros2.md "The client library").
"""

from __future__ import annotations

from dataclasses import dataclass

from supervisord.api.status import Cause, ProofTestResult
from supervisord.api.wire import Fields, JsonDict


@dataclass(frozen=True, slots=True, kw_only=True)
class Caller:
    """Who asked (docs/api.md "Who may do what"): the peer's uid, pid, login name, admin."""

    uid: int
    pid: int
    name: str
    admin: bool

    def json(self) -> JsonDict:
        return {"uid": self.uid, "pid": self.pid, "name": self.name, "admin": self.admin}

    @classmethod
    def read(cls, f: Fields) -> Caller:
        return cls(
            uid=f.integer("uid"), pid=f.integer("pid"), name=f.text("name"), admin=f.flag("admin")
        )


@dataclass(frozen=True, slots=True, kw_only=True)
class Change:
    """One cause's change in a record: ``raised``, ``updated``, ``cleared`` or ``released``."""

    name: str
    change: str

    def json(self) -> JsonDict:
        return {"name": self.name, "change": self.change}

    @classmethod
    def read(cls, f: Fields) -> Change:
        return cls(name=f.text("name"), change=f.text("change"))


@dataclass(frozen=True, slots=True, kw_only=True)
class Rearm:
    """How a stop was re-armed: ``kind`` (e.g. ``takeover``, ``local_reset``) and who asked."""

    kind: str
    caller: Caller | None = None

    def json(self) -> JsonDict:
        out: JsonDict = {"kind": self.kind}
        if self.caller is not None:
            out["caller"] = self.caller.json()
        return out

    @classmethod
    def read(cls, f: Fields) -> Rearm:
        caller = f.maybe_obj("caller")
        return cls(kind=f.text("kind"), caller=None if caller is None else Caller.read(caller))


@dataclass(frozen=True, slots=True, kw_only=True)
class OutputOffReport:
    """One output in one press of a field stop test (SR-12.1): ``off_ns`` from the e-stop's
    frame to its verified off (``None``: not off), ``off_ms`` the same in ms, its category-1
    ``off_delay_ms`` (SR-1.4) and whether it passed."""

    name: str
    off_ns: int | None
    off_ms: float | None
    off_delay_ms: int
    passed: bool

    def json(self) -> JsonDict:
        return {
            "name": self.name,
            "off_ns": self.off_ns,
            "off_ms": self.off_ms,
            "off_delay_ms": self.off_delay_ms,
            "passed": self.passed,
        }

    @classmethod
    def read(cls, f: Fields) -> OutputOffReport:
        return cls(
            name=f.text("name"),
            off_ns=f.maybe_integer("off_ns"),
            off_ms=f.maybe_number("off_ms"),
            off_delay_ms=f.maybe_integer("off_delay_ms") or 0,
            passed=f.flag("passed"),
        )


@dataclass(frozen=True, slots=True, kw_only=True)
class StopStepReport:
    """One press of a field stop test: its ``source`` (``remote``, ``wired``), the stop record
    it made (``seq``) and that record's ``mono_ns`` (``stop_ns``), and each output."""

    source: str
    seq: int
    stop_ns: int
    passed: bool
    outputs: tuple[OutputOffReport, ...]

    def json(self) -> JsonDict:
        return {
            "source": self.source,
            "seq": self.seq,
            "stop_ns": self.stop_ns,
            "passed": self.passed,
            "outputs": [o.json() for o in self.outputs],
        }

    @classmethod
    def read(cls, f: Fields) -> StopStepReport:
        return cls(
            source=f.text("source"),
            seq=f.integer("seq"),
            stop_ns=f.integer("stop_ns"),
            passed=f.flag("passed"),
            outputs=tuple(OutputOffReport.read(o) for o in f.objects("outputs")),
        )


@dataclass(frozen=True, slots=True, kw_only=True)
class StopTestReport:
    """A finished field stop test (SR-12.1; docs/srcsctl.md "The field stop test"): the
    ``stoptest`` object of its record and of the ``stoptest`` reply."""

    result: str  # "passed" or "failed"
    limit_ms: int
    steps: tuple[StopStepReport, ...]
    text: str

    @property
    def passed(self) -> bool:
        return self.result == "passed"

    def json(self) -> JsonDict:
        return {
            "result": self.result,
            "limit_ms": self.limit_ms,
            "steps": [s.json() for s in self.steps],
            "text": self.text,
        }

    @classmethod
    def read(cls, f: Fields) -> StopTestReport:
        return cls(
            result=f.text("result"),
            limit_ms=f.integer("limit_ms"),
            steps=tuple(StopStepReport.read(s) for s in f.objects("steps")),
            text=f.maybe_text("text") or "",
        )


@dataclass(frozen=True, slots=True, kw_only=True)
class StopRecord:
    """One record (docs/record.md): ``from_state`` and ``to_state`` are ``from`` and ``to`` on
    the wire; ``trigger`` stays JSON (its fields depend on its ``event``). The optional fields
    are absent on the wire when ``None``."""

    seq: int
    mono_ns: int
    utc: str
    kind: str | None
    from_state: str
    to_state: str
    causes: tuple[Cause, ...]
    changes: tuple[Change, ...] | None
    trigger: JsonDict
    reason: str | None = None
    prooftest: ProofTestResult | None = None
    stoptest: StopTestReport | None = None
    rearm: Rearm | None = None
    version: str | None = None

    @property
    def record_kind(self) -> str:
        """``kind``, or ``state_change`` where a record leaves it out (docs/record.md)."""
        return self.kind or "state_change"

    def json(self) -> JsonDict:
        out: JsonDict = {"seq": self.seq, "mono_ns": self.mono_ns, "utc": self.utc}
        if self.kind is not None:
            out["kind"] = self.kind
        out["from"] = self.from_state
        out["to"] = self.to_state
        out["causes"] = [c.json() for c in self.causes]
        if self.changes is not None:
            out["changes"] = [c.json() for c in self.changes]
        out["trigger"] = dict(self.trigger)
        if self.reason is not None:
            out["reason"] = self.reason
        if self.prooftest is not None:
            out["prooftest"] = self.prooftest.json()
        if self.stoptest is not None:
            out["stoptest"] = self.stoptest.json()
        if self.rearm is not None:
            out["rearm"] = self.rearm.json()
        if self.version is not None:
            out["version"] = self.version
        return out

    @classmethod
    def read(cls, f: Fields) -> StopRecord:
        proof, rearm = f.maybe_obj("prooftest"), f.maybe_obj("rearm")
        stop = f.maybe_obj("stoptest")
        return cls(
            seq=f.integer("seq"),
            mono_ns=f.integer("mono_ns"),
            utc=f.text("utc"),
            kind=f.maybe_text("kind"),
            from_state=f.text("from"),
            to_state=f.text("to"),
            causes=tuple(Cause.read(c) for c in f.objects("causes")),
            changes=tuple(Change.read(c) for c in f.objects("changes"))
            if f.has("changes")
            else None,
            trigger=f.raw("trigger"),
            reason=f.maybe_text("reason"),
            prooftest=None if proof is None else ProofTestResult.read(proof),
            stoptest=None if stop is None else StopTestReport.read(stop),
            rearm=None if rearm is None else Rearm.read(rearm),
            version=f.maybe_text("version"),
        )
