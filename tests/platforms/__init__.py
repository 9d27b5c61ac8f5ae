"""The platform tier: the project in Debian roots of other releases and architectures
(docs/platforms.md)."""
