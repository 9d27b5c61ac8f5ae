"""docs/api.md says the same message limits as the code that enforces them."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from supervisord.api.server import MAX_LINE_RANGE
from supervisord.config import load_config
from supervisord.errors import ConfigError
from supervisord.testkit.daemon import MINIMAL_CONFIG

API_DOC = Path(__file__).parents[2] / "docs" / "api.md"


def test_the_smallest_message_limit_in_api_md_is_the_configs(tmp_path: Path) -> None:
    """SR-8.8 "the docs agree with the config on message limits": the smallest
    ``api.max_message_bytes`` docs/api.md names is the code's lower bound, and the config
    really accepts it (and refuses one byte less)."""
    framing = API_DOC.read_text().split("## Framing", 1)[1].split("\n## ", 1)[0]
    found = re.search(r"allows limits from (\d+) bytes", " ".join(framing.split()))
    assert found is not None, "docs/api.md no longer names the smallest limit"
    smallest = int(found.group(1))
    assert smallest == MAX_LINE_RANGE[0]
    path = tmp_path / "robot.toml"
    path.write_text(MINIMAL_CONFIG + f"max_message_bytes = {smallest}\n")
    assert load_config(path).api.max_message_bytes == smallest
    path.write_text(MINIMAL_CONFIG + f"max_message_bytes = {smallest - 1}\n")
    with pytest.raises(ConfigError, match="max_message_bytes"):
        load_config(path)
