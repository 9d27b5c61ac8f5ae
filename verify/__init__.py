"""Verification of the safety core (docs/verification.md): the exhaustive exploration of the
real ``SafetyCore`` (``./dev verify``), its properties, the deliberately broken cores it must
reject, and the mutation runner (``./dev mutate``). Not part of the product: nothing under
``supervisord/`` imports it."""
