"""Every API test fails if it leaves a descriptor open."""

from tests.descriptors import no_descriptor_left_open  # noqa: F401 -- an autouse fixture
