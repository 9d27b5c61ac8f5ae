"""Mutants of the safety core that no test can tell from the original, each with the
argument why (docs/verification.md "Mutation testing"; ``./dev mutate`` reads this file and
counts them apart). A mutant is named by its file and its line before and after the change,
so an entry outlives edits elsewhere, and ``./dev mutate`` reports an entry whose mutant no
longer exists."""

from __future__ import annotations

from verify.mutate import Equivalent

EQUIVALENT: tuple[Equivalent, ...] = ()
