"""Tests of the documentation pages that are run as written."""
