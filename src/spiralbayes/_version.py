"""The package version (one place; read by ``__init__`` and by provenance records)."""

__version__ = "0.1.0"
