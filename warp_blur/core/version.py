"""The package's version (one place; read without importing Warp or USD)."""

__version__ = "0.1.0"
