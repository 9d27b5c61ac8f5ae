"""Every API test fails if it leaves a descriptor open; the clients a test makes of the API's
socket, closed after it."""

from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from tests.api.test_api_server import Peer
from tests.descriptors import no_descriptor_left_open  # noqa: F401 -- an autouse fixture


@pytest.fixture
def peers(tmp_path: Path) -> Iterator[Callable[[], Peer]]:
    """Make clients of ``tmp_path/api.sock``; each is closed when the test ends."""
    made: list[Peer] = []

    def make() -> Peer:
        made.append(Peer(tmp_path / "api.sock"))
        return made[-1]

    yield make
    for peer in made:
        peer.close()
