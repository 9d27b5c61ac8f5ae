"""The Debian package (packaging/, docs/install.md)."""
