"""Any config file, however hostile (nested thousands deep, huge, binary, not UTF-8), gets a
typed refusal with its line where it has one: ``srcsd --check-config`` exits 1 with the line,
``srcsd --config`` exits 78 so that systemd does not restart it (SR-11.2;
docs/configuration.md "Checking a config")."""

from __future__ import annotations

import contextlib
import subprocess
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from supervisord.config.nesting import MAX_DEPTH, too_deep
from supervisord.config.toml_file import MAX_CONFIG_BYTES, read_toml_text
from supervisord.errors import ConfigError
from tests.daemon.test_srcsd import SRCSD

RUN_LIMIT_S = 60.0
"""Far above a refusal (about a second); only a bound on a hung process."""
LEVELS = 3000
"""Deep enough for the parser's recursion to pass Python's limit (1,000 calls)."""

DEEP = {
    "arrays": ("[robot]\nname = " + "[" * LEVELS + "]" * LEVELS + "\n", (2, 40)),
    "inline tables": ("[robot]\nname = " + "{ a = " * LEVELS + "1" + " }" * LEVELS, (2, 200)),
    "dotted key": ("[robot]\n" + "a." * LEVELS + "b = 1\n", (2, 66)),
    "table header": ("[" + "a." * LEVELS + "b]\n", (1, 65)),
}
"""Each text, and the line and column where it goes deeper than :data:`MAX_DEPTH`."""


def srcsd(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [SRCSD, *args], capture_output=True, text=True, timeout=RUN_LIMIT_S, check=False
    )


@pytest.mark.parametrize(("text", "where"), DEEP.values(), ids=DEEP.keys())
def test_check_config_names_the_line_of_a_value_nested_too_deep(
    tmp_path: Path, text: str, where: tuple[int, int]
) -> None:
    """SR-11.2: ``srcsd --check-config`` of a file nested 3,000 deep prints the error at its
    line and column and exits 1 (it printed a RecursionError traceback, no line)."""
    file = tmp_path / "robot.toml"
    file.write_text(text)
    done = srcsd("--check-config", str(file))
    line, column = where
    assert done.returncode == 1, done
    assert done.stderr.startswith(f"{file}:{line}:{column}: error: line {line}, column {column}")
    assert f"at most {MAX_DEPTH} deep" in done.stderr
    assert "Traceback" not in done.stdout + done.stderr


@pytest.mark.parametrize(("text", "where"), DEEP.values(), ids=DEEP.keys())
def test_the_daemon_refuses_a_value_nested_too_deep_with_ex_config(
    tmp_path: Path, text: str, where: tuple[int, int]
) -> None:
    """SR-11.2: ``srcsd --config`` of a file nested 3,000 deep logs the error at its line and
    exits 78, which the unit does not restart (it exited 1: a restart loop)."""
    file = tmp_path / "robot.toml"
    file.write_text(text)
    done = srcsd("--config", str(file))
    line, column = where
    assert done.returncode == 78, done
    assert f"{file}:{line}:{column}: error: line {line}, column {column}" in done.stderr
    assert "Traceback" not in done.stderr


HOSTILE = {
    "huge": lambda path: path.write_bytes(b"# padding\n" * (MAX_CONFIG_BYTES // 10 + 1)),
    "binary": lambda path: path.write_bytes(bytes(range(256)) * 16),
    "not UTF-8": lambda path: path.write_bytes(b'[robot]\nname = "\xff\xfe"\n'),
    "NUL": lambda path: path.write_bytes(b"[robot]\x00\n"),
}


@pytest.mark.parametrize("make", HOSTILE.values(), ids=HOSTILE.keys())
def test_the_daemon_refuses_a_hostile_file_with_ex_config(tmp_path: Path, make: object) -> None:
    """SR-11.2: a huge, binary or non-UTF-8 file is refused with exit 78 and an error line,
    never a traceback; ``--check-config`` says the same with exit 1."""
    file = tmp_path / "robot.toml"
    make(file)  # type: ignore[operator]
    started = srcsd("--config", str(file))
    checked = srcsd("--check-config", str(file))
    assert started.returncode == 78, started
    assert checked.returncode == 1, checked
    assert f"{file}:" in started.stderr
    assert f"{file}:" in checked.stderr
    assert "Traceback" not in started.stderr + checked.stdout + checked.stderr


def test_the_daemon_refuses_an_endless_file_after_a_bounded_read() -> None:
    """SR-11.2: ``srcsd --config /dev/zero`` (a file without end) is refused as too large
    with exit 78 after reading 1 MiB, not read until memory runs out."""
    done = srcsd("--config", "/dev/zero")
    assert done.returncode == 78, done
    assert "larger than 1048576 bytes" in done.stderr


def nested(depth: int, kinds: list[str]) -> str:
    """A TOML key ``k`` whose value is ``depth`` tables or arrays deep, each level one of
    ``kinds`` (cycled): an array, an inline table, or one more part of a dotted key."""
    opened, closed, in_key = "k", "", True
    for level in range(depth):
        kind = kinds[level % len(kinds)]
        if kind == "array":
            opened, closed, in_key = opened + (" = [ " if in_key else "[ "), " ]" + closed, False
        elif kind == "key" and in_key:
            opened += ".d"
        else:  # an inline table, with its key d
            opened, closed, in_key = opened + (" = { d" if in_key else "{ d"), " }" + closed, True
    return f"{opened}{' = 1' if in_key else '1'}{closed}\n"


@settings(max_examples=200, deadline=None)
@given(
    st.integers(min_value=0, max_value=200),
    st.lists(st.sampled_from(["array", "table", "key"]), min_size=1, max_size=4),
    st.sampled_from(["", "[a.b]\n", '# "[[[[\n', 's = """a""""\n', "f = [1.5, 2.5]\n"]),
)
def test_nesting_deeper_than_the_limit_is_refused_and_shallower_parses(
    depth: int, kinds: list[str], before: str
) -> None:
    """SR-11.2: a value nested ``depth`` levels deep parses when the depth is well under
    :data:`MAX_DEPTH` and is refused with its line when it is over it, whatever comes before
    it (a header, a comment or string with brackets, floats); nothing else is raised."""
    text = before + nested(depth, kinds)
    refused: ConfigError | None = None
    try:
        read_toml_text(Path("robot.toml"), lambda _: text.encode())
    except ConfigError as error:
        refused = error
    if refused is None:
        assert depth <= MAX_DEPTH, text
    else:
        assert depth > MAX_DEPTH - 4, (text, refused)
        assert refused.key.startswith(f"line {before.count(chr(10)) + 1}, column ")


@settings(max_examples=500, deadline=None)
@given(st.binary(max_size=2000) | st.text(max_size=2000).map(str.encode))
def test_any_bytes_parse_or_are_refused_as_config_errors(raw: bytes) -> None:
    """SR-11.2: any bytes at all give parsed TOML or a :class:`ConfigError`, never another
    exception; the depth scan takes any text."""
    with contextlib.suppress(ConfigError):
        read_toml_text(Path("robot.toml"), lambda _: raw)
    too_deep(raw.decode(errors="replace"))
