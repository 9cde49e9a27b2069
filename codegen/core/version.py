"""The package version (recorded in every generated target's metadata)."""
__version__ = "0.1.0"
