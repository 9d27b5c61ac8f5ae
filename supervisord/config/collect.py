"""Every mistake of a config file at once, in file order, each with its line: what
``srcsd --check-config`` prints (docs/configuration.md "Checking a config").

The loader stops at the first mistake, and it alone says what is valid. So the file is loaded
again and again: after each mistake, the key it names is set aside in a copy of the parsed
file (removed, so that its default applies; a required key gets its declared example), and
the loader runs again, until it accepts the copy. What it refused on the way is the list.
Nothing here decides validity: a file is valid exactly when the loader takes it unchanged.

The rules between entries and sections (two outputs on one GPIO line, one file named twice,
no motion output) come last in the loader, after every section's own keys, and the loader
hands over every broken one at once (:class:`~supervisord.config.loader.RulesBroken`): they
are listed and the list is complete, as nothing is left to judge after them.

Three rules keep the list to the file's own mistakes. A mistake that only setting a key aside
caused (a required key then missing) is not listed. When the key that decides the shape of
its table is wrong (``vsc.transport``, an output's ``kind``), the keys it decides are not
judged against a guess (only the keys every such table has are): a note says so. When an
array of tables is not one (``[outputs.drive]`` for ``[[outputs]]``, ``clients = 3``), it is
replaced by a stand-in (:data:`STAND_INS`) that no key of the file is judged against, so
that the other sections are still judged: a note says so. Where setting aside cannot go on
at all, the list ends there and says that the checks after it did not run.

A valid config's warnings (:meth:`DaemonConfig.warnings`: simulated outputs, an unbound
client) are listed too, each at its key's line.

A user, group or directory the config names that this machine lacks (:class:`NotOnMachine`)
is an error, as it is for the daemon's start; ``strict_machine=False`` (``--portable``) makes
it a warning, for a config written on one machine for another. Directories are asked of
``directory_there`` (:mod:`supervisord.config.directories`; ``None``: not asked).
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Callable, Mapping, MutableMapping
from pathlib import Path
from typing import Final

from supervisord import strict
from supervisord.config.directories import missing_directories
from supervisord.config.lines import KeyPath, Position, key_path, key_positions, position
from supervisord.config.loader import NotOnMachine, RulesBroken, build_config
from supervisord.config.model import DaemonConfig
from supervisord.config.schema import OUTPUT_COMMON, SECTION, VSC_COMMON
from supervisord.config.toml_file import read_at_most, read_toml_text
from supervisord.errors import ConfigError

ROUNDS: Final = 500
"""At most this many loads: a file has fewer keys; a bound all the same."""
SHAPERS: Final[Mapping[KeyPath, frozenset[str]]] = {
    ("vsc", "transport"): frozenset(key.name for key in VSC_COMMON),
    ("outputs", -1, "kind"): frozenset(key.name for key in OUTPUT_COMMON),
}
"""Keys whose value decides which other keys their table may have (``-1``: any index), and
the keys their table has whatever the value."""
STAND_INS: Final[Mapping[str, list[dict[str, object]]]] = {
    "clients": [],
    "outputs": [{"name": "stand_in", "kind": "sim", "role": "motion"}],
}
"""What an array of tables that is not one is judged as, so that the loader goes on to the
sections after it: no client, and one simulated motion output that claims no device or
file (nothing of the file can clash with it)."""


@dataclasses.dataclass(frozen=True)
class Finding:
    """One mistake: the loader's error, whether it is only a warning (a user or group missing
    on this machine), and where it is written (``None``: nowhere the scan could place)."""

    error: ConfigError
    warning: bool
    where: Position | None


@dataclasses.dataclass
class Report:
    """Every finding in file order; the config when the file is valid; notes on what was not
    judged."""

    findings: list[Finding]
    config: DaemonConfig | None
    notes: list[str]

    @property
    def errors(self) -> int:
        return sum(not finding.warning for finding in self.findings)


def collect(
    path: str | Path,
    *,
    strict_machine: bool = False,
    base_dir: str | Path | None = None,
    group_exists: Callable[[str], bool] | None = None,
    read: Callable[[Path], bytes] = read_at_most,
    directory_there: Callable[[Path], bool] | None = None,
) -> Report:
    """Every mistake of the config at ``path`` (see the module's doc), its file read once with
    ``read``. ``strict_machine``: a user, group or directory missing on this machine is an
    error, not a warning."""
    source = Path(path)
    try:
        text, parsed = read_toml_text(source, read)
    except ConfigError as error:  # unreadable, not UTF-8, or not TOML: nothing more to judge
        located = error if error.file else error.in_file(str(path))
        return Report([Finding(located, False, _syntax_position(error.key))], None, [])
    positions = key_positions(text)
    data = copy.deepcopy(parsed)
    work = _Work(data, positions, strict_machine)
    for _ in range(ROUNDS):
        try:
            config = build_config(
                data, source, base_dir=base_dir, group_exists=group_exists, every_rule=True
            )
        except ConfigError as error:
            if not work.take(error):
                break
            continue
        except RulesBroken as broken:  # every section's own keys were judged: the list is whole
            for refused in broken.errors:
                work.list(refused)
            break
        if directory_there is not None:  # of the file's own paths, not of those set aside
            for missing in missing_directories(config, directory_there):
                work.list(missing)
        if work.report.errors == 0:
            work.report.config = config
            for warning in config.warnings():
                if warning.key in work.set_aside:  # of the copy, not of the file (a user
                    continue  # this machine lacks, set aside, leaves its client unbound)
                at = key_path(warning.key)
                where = position(positions, at) if at else None
                value = strict.MISSING if warning.value is None else warning.value
                said = ConfigError(warning.key, value, warning.text)
                work.report.findings.append(Finding(said, True, where))
        break
    else:  # pragma: no cover - more rounds than a file has keys
        work.report.notes.append("too many mistakes to list: correct these and check again")
    work.report.findings.sort(key=_order)
    return work.report


def _order(finding: Finding) -> tuple[int, int]:
    return finding.where or (1 << 30, 0)  # file order; what has no place, last


def _syntax_position(key: str) -> Position | None:
    """``line 3, column 5`` (the loader's key for a syntax error) as a position."""
    words = key.replace(",", "").split()
    if len(words) == 4 and words[0] == "line" and words[2] == "column":
        return int(words[1]), int(words[3])
    return None


class _Work:
    """The mistakes met so far, and what was set aside in the copy to go past them."""

    def __init__(
        self, data: dict[str, object], positions: dict[KeyPath, Position], strict_machine: bool
    ) -> None:
        self.data = data
        self.positions = positions
        self.strict_machine = strict_machine
        self.report = Report([], None, [])
        self.set_aside: set[str] = set()  # keys removed or given their example
        self.given_example: set[str] = set()
        self.unjudged: dict[str, frozenset[str]] = {}  # a table's prefix: the keys still judged
        self.stood_in: set[str] = set()  # arrays of tables replaced by their stand-in

    def list(self, error: ConfigError) -> bool:
        """List ``error`` unless setting a key aside caused it or its table is not judged;
        whether it was listed."""
        path = key_path(error.key)
        own = (
            error.key not in self.set_aside
            and not any(
                error.key.startswith(prefix) and error.key[len(prefix) :] not in common
                for prefix, common in self.unjudged.items()
            )
            and not any(
                error.key == name or error.key.startswith((f"{name}.", f"{name}["))
                for name in self.stood_in
            )
        )
        if own:
            warning = isinstance(error, NotOnMachine) and not self.strict_machine
            where = position(self.positions, path) if path else None
            self.report.findings.append(Finding(error, warning, where))
        return own

    def take(self, error: ConfigError) -> bool:
        """List ``error`` (:meth:`list`) and set its key aside; ``False`` when the loader
        cannot be taken past it."""
        path = key_path(error.key)
        if self.list(error):
            self._shaper(error.key, path)
        if path is not None and self._stand_in(error.key, path):
            return True
        if path is None or not self._aside(error.key, path):
            self.report.notes.append(
                f"the checks after {error.key} did not run: correct it and check again"
            )
            return False
        return True

    def _shaper(self, key: str, path: KeyPath | None) -> None:
        if path is None:
            return
        for shaper, common in SHAPERS.items():
            if len(path) == len(shaper) and all(
                s in (-1, p) for s, p in zip(shaper, path, strict=True)
            ):
                table = key.rsplit(".", 1)[0]
                self.unjudged[f"{table}."] = common
                self.report.notes.append(
                    f"the keys of {table} that {key} decides were not judged: correct it and "
                    "check again"
                )

    def _stand_in(self, key: str, path: KeyPath) -> bool:
        """Replace an array of tables that is not one (``path`` names it, or a table under it
        by name: ``outputs.drive``) by its stand-in, once; ``False`` when ``path`` is not
        such a key."""
        name = path[0]
        shape = len(path) == 1 or isinstance(path[1], str)
        if not (isinstance(name, str) and name in STAND_INS and shape) or name in self.stood_in:
            return False
        if name in self.data:  # (none written: nothing of the file goes unjudged)
            self.report.notes.append(
                f"the [[{name}]] tables were not judged, as {key} is not one: correct it and "
                "check again"
            )
        self.data[name] = copy.deepcopy(STAND_INS[name])
        self.stood_in.add(name)
        return True

    def _aside(self, key: str, path: KeyPath) -> bool:
        """Remove ``path`` from the copy (its default applies), or give it its declared
        example when it is required; ``False`` when neither can be done."""
        table = _table_at(self.data, path[:-1])
        name = path[-1]
        if table is None or isinstance(name, int):
            return False  # an entry of an array: removing it would renumber the others
        if name in table and key not in self.set_aside:
            del table[name]
            self.set_aside.add(key)
            return True
        if key in self.given_example:
            return False
        declared = _declared(self.data, path)
        if declared is None or declared.example is None or not declared.fits(declared.example):
            return False
        table[name] = declared.example
        self.set_aside.add(key)
        self.given_example.add(key)
        return True


def _table_at(data: dict[str, object], path: KeyPath) -> MutableMapping[str, object] | None:
    here: object = data
    for part in path:
        if isinstance(part, int):
            here = here[part] if isinstance(here, list) and part < len(here) else None
        else:
            here = here.get(part) if isinstance(here, dict) else None
    return here if isinstance(here, dict) else None


def _declared(data: dict[str, object], path: KeyPath) -> strict.Key | None:
    """The declaration of the key at ``path`` (for its example), or ``None``."""
    keys: tuple[strict.Key, ...] = ()
    if len(path) == 2 and isinstance(path[0], str) and path[0] in SECTION:
        keys = SECTION[path[0]].keys
    elif len(path) == 3 and path[0] == "clients":
        keys = SECTION["clients"].keys
    elif len(path) == 3 and path[0] == "outputs":
        keys = OUTPUT_COMMON + _output_options(_table_at(data, path[:2]))
    return next((key for key in keys if key.name == path[-1]), None)


def _output_options(table: MutableMapping[str, object] | None) -> tuple[strict.Key, ...]:
    from supervisord.outputs.registry import spec_class  # noqa: PLC0415 - imports the kind

    kind = (table or {}).get("kind")
    try:
        return tuple(spec_class(str(kind)).options)
    except (ValueError, KeyError, ImportError):
        return ()
